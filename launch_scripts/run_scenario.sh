#!/usr/bin/env bash
# Runs a scenario: one process per vehicle, controller and recorder plus the coordinator,
# watched until the run ends; prints a short summary, or a one-line reason on failure.
#
#   launch_scripts/run_scenario.sh SCENARIO.yaml [--output DIR] [--duration S] [--realtime]
#       [--single-process] [--processes per_member|per_vehicle|N] [--print-commands]
#       [--domain D] [--run-id ID] [--transport default|udp|udp_redundant] [--discovery-server ADDR:PORT]
#       [--log-level LEVEL] [--security-dir DIR] [--view [--view-port P] [--view-bind ADDR]]
#   launch_scripts/run_scenario.sh [SCENARIO.yaml] --resume RUN_DIR [--from-frame K] [options]
#
# --view also starts the browser viewer (syndds_viewer, docs/viewer.md) on the live run and
# prints its URL (port 8080 unless --view-port; 0: any free port; on 127.0.0.1 unless
# --view-bind). It only reads: it takes no part in the barrier, and stopping it or the browser
# changes nothing in the run. It is stopped when the run ends (view the record with view.sh).
#
# --processes overrides the scenario's process layout (docs/deployment.md, "Processes"): one
# process per member (default), a vehicle with its controller and sensors in one process, or
# the vehicles spread over N processes. The results are byte-identical whatever the layout.
#
# --resume continues the run in RUN_DIR from its latest complete checkpoint (or the one of
# frame K) with the same scenario and overrides (docs/checkpoints.md); its files are cut back
# to the checkpoint and go on from there. The scenario and the options of the run's first start
# are in RUN_DIR/launch.args: without SCENARIO they are used again; options typed now win.
#
# Exit status: 0 completed, 1 bad scenario or command line or more than this host can start,
# 2 run aborted, a process failed, or the run completed without its recorder, 130 interrupted.
# Logs of every process: OUTPUT/logs/. Programs: build/bin (or $SYNDDS_BUILD_DIR/bin; run
# launch_scripts/setup.sh first).
set -u
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
BIN=${SYNDDS_BUILD_DIR:-$ROOT/build}/bin
GRACE_S=${SYNDDS_LAUNCH_GRACE_S:-20}   # after a failure: time for the others to exit cleanly
PROCESS_MB=${SYNDDS_PROCESS_MB:-100}   # memory one process of a run needs (docs/deployment.md)
GROUP_MB=${SYNDDS_GROUP_MB:-200}       # a syndds_group process (it links libtorch): ~180 MB

die() { echo "run_scenario: $*" >&2; exit "${2:-1}"; }
usage() { sed -n '2,23p' "$0" | sed 's/^# \{0,1\}//'; }

[ $# -ge 1 ] || { usage >&2; exit 1; }
case "$1" in -h|--help) usage; exit 0 ;; esac
SCENARIO=""
case "$1" in --resume) ;; *) SCENARIO=$1; shift ;; esac
for p in syndds_plan syndds_coordinator syndds_vehicle syndds_controller syndds_policy_controller syndds_recorder syndds_sensor syndds_group syndds_sim; do
  [ -x "$BIN/$p" ] || die "$BIN/$p is missing: run launch_scripts/setup.sh first"
done

OUTPUT=""; SINGLE=0; PRINT=0; RESUME=""; FROM=latest
VIEW=0; VIEW_PORT=8080; VIEW_BIND=127.0.0.1
# The options that make the run what it is (scenario overrides, DDS setup, process layout, run
# id), in the order first given: RUN_DIR/launch.args records them, --resume reads them back.
declare -A RUN_OPT=(); RUN_KEYS=()
DEFAULTS=0   # 1 while the recorded options are read: they do not replace options typed now
set_run_opt() {  # $1 = option, $2 = its value ("" for a flag)
  if [ -n "${RUN_OPT[$1]+set}" ]; then
    [ $DEFAULTS = 1 ] && return
  else
    RUN_KEYS+=("$1")
  fi
  RUN_OPT[$1]=$2
}
parse_args() {
  while [ $# -gt 0 ]; do
    case "$1" in
      --output) [ $# -ge 2 ] || die "--output needs a directory"; OUTPUT=$2; shift ;;
      --resume) [ $# -ge 2 ] || die "--resume needs a run directory"; RESUME=$2; shift ;;
      --from-frame) [ $# -ge 2 ] || die "--from-frame needs a frame number"; FROM=$2; shift ;;
      --run-id|--duration|--domain|--transport|--discovery-server|--log-level|--dds-profiles|--config-dir|--security-dir|--processes)
        [ $# -ge 2 ] || die "$1 needs a value"; set_run_opt "$1" "$2"; shift ;;
      --realtime) set_run_opt "$1" "" ;;
      --single-process) SINGLE=1 ;;
      --print-commands) PRINT=1 ;;
      --view) VIEW=1 ;;
      --view-port) [ $# -ge 2 ] || die "--view-port needs a port"; VIEW_PORT=$2; shift ;;
      --view-bind) [ $# -ge 2 ] || die "--view-bind needs an address"; VIEW_BIND=$2; shift ;;
      -h|--help) usage; exit 0 ;;
      *) die "unknown option: $1 (see --help)" ;;
    esac
    shift
  done
}
parse_args "$@"

