#!/usr/bin/env bash
# Runs the paper's statistical study: N random obstacle courses (syndds_course), a convoy on each
# course on each terrain, the six deviation metrics of every follower, one CSV at the end.
#
#   launch_scripts/run_ensemble.sh --courses N --output DIR [--terrains rigid,scm_hard,scm_soft]
#       [--convoy 1L3F|2L2F|3L1F] [--protocol current|paper] [--follower-policy FILE]
#       [--follower-rig RIG] [--follower-trail leader|head] [--jobs J]
#       [--distributed] [--first-seed S] [--duration S] [--videos]
#       [--slurm [--slurm-args "SBATCH OPTIONS"] [--wait]] [--gather-only]
#   launch_scripts/run_ensemble.sh --paper --output DIR [...]
#
# --protocol paper makes the courses as the paper does (syndds_course --protocol paper: every
# field used, obstacles shrunk to leave 2 m to the leader's path, the speed ramp not capped);
# current (the default) redraws fields until a path keeps 2 m from the full-size obstacles and
# caps the ramp at 5 m/s (docs/ensemble.md, "Protocols"). --paper is the paper's study:
# --protocol paper, 128 courses unless --courses, 1L3F. On the paper's protocol the first course
# keeps the chase video (one still per terrain in the figures).
# --videos keeps each course's chase camera and video behind the last vehicle (syndds_course's
# default): rendering and encoding it takes 4-6 times as long as the rest of a run and changes
# no metric, so a study leaves it out unless asked (docs/ensemble.md, "Throughput").
# --follower-policy drives the followers with a learned policy (e.g.
# policies/convoy_follow_camera.pt; docs/learning.md) instead of the classical follower; the
# followers then carry the rig the policy's metadata names (<policy>.json, "sensors") unless
# --follower-rig names another (config/sensors/<rig>.yaml; syndds_course --follower-rig).
# --follower-trail leader|head: whose trail every follower steers along, the vehicle ahead's or
# the convoy head's (syndds_course --follower-trail; docs/convoy.md, step 8); default: the
# classical follower the leader's, a learned one the head's.
# Course k has seed first-seed + k (default 1). Each run goes to DIR/runs/<seed>_<terrain>/, its
# scenario to DIR/courses/. Runs in one process each (syndds_sim, byte-identical to a distributed
# run) unless --distributed (run_scenario.sh: one process per member), J at a time (default: the
# number of cores). Resumable: a run whose summary.json says "completed" is skipped, any other is
# run again. At the end: DIR/ensemble.csv (one row per run and follower: the metrics, no wall
# times, so an interrupted and resumed ensemble ends with the same file as an uninterrupted one)
# and DIR/runs.csv (one row per run: status, simulated and wall time, real-time factor), then the
# figures (DIR/figures/) and DIR/report.md (tools/ensemble_figures.py).
#
# --slurm runs nothing here: it submits one Slurm array job with one task per run still to run
# (launch_scripts/slurm/ensemble_task.sbatch; task i runs line i + 1 of DIR/slurm/todo.txt), at
# most J at a time if --jobs is given, and a gather job that starts once every task has ended
# and writes the CSVs, figures and report.md as above. It prints the job ids (also kept in
# DIR/slurm/jobs). Each run's log is DIR/runs/<seed>_<terrain>.log, the jobs' output is in
# DIR/slurm/. Every node must see DIR and this repository (programs, config/) at the same paths:
# a shared filesystem. --slurm-args adds sbatch options to both jobs, split into words as a shell
# would, quotes included (e.g. "-p short -t 30 --comment 'study 3'"); --wait waits for the
# gather job and exits as a local run does. --slurm refuses --distributed (for one run across
# nodes: launch_scripts/slurm/run_scenario.sbatch).
# --gather-only runs nothing: it writes the CSVs, figures and report.md from the runs DIR holds
# (the gather job runs it). --run-one SEED_TERRAIN runs that one run as the ensemble would (each
# array task runs it).
# Exit status: 0 every run completed (--slurm without --wait: submitted), 2 some failed (listed),
# 1 bad command line or environment, 130 interrupted.
set -u
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
BIN=${SYNDDS_BUILD_DIR:-$ROOT/build}/bin
die() { echo "run_ensemble: $1" >&2; exit "${2:-1}"; }  # message [exit status, default 1]

