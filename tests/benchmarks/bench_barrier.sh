#!/usr/bin/env bash
# Barrier benchmark: real processes on loopback, one coordinator and N members.
#
#   tests/benchmarks/bench_barrier.sh [barrier|scaling] [DURATION_S]
#
# barrier: N vehicle processes (reduced model, no controller, no recorder) for N = 1 2 4 8 16
#          (BARRIER_N="32 48" chooses others): frames/s and mean barrier round (wall time /
#          frames) as the coordinator reports them.
# scaling: N vehicles (reduced model) + N path-follower controllers + the recorder (a full run)
#          for growing N: real-time factor at heartbeat 0.01 s; the largest N with RTF <= 1 is
#          the answer. SCALING_N="8 16 24" chooses the N.
# Runs inside a private network namespace when allowed (tests/netns_exec.sh).
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)
BIN=${SYNDDS_BUILD_DIR:-$ROOT/build}/bin
MODE=${1:-barrier}
DURATION=${2:-10}
WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT

scenario() {  # $1 = N, $2 = with controllers and recorder (0/1)
  local n=$1 full=$2 f=$WORK/bench_$1_$2.yaml
  {
    echo "name: bench"
    echo "time: {step_s: 0.002, heartbeat_s: 0.01, end_time_s: $DURATION}"
    echo "coordinator: {join_timeout_s: 60, frame_timeout_s: 30}"
    echo "recorder: {enabled: $([ "$full" = 1 ] && echo true || echo false)}"
    echo "vehicles:"
    for i in $(seq 1 "$n"); do
      local y=$((i * 10))
      echo "  - id: v$i"
      echo "    model: hmmwv"
      if [ "$full" = 1 ]; then
        echo "    controller:"
        echo "      type: path_follower"
        echo "      path: {waypoints: [[0, $y], [200, $y], [200, $((y + 200))]], closed: true}"
        echo "      speed: {target_mps: 8}"
      else
        echo "    start: {x: 0, y: $y}"
      fi
    done
  } > "$f"
  echo "$f"
}

run_one() {  # $1 = scenario file; prints "frames wall_s rtf" (the coordinator's status file)
  local out=$WORK/out
  rm -rf "$out"
  "$ROOT/tests/netns_exec.sh" "$ROOT/launch_scripts/run_scenario.sh" "$1" --output "$out" \
      > "$WORK/launch.log" 2>&1 || { cat "$WORK/launch.log" >&2; return 1; }
  /usr/bin/python3 -c 'import json, sys; s = json.load(open(sys.argv[1]))["stats"]
print(s["frames"], "%.3f %.3f" % (s["wall_time_s"], s["real_time_factor"]))' "$out/logs/run_status.json"
}

echo "# $(date -u +%F) $(nproc) cores, $(uname -r); duration ${DURATION} s simulated, heartbeat 0.01 s"
if [ "$MODE" = barrier ]; then
  echo "| members | frames/s | mean round (ms) | real-time factor |"
  echo "|---|---|---|---|"
  for n in ${BARRIER_N:-1 2 4 8 16}; do
    read -r frames wall rtf < <(run_one "$(scenario "$n" 0)") || { echo "| $n | failed |"; continue; }
    awk -v n="$n" -v f="$frames" -v w="$wall" -v r="$rtf" \
      'BEGIN { printf "| %d | %.0f | %.3f | %.3f |\n", n, f / w, 1000 * w / f, r }'
  done
else
  echo "| vehicles | processes | real-time factor |"
  echo "|---|---|---|"
  for n in ${SCALING_N:-4 8 12 16 20 24 32}; do
    if read -r frames wall rtf < <(run_one "$(scenario "$n" 1)") && [ -n "${rtf:-}" ]; then
      echo "| $n | $((2 * n + 2)) | $rtf |"
    else
      echo "| $n | $((2 * n + 2)) | failed (see above) |"
    fi
  done
fi
