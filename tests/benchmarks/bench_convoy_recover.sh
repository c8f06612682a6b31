#!/usr/bin/env bash
# The nine shipped convoys (config/scenarios/convoy/*.yaml) with checkpoint: and
# on_member_loss: recover added: each runs with the launcher, its chase camera's sensor
# process (the only sensor process of a convoy: it writes the video) is killed with SIGKILL
# once the run passed the given fraction of its frames, and the finished run directory is
# compared with an undisturbed single-process run of the same copy, byte for byte (the video
# included).
#
#   tests/benchmarks/bench_convoy_recover.sh [--every S] [--at FRACTION] [--duration S]
#       [--only PATTERN]
#
# Defaults: a checkpoint every 5 s, the kill at 0.6 of the run, whole runs (--duration
# shortens them), all nine (--only 1L3F: those whose file name holds the pattern). Prints one
# line per scenario; exits 1 if any run is not byte-identical.
set -uo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)
BIN=${SYNDDS_BUILD_DIR:-$ROOT/build}/bin
EVERY=5; AT=0.6; DURATION=(); ONLY=""
while [ $# -gt 0 ]; do
  case "$1" in
    --every) EVERY=$2; shift ;;
    --at) AT=$2; shift ;;
    --duration) DURATION=(--duration "$2"); shift ;;
    --only) ONLY=$2; shift ;;
    -h|--help) sed -n '2,14p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) echo "bench_convoy_recover: unknown option $1" >&2; exit 1 ;;
  esac
  shift
done
export SYNDDS_CONFIG_DIR=${SYNDDS_CONFIG_DIR:-$ROOT/config}
WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT
same_files() {  # every result file of $1 equal in $2
  (cd "$1" && find . -type f ! -path './logs*' ! -path './checkpoints/*' ! -name 'summary.*' \
      ! -name recoveries.csv ! -name '.*' | sort) > "$WORK/want"
  while read -r f; do cmp -s "$1/$f" "$2/$f" || { echo "differs: $f"; return 1; }; done < "$WORK/want"
}
echo "machine: $(nproc) CPUs, load average $(cut -d' ' -f1-3 /proc/loadavg); checkpoint every $EVERY s, kill at $AT of the run${DURATION[*]:+ (${DURATION[*]})}"
bad=0
for original in "$ROOT"/config/scenarios/convoy/*.yaml; do
  name=$(basename "$original" .yaml)
  [ -z "$ONLY" ] || [[ "$name" == *$ONLY* ]] || continue
  dir="$WORK/$name"
  mkdir -p "$dir"
  scenario="$dir/$name.yaml"
  grep -q '^coordinator: {.*}$' "$original" || { echo "$name: no one-line coordinator: {...}" >&2; exit 1; }
  sed 's/^coordinator: {\(.*\)}$/coordinator: {\1, on_member_loss: recover, rejoin_timeout_s: 60}/' \
    "$original" > "$scenario"
  echo "checkpoint: {every_s: $EVERY}" >> "$scenario"
  started=$(date +%s)
  if ! "$BIN/syndds_sim" "$scenario" --output "$dir/reference" --quiet "${DURATION[@]}" \
      > "$dir/reference.log" 2>&1; then
    echo "$name: the reference run failed"; tail -n 3 "$dir/reference.log"; bad=1; continue
  fi
  reference_s=$(( $(date +%s) - started ))
  victim=$("$BIN/syndds_coordinator" "$scenario" --print-members 2>/dev/null | grep '^sensor/')
  frames=$(tail -n1 "$dir/reference/vehicles.csv" | cut -d, -f1)
  per_frame=$(( ($(wc -l < "$dir/reference/vehicles.csv") - 1) / (frames + 1) ))
  frame=$(python3 -c "print(int($frames * $AT))")
  out="$dir/out"
  started=$(date +%s)
  "$ROOT/launch_scripts/run_scenario.sh" "$scenario" --output "$out" "${DURATION[@]}" \
    > "$dir/launcher.log" 2>&1 &
  launcher=$!
  while kill -0 $launcher 2>/dev/null; do
    rows=0; [ -f "$out/vehicles.csv" ] && rows=$(wc -l < "$out/vehicles.csv")
    [ "$rows" -gt $(( frame * per_frame + 1 )) ] && break
    sleep 0.05
  done
  pid=$(awk -v m="$victim" '$1 == m {print $2}' "$out/logs/pids" 2>/dev/null | head -n1)
  [ -n "$pid" ] && kill -KILL "$pid" 2>/dev/null
  wait $launcher; rc=$?
  run_s=$(( $(date +%s) - started ))
  back=$(python3 -c 'import json, sys; r = json.load(open(sys.argv[1])).get("recovery_list", []); print(r[0]["rolled_back_to_frame"] if r else "")' \
         "$out/logs/run_status.json" 2>/dev/null)
  video=$(cd "$out" && find sensors -name '*.avi' | head -n1)
  size=$(stat -c %s "$out/$video" 2>/dev/null || echo 0)
  if [ $rc -eq 0 ] && [ -n "$back" ] && diff_out=$(same_files "$dir/reference" "$out"); then
    result=byte-identical
  else
    result="NOT identical (launcher status $rc, rollback '${back}') ${diff_out:-}"
    bad=1
    tail -n 3 "$dir/launcher.log"
  fi
  printf '%-14s killed %s once frame %5d of %5d was recorded; rolled back to %s; %s %s bytes; reference %3d s, run %3d s; %s\n' \
    "$name" "$victim" "$frame" "$frames" "${back:--}" "$video" "$size" "$reference_s" "$run_s" "$result"
  rm -rf "$dir/reference" "$out"
done
exit $bad