# RUN_DIR/launch.args: the scenario, then the options of RUN_KEYS, one argument per line.
LAUNCH_ARGS=launch.args
if [ -n "$RESUME" ]; then
  if [ -f "$RESUME/$LAUNCH_ARGS" ]; then
    mapfile -t recorded < "$RESUME/$LAUNCH_ARGS"
    [ ${#recorded[@]} -ge 1 ] || die "--resume $RESUME: $RESUME/$LAUNCH_ARGS is empty"
    [ -n "$SCENARIO" ] || SCENARIO=${recorded[0]}
    DEFAULTS=1; parse_args "${recorded[@]:1}"; DEFAULTS=0
  elif [ -z "$SCENARIO" ]; then
    die "--resume $RESUME: no $LAUNCH_ARGS there (the run was not started by this launcher, or by an older one): name the scenario and its overrides again: run_scenario.sh SCENARIO.yaml --resume $RESUME [options]"
  fi
fi
[ -n "$SCENARIO" ] || die "no scenario file given (see --help)"
[ -f "$SCENARIO" ] || die "scenario file not found: $SCENARIO"
RUN_ID=${RUN_OPT[--run-id]-}
PASS=(); LAYOUT=()
for k in "${RUN_KEYS[@]}"; do
  case "$k" in
    --run-id) ;;
    --processes) LAYOUT=(--processes "${RUN_OPT[$k]}") ;;
    --realtime) PASS+=("$k") ;;
    *) PASS+=("$k" "${RUN_OPT[$k]}") ;;
  esac
done

# Writes OUTPUT/launch.args for a later --resume: paths made absolute (it may be typed in
# another folder), one argument per line.
record_launch() {
  local lines=() k v
  lines+=("$(realpath -s -- "$SCENARIO")")
  for k in "${RUN_KEYS[@]}"; do
    v=${RUN_OPT[$k]}
    case "$k" in --config-dir|--dds-profiles|--security-dir) v=$(realpath -ms -- "$v") ;; esac
    lines+=("$k")
    [ "$k" = --realtime ] || lines+=("$v")
  done
  for v in "${lines[@]}"; do
    case "$v" in *$'\n'*) die "cannot record an argument with a line break for --resume: $v" ;; esac
  done
  mkdir -p "$OUTPUT" || die "cannot create $OUTPUT"
  printf '%s\n' "${lines[@]}" > "$OUTPUT/$LAUNCH_ARGS.tmp" && mv -f "$OUTPUT/$LAUNCH_ARGS.tmp" "$OUTPUT/$LAUNCH_ARGS" ||
    die "cannot write $OUTPUT/$LAUNCH_ARGS"
}