COURSES=""; OUTPUT=""; TERRAINS="rigid,scm_hard,scm_soft"; CONVOY=1L3F
JOBS=$(nproc 2>/dev/null || echo 1); JOBS_SET=0; DISTRIBUTED=0; FIRST=1; DURATION=(); POLICY=""; RIG=""; TRAIL=""
VIDEOS=0; PROTOCOL=current; PROTOCOL_SET=0; PAPER=0; CONVOY_SET=0
SLURM=0; SLURM_ARGS=""; SLURM_ARGS_SET=0; SLURM_EXTRA=(); WAIT=0; GATHER_ONLY=0; RUN_ONE=""
while [ $# -gt 0 ]; do
  case "$1" in
    --courses) [ $# -ge 2 ] || die "--courses needs a number"; COURSES=$2; shift ;;
    --output) [ $# -ge 2 ] || die "--output needs a directory"; OUTPUT=$2; shift ;;
    --terrains) [ $# -ge 2 ] || die "--terrains needs a list"; TERRAINS=$2; shift ;;
    --convoy) [ $# -ge 2 ] || die "--convoy needs a value"; CONVOY=$2; CONVOY_SET=1; shift ;;
    --protocol) [ $# -ge 2 ] || die "--protocol needs a value (current or paper)"; PROTOCOL=$2; PROTOCOL_SET=1; shift ;;
    --paper) PAPER=1 ;;
    --jobs) [ $# -ge 2 ] || die "--jobs needs a number"; JOBS=$2; JOBS_SET=1; shift ;;
    --first-seed) [ $# -ge 2 ] || die "--first-seed needs a number"; FIRST=$2; shift ;;
    --duration) [ $# -ge 2 ] || die "--duration needs seconds"; DURATION=(--duration "$2"); shift ;;
    --follower-policy) [ $# -ge 2 ] || die "--follower-policy needs a file"; POLICY=$2; shift ;;
    --follower-rig) [ $# -ge 2 ] || die "--follower-rig needs a rig name"; RIG=$2; shift ;;
    --follower-trail) [ $# -ge 2 ] || die "--follower-trail needs leader or head"; TRAIL=$2; shift
      [ "$TRAIL" = leader ] || [ "$TRAIL" = head ] || die "--follower-trail: '$TRAIL' is not leader or head" ;;
    --distributed) DISTRIBUTED=1 ;;
    --videos) VIDEOS=1 ;;
    --slurm) SLURM=1 ;;
    --slurm-args) [ $# -ge 2 ] || die "--slurm-args needs sbatch options in one argument"
      SLURM_ARGS=$2; SLURM_ARGS_SET=1; shift ;;
    --wait) WAIT=1 ;;
    --gather-only) GATHER_ONLY=1 ;;
    --run-one) [ $# -ge 2 ] || die "--run-one needs a run id (SEED_TERRAIN)"; RUN_ONE=$2; shift ;;
    -h|--help) awk 'NR > 1 && !/^#/ { exit } NR > 1 { sub(/^# ?/, ""); print }' "$0"; exit 0 ;;
    *) die "unknown option: $1 (see --help)" ;;
  esac
  shift
done
if [ $PAPER = 1 ]; then
  [ $PROTOCOL_SET = 0 ] || [ "$PROTOCOL" = paper ] || die "--paper runs the paper's protocol: leave --protocol $PROTOCOL out"
  PROTOCOL=paper
  [ $CONVOY_SET = 0 ] || [ "$CONVOY" = 1L3F ] || die "--paper is the paper's 1L3F study: leave --convoy out (or use --protocol paper with --convoy $CONVOY)"
  [ -n "$COURSES" ] || COURSES=128
