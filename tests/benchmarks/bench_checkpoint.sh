#!/usr/bin/env bash
# Checkpoint cost: bytes and milliseconds per member and checkpoint, and the run's wall time with
# and without checkpoints, for a scenario run in one process (syndds_sim: the members' own save
# code, without DDS; distributed runs write the same files from each process).
#
#   tests/benchmarks/bench_checkpoint.sh [SCENARIO ...] [--every S] [--runs N]
#
# Defaults: config/scenarios/default.yaml and config/scenarios/scm_crossing.yaml, a checkpoint
# every 5 s, 2 runs each. The scenario is copied with `checkpoint: {every_s: S}` added. Prints a
# Markdown table per scenario (per member: bytes, ms per checkpoint) and the wall times.
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)
BIN=${SYNDDS_BUILD_DIR:-$ROOT/build}/bin
EVERY=5; RUNS=2; SCENARIOS=()
while [ $# -gt 0 ]; do
  case "$1" in
    --every) EVERY=$2; shift ;;
    --runs) RUNS=$2; shift ;;
    -h|--help) sed -n '2,10p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) SCENARIOS+=("$1") ;;
  esac
  shift
done
[ ${#SCENARIOS[@]} -gt 0 ] || SCENARIOS=("$ROOT/config/scenarios/default.yaml" "$ROOT/config/scenarios/scm_crossing.yaml")
WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT
export SYNDDS_CONFIG_DIR=${SYNDDS_CONFIG_DIR:-$ROOT/config}

echo "machine: $(nproc) CPUs, load average $(cut -d' ' -f1-3 /proc/loadavg)"
for scenario in "${SCENARIOS[@]}"; do
  name=$(basename "$scenario" .yaml)
  # The copy sits beside the original so that its relative paths (height maps) still resolve.
  copy="$(dirname "$scenario")/.bench_checkpoint_$name.yaml"
  { grep -v '^checkpoint:' "$scenario"; printf '\ncheckpoint: {every_s: %s}\n' "$EVERY"; } > "$copy"
  for run in $(seq 1 "$RUNS"); do
    for mode in without with; do
      file=$scenario; [ $mode = with ] && file=$copy
      out="$WORK/$name-$mode-$run"
      start=$(date +%s.%N)
      "$BIN/syndds_sim" "$file" --output "$out" --quiet --checkpoint-log "$WORK/timings.csv" \
          > "$WORK/log" 2>&1 || { rm -f "$copy"; cat "$WORK/log" >&2; exit 1; }
      wall=$(echo "$(date +%s.%N) - $start" | bc)
      echo "$name run $run $mode checkpoints: wall ${wall} s"
      if [ $mode = with ]; then
        echo
        echo "| $name, run $run | checkpoints | mean bytes | mean ms |"
        echo "|---|---|---|---|"
        awk -F, 'NR > 1 {n[$3]++; b[$3]+=$4; t[$3]+=$5} END {for (m in n) printf "| %s | %d | %.0f | %.2f |\n", m, n[m], b[m]/n[m], t[m]/n[m]}' \
          "$WORK/timings.csv" | sort
        echo
      fi
    done
  done
  rm -f "$copy"
done