stem=$(basename "$SCENARIO" .yaml)
stem=${stem//[^A-Za-z0-9_.-]/_}
stamp=$(date +%Y%m%d-%H%M%S)
# The pid keeps two launches of one scenario in the same second apart; the stem is cut so that
# the run id stays within the 64 characters a run id may have (40 + 1 + 15 + 1 + at most 7).
if [ -n "$RESUME" ]; then
  [ -z "$OUTPUT" ] || [ "$OUTPUT" = "$RESUME" ] || die "--resume continues RUN_DIR in place: no --output"
  [ -d "$RESUME/checkpoints" ] || die "--resume $RESUME: no checkpoints there (the scenario needs checkpoint: every_s)"
  OUTPUT=$RESUME
  PASS+=(--resume-from "$FROM")
  # The logs of the interrupted attempt stay beside the new ones.
  [ -d "$OUTPUT/logs" ] && mv "$OUTPUT/logs" "$OUTPUT/logs.before-resume-$stamp"
fi
[ -n "$OUTPUT" ] || OUTPUT="runs/$stem-$stamp-$$"
[ -n "$RUN_ID" ] || RUN_ID="${stem:0:40}-$stamp-$$"

if [ "$SINGLE" = 1 ]; then
  # One process has no DDS traffic to watch.
  [ "$VIEW" = 0 ] || die "--view watches a distributed run; view a --single-process run afterwards with launch_scripts/view.sh OUTPUT"
  if [ "$PRINT" = 1 ]; then
    printf '%q ' "$BIN/syndds_sim" "$SCENARIO" --output "$OUTPUT" --run-id "$RUN_ID" "${PASS[@]}"
    echo
    exit 0
  fi
  [ -n "$RESUME" ] || record_launch
  "$BIN/syndds_sim" "$SCENARIO" --output "$OUTPUT" --run-id "$RUN_ID" "${PASS[@]}"
  rc=$?
  [ $rc -eq 0 ] && echo "output: $OUTPUT"
  exit $rc
fi

if [ "$PRINT" = 1 ]; then
  exec "$BIN/syndds_plan" "$SCENARIO" --output "$OUTPUT" --run-id "$RUN_ID" --bin-dir "$BIN" "${LAYOUT[@]}" "${PASS[@]}"
fi

plan=$("$BIN/syndds_plan" "$SCENARIO" --output "$OUTPUT" --run-id "$RUN_ID" --bin-dir "$BIN" \
       --format launcher "${LAYOUT[@]}" "${PASS[@]}") || exit 1
# on_member_loss: recover: a member process that dies is started again (--rejoin), at most
# max_recoveries times per process; the coordinator rolls every member back (docs/checkpoints.md).
read -r LOSS_POLICY MAX_RESTARTS < <("$BIN/syndds_plan" "$SCENARIO" --format policy "${PASS[@]}") || exit 1

# Refuse what this machine cannot start, before starting anything: every process of a run
# holds about PROCESS_MB of memory (Fast DDS participant, shared-memory transport; measured in
# docs/deployment.md), and the user may only have so many processes.
nproc_run=$(printf '%s\n' "$plan" | grep -c $'\t')
ngroups=$(printf '%s\n' "$plan" | grep -c '^group/')
need_mb=$(( (nproc_run - ngroups) * PROCESS_MB + ngroups * GROUP_MB ))
avail_mb=$(awk '/^MemAvailable:/ {print int($2 / 1024)}' /proc/meminfo 2>/dev/null)
if [ -n "$avail_mb" ] && [ "$need_mb" -gt "$avail_mb" ]; then
  die "$nproc_run processes need about $need_mb MB ($PROCESS_MB MB each, $GROUP_MB MB a group process) but this machine has $avail_mb MB available: run fewer vehicles or spread the run over hosts (docs/deployment.md)"
fi
max_user=$(ulimit -u)
if [ "$max_user" != unlimited ]; then
  running_user=$(ps -U "$(id -u)" -o pid= 2>/dev/null | wc -l)
  [ $((running_user + nproc_run)) -le "$max_user" ] ||
    die "$nproc_run processes would exceed this user's limit of $max_user processes ($running_user running; ulimit -u)"
fi

[ -n "$RESUME" ] || record_launch
mkdir -p "$OUTPUT/logs" || die "cannot create $OUTPUT/logs"
: > "$OUTPUT/logs/pids"
names=(); pids=(); codes=(); cmds=(); restarts=()
# The viewer is not a member: the launcher neither waits for it nor cares how it ends.
VIEW_PID=""
stop_viewer() { [ -z "$VIEW_PID" ] || { kill -TERM "$VIEW_PID" 2>/dev/null; wait "$VIEW_PID" 2>/dev/null; VIEW_PID=""; }; }
if [ "$VIEW" = 1 ]; then
  [ -x "$BIN/syndds_viewer" ] || die "$BIN/syndds_viewer is missing: run launch_scripts/setup.sh first"
  rm -f "$OUTPUT/logs/viewer.url"
  "$BIN/syndds_viewer" "$SCENARIO" --run-id "$RUN_ID" --port "$VIEW_PORT" --bind "$VIEW_BIND" \
      --url-file "$OUTPUT/logs/viewer.url" "${PASS[@]}" > "$OUTPUT/logs/viewer.log" 2>&1 &
  VIEW_PID=$!
  for _ in $(seq 100); do
    [ -s "$OUTPUT/logs/viewer.url" ] || ! kill -0 "$VIEW_PID" 2>/dev/null && break
    sleep 0.1
  done
  if [ -s "$OUTPUT/logs/viewer.url" ]; then
    echo "run_scenario: viewer at $(cat "$OUTPUT/logs/viewer.url")"
  else
    echo "run_scenario: the viewer did not start (the run goes on): $(tail -n1 "$OUTPUT/logs/viewer.log")" >&2
  fi
fi
# From here on no child may outlive the launcher: signals are noted and handled by the watch
# loop below, and whatever ends the script kills what is still running.
interrupted=0
trap 'interrupted=1' INT TERM HUP
kill_children() {
  for i in "${!pids[@]}"; do
    [ -z "${codes[$i]}" ] && kill -KILL "${pids[$i]}" 2>/dev/null
  done
}
trap 'kill_children; stop_viewer' EXIT
# The coordinator comes first in the plan. Starting stops as soon as the run has ended (the
# coordinator exited: join timeout, bad configuration) or the user interrupted: with hundreds of
# processes starting takes long, and nothing started after the end can take part.
while IFS=$'\t' read -r member cmd; do
  [ -n "$member" ] || continue
  if [ $interrupted = 1 ] || { [ ${#pids[@]} -gt 0 ] && ! kill -0 "${pids[0]}" 2>/dev/null; }; then
    echo "run_scenario: the run ended while processes were starting; $member and the rest were not started" >&2
    break
  fi
  log="$OUTPUT/logs/${member//\//_}.log"
  ( eval "exec $cmd" ) > "$log" 2>&1 &
  names+=("$member"); pids+=($!); codes+=(""); cmds+=("$cmd"); restarts+=(0)
  echo "$member $!" >> "$OUTPUT/logs/pids"
done <<< "$plan"
echo "run_scenario: started ${#pids[@]} processes for run $RUN_ID (logs in $OUTPUT/logs)"

stop_all() {  # $1 = signal
  for i in "${!pids[@]}"; do
    [ -z "${codes[$i]}" ] && kill "-$1" "${pids[$i]}" 2>/dev/null
  done
}

# The coordinator is the authority on the run: when it exits (completed or aborted) every other
# process has GRACE_S seconds to follow before it is stopped. A member that fails before that
# either makes the coordinator abort (on_member_loss: abort) or is left behind (continue).
failed=""; deadline=0; killed=0; coordinator_code=""; recorder_code=0; notes=(); early=""; early_log=""; recorder_what=""
# Until the coordinator says every member joined, a member that exits can never join: the run
# cannot start, and waiting out the join timeout would only hide why.
started() { grep -q "all members joined" "$OUTPUT/logs/coordinator.log" 2>/dev/null; }
run_started=0
while :; do
  alive=0
  for i in "${!pids[@]}"; do
    [ -n "${codes[$i]}" ] && continue
    if kill -0 "${pids[$i]}" 2>/dev/null; then
      alive=$((alive + 1))
      continue
    fi
    wait "${pids[$i]}"; code=$?
    # Only a process that died (killed by a signal) is restarted: one that ended by itself
    # (aborted run, own failure, interrupt) was told to or will fail again.
    if [ "$LOSS_POLICY" = recover ] && [ "${names[$i]}" != coordinator ] && [ $code -gt 128 ] &&
       [ $code -ne 130 ] && [ $run_started = 1 ] && [ $interrupted = 0 ] && [ $deadline -eq 0 ] &&
       [ "${restarts[$i]}" -lt "$MAX_RESTARTS" ] && kill -0 "${pids[0]}" 2>/dev/null; then
      # Lost while the run goes on: start it again; it rejoins from the coordinator's rollback.
      restarts[$i]=$((restarts[$i] + 1))
      echo "run_scenario: ${names[$i]} was killed by signal $((code - 128)); restarting it (${restarts[$i]} of at most $MAX_RESTARTS)" >&2
      # (It runs over UDP: the dead process's shared-memory ports stay behind, and `fastdds shm
      # clean` does not see them; services/common/service_cli.cpp, --rejoin.)
      log="$OUTPUT/logs/${names[$i]//\//_}.restart${restarts[$i]}.log"
      ( eval "exec ${cmds[$i]} --rejoin" ) > "$log" 2>&1 &
      pids[$i]=$!
      echo "${names[$i]} $!" >> "$OUTPUT/logs/pids"
      alive=$((alive + 1))
      continue
    fi
    codes[$i]=$code
    case "${names[$i]}" in
      coordinator) coordinator_code=${codes[$i]}
                   [ $deadline -eq 0 ] && deadline=$((SECONDS + GRACE_S)) ;;
      recorder) recorder_code=${codes[$i]} ;;
    esac
    if [ "${codes[$i]}" -ne 0 ]; then
      what="${names[$i]} exited with status ${codes[$i]}"
      [ "${codes[$i]}" -eq 130 ] && what="${names[$i]} was interrupted"
      [ "${codes[$i]}" -gt 130 ] && what="${names[$i]} was killed by signal $((codes[$i] - 128))"
      [ -n "$failed" ] || failed=$what
      notes+=("$what")
      [ "${names[$i]}" = recorder ] && recorder_what=$what
    fi
    if [ "${names[$i]}" != coordinator ] && [ -z "$early" ] && [ $run_started = 0 ] && ! started; then
      early="${names[$i]} exited (status ${codes[$i]}) before the run started"
      early_log="$OUTPUT/logs/${names[$i]//\//_}.log"
      [ -n "$failed" ] || failed=$early
    fi
  done
  [ $alive -eq 0 ] && break
  [ $run_started = 1 ] || ! started || run_started=1
  if [ -n "$early" ] && [ $killed = 0 ]; then
    echo "run_scenario: $early; stopping every process (see ${OUTPUT}/logs)" >&2
    stop_all TERM; killed=1; deadline=$((SECONDS + 5))
  fi
  if [ $interrupted = 1 ] && [ $killed = 0 ]; then
    echo "run_scenario: interrupted; stopping every process" >&2
    stop_all TERM; killed=1; deadline=$((SECONDS + 5))
  fi
  if [ $deadline -gt 0 ] && [ $SECONDS -ge $deadline ]; then
    if [ $killed -lt 2 ]; then
      echo "run_scenario: processes still running after the end of the run; stopping them" >&2
      stop_all TERM; killed=2; deadline=$((SECONDS + 5))
    else
      stop_all KILL; deadline=0
    fi
  fi
  sleep 0.1
done
trap - INT TERM HUP EXIT
stop_viewer

# A process killed by a signal leaves its Fast DDS shared-memory files behind, and new runs on
# this machine then fail to open their ports for minutes: remove those of dead processes
# (Fast DDS's own tool; files of running processes are left alone).
for c in "${codes[@]}"; do
  if [ -n "$c" ] && [ "$c" -gt 128 ]; then
    command -v fastdds > /dev/null && fastdds shm clean > /dev/null 2>&1
    break
  fi
done

summary="$OUTPUT/summary.txt"
if [ $interrupted = 0 ] && [ "$coordinator_code" = 0 ] && [ "$recorder_code" = 0 ]; then
  [ -f "$summary" ] && cat "$summary"
  for n in "${notes[@]}"; do
    # A member that failed once the run had completed took nothing from the results; the
    # coordinator names it as such (docs/protocol.md, "Failure handling").
    after=$(grep -h "coordinator: ${n%% *} failed after the run completed" \
            "$OUTPUT/logs/coordinator.log" 2>/dev/null | tail -n1 | sed 's/.*coordinator: //')
    if [ -n "$after" ]; then
      echo "run_scenario: note: $after (the results are complete)" >&2
    else
      echo "run_scenario: note: $n; the run went on without it (on_member_loss: continue)" >&2
    fi
  done
  echo "output: $OUTPUT"
  [ "$VIEW" = 0 ] || echo "replay: launch_scripts/view.sh $OUTPUT"
  exit 0
fi
[ -n "$failed" ] || failed="interrupted"

# One line saying why: the coordinator's verdict (as recorded), else who failed first.
reason=""
if [ -n "$early" ]; then
  reason="$early: $(grep -h -E "error|Error|failed" "$early_log" 2>/dev/null | tail -n1)"
  reason=${reason%: }
elif [ "$coordinator_code" = 0 ] && [ "$recorder_code" != 0 ]; then
  # The coordinator completed the run; what is missing is the record of it.
  upto=$(sed -n 's/.*"recorded_up_to_frame": *\(-\{0,1\}[0-9]*\).*/\1/p' "$OUTPUT/summary.json" 2>/dev/null | head -n1)
  reason="the run completed but the recording is incomplete: $recorder_what"
  [ -n "$upto" ] && reason="$reason (frames 0 to $upto are in $OUTPUT)"
elif [ -f "$summary" ] && ! head -n1 "$summary" | grep -q " is running"; then
  reason=$(head -n1 "$summary")
fi
if [ -z "$reason" ]; then
  reason=$(grep -h -E "run aborted: |error: |failed: " "$OUTPUT/logs/coordinator.log" 2>/dev/null | tail -n1 | sed 's/^\[[^]]*\] \[[^]]*\] \[[^]]*\] //')
fi
[ -n "$reason" ] || reason="$failed"
[ $interrupted = 1 ] && { echo "run_scenario: interrupted: $reason (logs: $OUTPUT/logs)" >&2; exit 130; }
echo "run_scenario: FAILED: $reason [first exit: $failed] (logs: $OUTPUT/logs)" >&2
exit 2