fi
case "$PROTOCOL" in current|paper) ;; *) die "--protocol must be current or paper, got '$PROTOCOL'" ;; esac
[[ "$COURSES" =~ ^[1-9][0-9]{0,3}$ ]] || die "--courses must be 1..9999, got '$COURSES'"
[[ "$JOBS" =~ ^[1-9][0-9]{0,2}$ ]] || die "--jobs must be 1..999, got '$JOBS'"
[[ "$FIRST" =~ ^[0-9]{1,9}$ ]] || die "--first-seed must be 0..999999999, got '$FIRST'"
[ -n "$OUTPUT" ] || die "--output is required"
IFS=, read -r -a terrains <<< "$TERRAINS"
[ ${#terrains[@]} -gt 0 ] || die "--terrains is empty"
for t in "${terrains[@]}"; do
  case "$t" in rigid|scm_hard|scm_soft) ;; *) die "--terrains: unknown terrain '$t' (rigid, scm_hard, scm_soft)" ;; esac
done
case "$CONVOY" in 1L3F|2L2F|3L1F) ;; *) die "--convoy must be 1L3F, 2L2F or 3L1F, got '$CONVOY'" ;; esac
if [ $SLURM = 0 ]; then
  [ $WAIT = 0 ] || die "--wait needs --slurm (a local ensemble always waits for its runs)"
  [ $SLURM_ARGS_SET = 0 ] || die "--slurm-args needs --slurm"
else
  [ $DISTRIBUTED = 0 ] || die "--slurm and --distributed together: with --slurm each run is one single-process Slurm task; for one run across nodes use launch_scripts/slurm/run_scenario.sbatch"
  [ $GATHER_ONLY = 0 ] || die "--slurm and --gather-only together: --gather-only runs here, choose one"
  [ -z "$RUN_ONE" ] || die "--slurm and --run-one together: --run-one runs here, choose one"
  command -v sbatch > /dev/null || die "--slurm needs Slurm's sbatch on PATH (run it on a machine of the cluster, e.g. its login node)"
  if [ $WAIT = 1 ]; then
    for p in scontrol squeue; do command -v "$p" > /dev/null || die "--wait needs Slurm's $p on PATH"; done
  fi
  # Split as a shell splits words, quotes kept together (xargs' quoting; no expansion, no eval).
  mapfile -d '' -t SLURM_EXTRA < <(printf '%s' "$SLURM_ARGS" | xargs -r printf '%s\0')
  wait $! || die "--slurm-args: cannot split '$SLURM_ARGS' into sbatch options (xargs' reason above)"
  for a in "${SLURM_EXTRA[@]}"; do
    case "$a" in
      -a|--array|--array=*|-d|--dependency|--dependency=*|-W|--wait|--parsable|--wrap|--wrap=*)
        die "--slurm-args: $a is set by run_ensemble.sh, not by hand" ;;
    esac
  done
fi
[ $GATHER_ONLY = 0 ] || [ -z "$RUN_ONE" ] || die "--gather-only and --run-one together: choose one"
for p in syndds_course syndds_sim; do
  [ -x "$BIN/$p" ] || die "$BIN/$p is missing: run launch_scripts/setup.sh first"
done
if [ $SLURM = 0 ] && [ -z "$RUN_ONE" ]; then
  command -v python3 > /dev/null || die "python3 is needed to write the CSV files (apt-get install python3)"
fi
if [ -n "$POLICY" ] && [ ! -f "$ROOT/config/$POLICY" ] && [ ! -f "$POLICY" ]; then
  die "--follower-policy: no file $POLICY (looked in config/ and here)"
