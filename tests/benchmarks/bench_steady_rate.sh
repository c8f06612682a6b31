#!/usr/bin/env bash
# Does a long distributed run keep its frame rate? Runs a scenario with the launcher (one process
# per agent, private network namespace when allowed), counts the recorder's complete frames once
# a second, and prints the frame rate over the first and the last WINDOW_S seconds of wall time.
#
#   tests/benchmarks/bench_steady_rate.sh [SCENARIO.yaml] [DURATION_S] [WINDOW_S]
#
# Defaults: config/scenarios/scm_crossing.yaml, 120 s simulated, 20 s windows. The last line
# reads "steady" when the last window's rate is within 25 % of the first's, else "slowing down".
# Exit status 0 either way (it measures); 1 when the run itself fails.
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)
SCENARIO=${1:-$ROOT/config/scenarios/scm_crossing.yaml}
DURATION=${2:-120}
WINDOW=${3:-20}
BIN=${SYNDDS_BUILD_DIR:-$ROOT/build}/bin
WORK=$(mktemp -d)
trap 'kill "$launcher" 2>/dev/null || true; rm -rf "$WORK"' EXIT

vehicles=$("$BIN/syndds_plan" "$SCENARIO" --output "$WORK/plan" --run-id plan \
            --format launcher | grep -c "^vehicle/" || true)
[ "$vehicles" -gt 0 ] || { echo "bench_steady_rate: no vehicles in $SCENARIO" >&2; exit 1; }

"$ROOT/tests/netns_exec.sh" "$ROOT/launch_scripts/run_scenario.sh" "$SCENARIO" \
    --output "$WORK/out" --duration "$DURATION" > "$WORK/launch.log" 2>&1 &
launcher=$!
# One sample a second: seconds since start and complete frames recorded (rows / vehicles).
samples=()
t=0
while kill -0 "$launcher" 2>/dev/null; do
  sleep 1
  t=$((t + 1))
  rows=$(($(wc -l < "$WORK/out/vehicles.csv" 2>/dev/null || echo 1) - 1))
  [ "$rows" -lt 0 ] && rows=0
  samples+=("$t $((rows / vehicles))")
done
wait "$launcher" || { cat "$WORK/launch.log" >&2; exit 1; }

printf '%s\n' "${samples[@]}" | awk -v w="$WINDOW" -v load="$(cut -d' ' -f1-3 /proc/loadavg)" \
    -v name="$(basename "$SCENARIO")" -v dur="$DURATION" '
  { t[NR] = $1; f[NR] = $2 }
  END {
    n = NR
    # The run ends with the last frame written: the last sample that still shows progress.
    while (n > 1 && f[n] == f[n - 1]) n--
    if (t[n] < 2 * w) w = int(t[n] / 2)
    first_end = 0; last_start = n
    for (i = 1; i <= n; i++) if (t[i] <= w) first_end = i
    for (i = n; i >= 1; i--) if (t[n] - t[i] <= w) last_start = i
    first = f[first_end] / t[first_end]
    last = (f[n] - f[last_start]) / (t[n] - t[last_start])
    printf "%s, %s s simulated: %d frames in %d s of wall time (load %s)\n", name, dur, f[n], t[n], load
    printf "first %d s: %.0f frames/s; last %d s: %.0f frames/s; ratio %.2f -> %s\n", w, first, w,
           last, last / first, (last >= 0.75 * first ? "steady" : "slowing down")
  }'
