#!/usr/bin/env bash
# Recovery trials (on_member_loss: recover): each trial runs the scenario with the launcher,
# kills a random member process with SIGKILL once the run passed a random frame, and compares
# the finished run directory with an undisturbed single-process run, byte for byte.
#
#   tests/benchmarks/bench_recover.sh [--trials N] [--seed S] [SCENARIO]
#
# Defaults: 10 trials, seed 1, tests/multiprocess/scenarios/checkpointed.yaml (it must set
# on_member_loss: recover and checkpoint: every_s). Prints one line per trial: the member
# killed, the frame, the frame rolled back to, the seconds from the kill to the rollback, and
# whether the result is byte-identical; exits 1 if any trial is not.
set -uo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)
BIN=${SYNDDS_BUILD_DIR:-$ROOT/build}/bin
TRIALS=10; SEED=1; SCENARIO=$ROOT/tests/multiprocess/scenarios/checkpointed.yaml
while [ $# -gt 0 ]; do
  case "$1" in
    --trials) TRIALS=$2; shift ;;
    --seed) SEED=$2; shift ;;
    -h|--help) sed -n '2,11p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) SCENARIO=$1 ;;
  esac
  shift
done
export SYNDDS_CONFIG_DIR=${SYNDDS_CONFIG_DIR:-$ROOT/config}
WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT
RANDOM=$SEED
"$BIN/syndds_sim" "$SCENARIO" --output "$WORK/reference" --quiet \
    --checkpoint-log "$WORK/checkpoints.csv" > "$WORK/reference.log" 2>&1 ||
  { cat "$WORK/reference.log" >&2; exit 1; }
members=($("$BIN/syndds_coordinator" "$SCENARIO" --print-members))
vehicles=$(( $(wc -l < "$WORK/reference/vehicles.csv") ))
frames=$(tail -n1 "$WORK/reference/vehicles.csv" | cut -d, -f1)
per_frame=$(( (vehicles - 1) / (frames + 1) ))
# The first checkpoint (the reference keeps only the newest ones: checkpoint.keep_last).
first=$(awk -F, 'NR == 2 {print $1}' "$WORK/checkpoints.csv")
[ -n "$first" ] || { echo "bench_recover: $SCENARIO writes no checkpoints" >&2; exit 1; }
same_files() {  # every result file of $1 equal in $2
  (cd "$1" && find . -type f ! -path './logs*' ! -path './checkpoints/*' ! -name 'summary.*' \
      ! -name recoveries.csv ! -name '.*' | sort) > "$WORK/want"
  while read -r f; do cmp -s "$1/$f" "$2/$f" || { echo "differs: $f"; return 1; }; done < "$WORK/want"
}
echo "machine: $(nproc) CPUs, load average $(cut -d' ' -f1-3 /proc/loadavg); $SCENARIO"
bad=0
for t in $(seq 1 "$TRIALS"); do
  victim=${members[$((RANDOM % ${#members[@]}))]}
  frame=$(( first + 10 + RANDOM % (frames - first - 60) ))
  out="$WORK/trial$t"
  "$ROOT/launch_scripts/run_scenario.sh" "$SCENARIO" --output "$out" > "$WORK/launcher$t.log" 2>&1 &
  launcher=$!
  for _ in $(seq 1 1200); do
    rows=0; [ -f "$out/vehicles.csv" ] && rows=$(wc -l < "$out/vehicles.csv")
    [ "$rows" -gt $(( frame * per_frame + 1 )) ] && break
    kill -0 $launcher 2>/dev/null || break
    sleep 0.05
  done
  pid=$(awk -v m="$victim" '$1 == m {print $2}' "$out/logs/pids" 2>/dev/null | head -n1)
  killed_at=$(date +%s.%N)
  [ -n "$pid" ] && kill -KILL "$pid" 2>/dev/null
  wait $launcher; rc=$?
  # The first recovery, from the coordinator's status file: "FRAME SECONDS-AFTER-THE-KILL".
  back=$(python3 - "$out/logs/run_status.json" "$killed_at" <<'PY' 2>/dev/null
import json, sys
r = json.load(open(sys.argv[1])).get("recovery_list", [])
if r: print(r[0]["rolled_back_to_frame"], "%.2f" % (r[0]["decided_unix_s"] - float(sys.argv[2])))
PY
)
  secs="-"; to="-"
  if [ -n "$back" ]; then
    to=${back% *}
    secs=${back#* }
  fi
  if [ $rc -eq 0 ] && diff_out=$(same_files "$WORK/reference" "$out"); then
    result=byte-identical
  else
    result="NOT identical (launcher status $rc) ${diff_out:-}"
    bad=1
    tail -n 3 "$WORK/launcher$t.log"
  fi
  printf 'trial %2d: killed %-14s once frame %4d was recorded; rolled back to %s, %s s after the kill; %s\n' \
    "$t" "$victim" "$frame" "$to" "$secs" "$result"
done
exit $bad