fi
[ -n "$POLICY" ] && [ ! -f "$ROOT/config/$POLICY" ] && POLICY=$(cd "$(dirname "$POLICY")" && pwd)/$(basename "$POLICY")
mkdir -p "$OUTPUT/courses" "$OUTPUT/runs" || die "cannot create $OUTPUT"
# The jobs run elsewhere: they get absolute paths.
[ $SLURM = 0 ] || OUTPUT=$(cd "$OUTPUT" && pwd)
# The courses are generated once: an ensemble folder belongs to one convoy and one follower.
setup="convoy=$CONVOY follower_policy=${POLICY:-classical}"
[ -z "$RIG" ] || setup+=" follower_rig=$RIG"
# The trail the followers steer along, as syndds_course decides it (a learned follower: head).
trail=${TRAIL:-$([ -n "$POLICY" ] && echo head || echo leader)}
[ "$trail" = leader ] || setup+=" follower_trail=$trail"
[ "$PROTOCOL" = current ] || setup+=" protocol=$PROTOCOL"
if [ -f "$OUTPUT/ensemble.setup" ]; then
  [ "$(cat "$OUTPUT/ensemble.setup")" = "$setup" ] ||
    die "$OUTPUT was made with $(cat "$OUTPUT/ensemble.setup"), not $setup: use another --output"
else
  echo "$setup" > "$OUTPUT/ensemble.setup"
fi

completed() { grep -q '"status": *"completed"' "$1/summary.json" 2>/dev/null; }

# Every (course, terrain) pair, in a fixed order; the finished ones are skipped.
ids=(); todo=()
for ((k = 0; k < COURSES; ++k)); do
  seed=$((FIRST + k))
  for t in "${terrains[@]}"; do
    id="${seed}_$t"
    ids+=("$id")
    if completed "$OUTPUT/runs/$id"; then continue; fi
    todo+=("$id")
  done
