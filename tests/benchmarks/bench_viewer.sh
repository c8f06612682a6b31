#!/usr/bin/env bash
# What watching a live run costs it (docs/performance.md, "Viewer"): the scenario run distributed
# without a viewer, and with syndds_viewer plus a headless Chromium showing the page, both started
# before the run, alternately, RUNS times each; prints each run's real-time factor (wall / sim)
# from summary.json. Needs chromium and the npm packages (launch_scripts/setup.sh).
# BROWSER=0: the viewer alone, no browser (what the viewer process itself costs).
#   [BROWSER=0] tests/benchmarks/bench_viewer.sh [SCENARIO] [RUNS] [DURATION_S]
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)
BIN=${SYNDDS_BUILD_DIR:-$ROOT/build}/bin
SCENARIO=${1:-$ROOT/config/scenarios/scm_crossing.yaml}
RUNS=${2:-3}
DURATION=${3:-20}
work=$(mktemp -d)
pids=()
trap 'for p in "${pids[@]}"; do kill -- "-$p" 2>/dev/null || kill "$p" 2>/dev/null || true; done; rm -rf "$work"' EXIT
rtf() { sed -n 's/.*"real_time_factor": *\([0-9.e+-]*\).*/\1/p' "$1/summary.json" | head -n1; }
echo "load before: $(cut -d' ' -f1-3 /proc/loadavg)"
for k in $(seq "$RUNS"); do
  "$ROOT/launch_scripts/run_scenario.sh" "$SCENARIO" --duration "$DURATION" --run-id "bv-plain-$k-$$" \
      --output "$work/plain$k" > /dev/null 2>&1
  echo "run $k without viewer: RTF $(rtf "$work/plain$k")"
  id="bv-view-$k-$$"
  "$BIN/syndds_viewer" "$SCENARIO" --duration "$DURATION" --run-id "$id" --port 0 \
      --url-file "$work/url$k" > "$work/viewer$k.log" 2>&1 &
  vpid=$!; pids+=("$vpid")
  for _ in $(seq 100); do [ -s "$work/url$k" ] && break; sleep 0.1; done
  bpid=""
  if [ "${BROWSER:-1}" = 1 ]; then
    setsid node "$ROOT/tests/viewer/browser_tests.mjs" watch "$(cat "$work/url$k")" > "$work/browser$k.log" 2>&1 &
    bpid=$!; pids+=("$bpid")
    for _ in $(seq 300); do grep -q "page open" "$work/browser$k.log" && break; sleep 0.1; done
  fi
  "$ROOT/launch_scripts/run_scenario.sh" "$SCENARIO" --duration "$DURATION" --run-id "$id" \
      --output "$work/view$k" > /dev/null 2>&1
  echo "run $k with viewer$([ "${BROWSER:-1}" = 1 ] && echo " and browser"): RTF $(rtf "$work/view$k")"
  if [ -n "$bpid" ]; then
    echo "  page: $(grep drawing "$work/browser$k.log" | tail -n1 | sed 's/.*drawing //')"
    kill -- "-$bpid" 2>/dev/null || true  # node and its Chromium
  fi
  kill "$vpid" 2>/dev/null || true
  wait "$vpid" 2>/dev/null || true
  cmp -s "$work/plain$k/vehicles.csv" "$work/view$k/vehicles.csv" &&
    echo "  vehicles.csv byte-identical" || echo "  vehicles.csv DIFFERS"
done
echo "load after: $(cut -d' ' -f1-3 /proc/loadavg)"