done
skipped=$((${#ids[@]} - ${#todo[@]}))
# A full-length run writes about 30 MB (the paper's 384-run study: 11 GB); a full disk fails the
# runs that are writing. Warn, with the numbers, when the runs to do may not fit.
if [ ${#todo[@]} -gt 0 ] && [ ${#DURATION[@]} = 0 ]; then
  free_mb=$(df -Pm "$OUTPUT" 2> /dev/null | awk 'NR == 2 { print $4 }')
  need_mb=$((30 * ${#todo[@]}))
  [ -z "$free_mb" ] || [ "$free_mb" -ge "$need_mb" ] ||
    echo "run_ensemble: warning: ${#todo[@]} runs need about $need_mb MB, $OUTPUT has $free_mb MB free: runs that find the disk full fail (the same command resumes them)" >&2
fi

# One run: the course's scenario (generated once), then the run itself; its log beside its folder.
run_one() {
  local id=$1 seed=${1%%_*} terrain=${1#*_}
  local scenario="$OUTPUT/courses/$id.yaml" dir="$OUTPUT/runs/$id" log="$OUTPUT/runs/$id.log"
  rm -rf "$dir"
  if [ ! -s "$scenario" ]; then
    local video=(--no-chase-video)
    # The paper's study keeps its first course's chase video: a still per terrain.
    [ "$VIDEOS" = 0 ] && { [ "$PROTOCOL" = current ] || [ "$seed" != "$FIRST" ]; } || video=()
    "$BIN/syndds_course" --seed "$seed" --terrain "$terrain" --convoy "$CONVOY" "${video[@]}" \
        --protocol "$PROTOCOL" \
        ${POLICY:+--follower-policy "$POLICY"} ${RIG:+--follower-rig "$RIG"} \
        ${TRAIL:+--follower-trail "$TRAIL"} \
        --output "$scenario.tmp" > "$log" 2>&1 &&
      mv "$scenario.tmp" "$scenario" || return 1
  fi
  # exec: the pid the ensemble knows is the run's own, so a stop reaches it (and it aborts
  # cleanly, keeping its complete frames).
  if [ "$DISTRIBUTED" = 1 ]; then
    SYNDDS_BUILD_DIR="$BIN/.." exec "$ROOT/launch_scripts/run_scenario.sh" "$scenario" \
        --output "$dir" "${DURATION[@]}" >> "$log" 2>&1
  else
    exec "$BIN/syndds_sim" "$scenario" --output "$dir" --run-id "ensemble-$id" --quiet \
        --config-dir "$ROOT/config" "${DURATION[@]}" >> "$log" 2>&1
  fi
}

# The CSVs, the figures and report.md from the runs DIR holds: the one implementation for a local
# ensemble and for the gather job of a Slurm one (--gather-only). Arguments: the runs that
# failed, listed at the end (exit status 2).
gather() {
python3 - "$OUTPUT" "$CONVOY" "${POLICY:-classical}" "${ids[@]}" <<'EOF'
import csv, json, pathlib, sys
out, convoy, controller, ids = pathlib.Path(sys.argv[1]), sys.argv[2], sys.argv[3], sys.argv[4:]
metrics = ["m_p_avg", "m_p_max", "m_as_avg", "m_as_max", "m_rs_avg", "m_rs_max"]
def cell(v):
    return "" if v is None else f"{v:.9g}" if isinstance(v, float) else str(v)
with open(out / "ensemble.csv", "w", newline="") as f, \
     open(out / "runs.csv", "w", newline="") as g:
    e, r = csv.writer(f, lineterminator="\n"), csv.writer(g, lineterminator="\n")
    e.writerow(["seed", "terrain", "convoy", "controller", "status", "follower", "position", "leader",
                *metrics, "obstacles_hit", "samples", "segment_length_m",
                "leader_max_speed_mps", "leader_mean_speed_mps", "leader_lost_events", "stuck"])
    r.writerow(["seed", "terrain", "status", "sim_time_s", "wall_time_s", "real_time_factor"])
    for run_id in ids:
        seed, terrain = run_id.split("_", 1)
        run = out / "runs" / run_id
        try:
            s = json.loads((run / "summary.json").read_text())
            status = s.get("status", "unknown")
        except (OSError, ValueError):
            s, status = {}, "no summary"
        r.writerow([seed, terrain, status, cell(s.get("sim_time_s")), cell(s.get("wall_time_s")),
                    cell(s.get("real_time_factor"))])
        try:
            j = json.loads((run / "metrics.json").read_text())
            followers, leaders = j["followers"], {l["id"]: l for l in j["leaders"]}
        except (OSError, ValueError, KeyError, TypeError):
            followers, leaders = [], {}
        try:  # leader-lost events and stuck (docs/convoy.md) per follower, from the convoy report
            convoy_report = {c["follower"]: c for c in json.loads((run / "convoy.json").read_text())}
        except (OSError, ValueError, KeyError, TypeError):
            convoy_report = {}
        if status != "completed" or not followers:
            e.writerow([seed, terrain, convoy, controller, status] + [""] * (3 + len(metrics) + 7))
            continue
        for m in sorted(followers, key=lambda m: m["position"]):
            head = leaders.get(m["leader"], {})
            e.writerow([seed, terrain, convoy, controller, status, m["id"], m["position"], m["leader"],
                        *[cell(m[k]) for k in metrics], m["obstacles_hit"], m["samples"],
                        cell(m["segment_length_m"]), cell(head.get("max_speed_mps")),
                        cell(head.get("mean_moving_speed_mps")),
                        convoy_report.get(m["id"], {}).get("leader_lost_events", ""),
                        int(convoy_report[m["id"]]["stuck"]) if m["id"] in convoy_report else ""])
EOF
[ $? = 0 ] || die "could not write $OUTPUT/ensemble.csv" 2
echo "run_ensemble: $OUTPUT/ensemble.csv (metrics per run and follower), $OUTPUT/runs.csv (times)"
# Figures and report.md need Debian's matplotlib, which lives with the system's Python.
if /usr/bin/python3 -c "import matplotlib, numpy" 2> /dev/null; then
  /usr/bin/python3 "$ROOT/tools/ensemble_figures.py" "$OUTPUT" || die "could not draw the figures" 2
else
  echo "run_ensemble: no figures: install python3-matplotlib python3-numpy (launch_scripts/setup.sh does)" >&2
fi
if [ $# -gt 0 ]; then
  echo "run_ensemble: $# runs failed: $*" >&2
  exit 2
fi
}

if [ -n "$RUN_ONE" ]; then
  case " ${ids[*]} " in
    *" $RUN_ONE "*) ;;
    *) die "--run-one: $RUN_ONE is not a run of this ensemble (SEED_TERRAIN, seeds $FIRST..$((FIRST + COURSES - 1)), terrains $TERRAINS)" ;;
  esac
  run_one "$RUN_ONE"  # replaces this shell with the run; returns only if the course failed
  exit 1
fi
if [ $GATHER_ONLY = 1 ]; then
  failed=()
  for id in "${ids[@]}"; do completed "$OUTPUT/runs/$id" || failed+=("$id"); done
  gather "${failed[@]}"
  exit 0
fi

# Slurm jobs submitted for DIR (DIR/slurm/jobs: "array ID" and "gather ID" lines) that have not
# ended yet: their ids, one a line. Nothing when there are none or Slurm cannot be asked.
SL=$OUTPUT/slurm
unended_jobs() {
  [ -s "$SL/jobs" ] && command -v squeue > /dev/null || return 0
  local list
  list=$(awk '{ print $2 }' "$SL/jobs" | paste -sd, -)
  [ -n "$list" ] || return 0
  squeue -h --jobs="$list" -o '%F %T' 2> /dev/null |
    awk '$2 !~ /^(COMPLETED|CANCELLED|FAILED|TIMEOUT|NODE_FAIL|PREEMPTED|BOOT_FAIL|DEADLINE|OUT_OF_MEMORY|SPECIAL_EXIT|REVOKED)$/ && !seen[$1]++ { print $1 }'
}
alive=$(unended_jobs | paste -sd' ' -)
[ -z "$alive" ] || die "$OUTPUT has Slurm jobs that have not ended ($alive): wait for them (squeue --jobs=${alive// /,}) or cancel them (scancel $alive) first"

if [ $SLURM = 1 ]; then
  at_a_time=""; [ $JOBS_SET = 0 ] || at_a_time=", $JOBS at a time"
  echo "run_ensemble: ${#ids[@]} runs ($COURSES courses x ${#terrains[@]} terrains, $CONVOY); $skipped finished before, ${#todo[@]} to submit$at_a_time"
  mkdir -p "$SL" || die "cannot create $SL"
  if [ ${#todo[@]} -gt 0 ]; then
    max=$(scontrol show config 2> /dev/null | sed -n 's/^MaxArraySize *= *\([0-9]*\).*/\1/p')
    [ -z "$max" ] || [ ${#todo[@]} -le "$max" ] ||
      die "${#todo[@]} runs to submit, more than one array job may hold on this cluster (MaxArraySize $max): submit fewer courses first (a smaller --courses; the same command with the full --courses then submits only the rest)"
  fi
  printf '%s\n' "${todo[@]}" | sed '/^$/d' > "$SL/todo.txt" || die "cannot write $SL/todo.txt"
  # What an array task and the gather job run: this script, with the ensemble's options, on
  # any node (the same paths everywhere).
  build=$(cd "$BIN/.." && pwd)
  command=(env "SYNDDS_BUILD_DIR=$build" "$ROOT/launch_scripts/run_ensemble.sh" --courses "$COURSES"
           --output "$OUTPUT" --terrains "$TERRAINS" --convoy "$CONVOY" --protocol "$PROTOCOL"
           --first-seed "$FIRST"
           "${DURATION[@]}")
  [ -z "$POLICY" ] || command+=(--follower-policy "$POLICY")
  [ -z "$RIG" ] || command+=(--follower-rig "$RIG")
  [ -z "$TRAIL" ] || command+=(--follower-trail "$TRAIL")
  [ "$VIDEOS" = 0 ] || command+=(--videos)
  {
    echo '#!/usr/bin/env bash'
    echo '# The gather job of this ensemble (written by run_ensemble.sh --slurm).'
    printf 'exec'; printf ' %q' "${command[@]}" --gather-only; echo
  } > "$SL/gather.sh" || die "cannot write $SL/gather.sh"
  name=ensemble-$(basename "$OUTPUT")
  array=""; after=()
  if [ ${#todo[@]} -gt 0 ]; then
    limit=""; [ $JOBS_SET = 0 ] || limit="%$JOBS"
    out=$(sbatch --parsable --array="0-$((${#todo[@]} - 1))$limit" --job-name="$name" \
          --chdir="$OUTPUT" --output="$SL/task-%A_%a.out" "${SLURM_EXTRA[@]}" \
          "$ROOT/launch_scripts/slurm/ensemble_task.sbatch" "$SL/todo.txt" "${command[@]}") ||
      die "sbatch refused the array job (its message is above; --slurm-args '$SLURM_ARGS')"
    array=${out%%;*}
    [[ $array =~ ^[0-9]+$ ]] || die "sbatch answered '$out', not a job id"
    after=(--dependency="afterany:$array")
  fi
  out=$(sbatch --parsable "${after[@]}" --job-name="$name-gather" --ntasks=1 --chdir="$OUTPUT" \
        --output="$SL/gather-%j.out" "${SLURM_EXTRA[@]}" "$SL/gather.sh") || {
    [ -z "$array" ] || scancel "$array" 2> /dev/null
    die "sbatch refused the gather job (its message is above)${array:+; array job $array cancelled}"
  }
  gather_job=${out%%;*}
  [[ $gather_job =~ ^[0-9]+$ ]] || die "sbatch answered '$out', not a job id"
  { [ -z "$array" ] || echo "array $array"; echo "gather $gather_job"; } > "$SL/jobs"
  jobs=${array:+$array,}$gather_job
  [ -z "$array" ] ||
    echo "run_ensemble: array job $array: ${#todo[@]} runs (listed in $SL/todo.txt)$at_a_time; logs $OUTPUT/runs/<run>.log, $SL/task-${array}_<index>.out"
  echo "run_ensemble: gather job $gather_job${array:+ (after array job $array)} writes $OUTPUT/ensemble.csv, runs.csv, figures/ and report.md; its output $SL/gather-$gather_job.out"
  echo "run_ensemble: follow them with: squeue --jobs=$jobs; stop them with: scancel ${jobs//,/ }"
  [ $WAIT = 1 ] || exit 0

  # Until the gather job has ended: its state every half second for a minute, then every 2 s.
  # A job that can never start (e.g. its time limit over the partition's) is named, and the
  # wait given up.
  interrupted=0
  trap 'interrupted=1' INT TERM HUP
  pending=("${todo[@]}"); polls=0; misses=0; info=""; st=""
  while :; do
    info=$(scontrol show job -o "$gather_job" 2> /dev/null) || info=""
    st=$(sed -n 's/.* JobState=\([A-Z_]*\).*/\1/p' <<< "$info")
    if [ -n "$st" ]; then
      misses=0
    else
      misses=$((misses + 1))
      [ $misses -lt 30 ] || die "lost track of gather job $gather_job (scontrol show job $gather_job answers nothing); see $SL/gather-$gather_job.out" 2
    fi
    case "$st" in COMPLETED|FAILED|CANCELLED|TIMEOUT|NODE_FAIL|PREEMPTED|BOOT_FAIL|DEADLINE|OUT_OF_MEMORY) break ;; esac
    stuck=$(squeue -h --jobs="$jobs" -o '%i %r' 2> /dev/null | awk '$2 ~ /^(PartitionTimeLimit|PartitionNodeLimit|PartitionConfig|BadConstraints|DependencyNeverSatisfied|InvalidAccount|InvalidQOS|AssocMaxWallDurationPerJobLimit|QOSMaxWallDurationPerJobLimit)$/ { print; exit }')
    [ -z "$stuck" ] ||
      die "job ${stuck% *} cannot start (${stuck#* }): scancel ${jobs//,/ }, then submit again with other --slurm-args (e.g. -p PARTITION -t MINUTES)" 2
    rest=()
    for id in "${pending[@]}"; do completed "$OUTPUT/runs/$id" || rest+=("$id"); done
    if [ ${#rest[@]} != ${#pending[@]} ]; then
      pending=("${rest[@]}")
      echo "run_ensemble: [$((${#ids[@]} - ${#pending[@]}))/${#ids[@]}] runs completed"
    fi
    [ $interrupted = 0 ] ||
      die "stopped waiting; the jobs go on (squeue --jobs=$jobs; scancel ${jobs//,/ } stops them)" 130
    polls=$((polls + 1))
    if [ $polls -lt 120 ]; then sleep 0.5; else sleep 2; fi
  done
  trap - INT TERM HUP
  code=$(sed -n 's/.* ExitCode=\([0-9]*\):.*/\1/p' <<< "$info")
  cat "$SL/gather-$gather_job.out" 2> /dev/null
  case "$st:$code" in
    COMPLETED:0) exit 0 ;;
    FAILED:2) exit 2 ;;  # the failed runs are listed in the gather job's output, above
    FAILED:1) die "gather job $gather_job failed (exit code 1): see $SL/gather-$gather_job.out" 1 ;;
  esac
  die "gather job $gather_job ended $st (exit code ${code:-unknown}): see $SL/gather-$gather_job.out" 2
fi

echo "run_ensemble: ${#ids[@]} runs ($COURSES courses x ${#terrains[@]} terrains, $CONVOY); $skipped finished before, ${#todo[@]} to run, $JOBS at a time"
declare -A running=()   # pid -> run id
interrupted=0
trap 'interrupted=1' INT TERM HUP
stop_running() {
  for pid in "${!running[@]}"; do kill -TERM "$pid" 2>/dev/null; done
  for pid in "${!running[@]}"; do wait "$pid" 2>/dev/null; done
}
trap stop_running EXIT

start=$SECONDS; done_now=0; failed=()
report() {  # $1 = run id, $2 = exit status
  done_now=$((done_now + 1))
  local state=completed
  if [ "$2" != 0 ] || ! completed "$OUTPUT/runs/$1"; then state="FAILED (status $2, log runs/$1.log)"; failed+=("$1"); fi
  local elapsed=$((SECONDS - start)) left=$((${#todo[@]} - done_now))
  local eta=$((elapsed * left / done_now))
  printf 'run_ensemble: [%d/%d] %s %s; %dm%02ds elapsed, about %dm%02ds left\n' \
      "$((skipped + done_now))" "${#ids[@]}" "$1" "$state" $((elapsed / 60)) $((elapsed % 60)) \
      $((eta / 60)) $((eta % 60))
}
reap() {  # waits for one run to end
  local pid
  while :; do
    for pid in "${!running[@]}"; do
      if ! kill -0 "$pid" 2>/dev/null; then
        wait "$pid"; local code=$?
        local id=${running[$pid]}; unset "running[$pid]"
        [ $interrupted = 1 ] || report "$id" "$code"
        return
      fi
    done
    [ $interrupted = 1 ] && return
    sleep 0.2
  done
}

for id in "${todo[@]}"; do
  [ $interrupted = 1 ] && break
  while [ ${#running[@]} -ge "$JOBS" ] && [ $interrupted = 0 ]; do reap; done
  [ $interrupted = 1 ] && break
  run_one "$id" &
  running[$!]=$id
done
while [ ${#running[@]} -gt 0 ] && [ $interrupted = 0 ]; do reap; done
if [ $interrupted = 1 ]; then
  stop_running
  die "interrupted; run the same command again to go on (finished runs are kept)" 130
fi
trap - EXIT

gather "${failed[@]}"
