#!/usr/bin/env bash
# Runs the paper's statistical study: N random obstacle courses (syndds_course), a convoy on each
# course on each terrain, the six deviation metrics of every follower, one CSV at the end.
#
#   launch_scripts/run_ensemble.sh --courses N --output DIR [--terrains rigid,scm_hard,scm_soft]
#       [--convoy 1L3F|2L2F|3L1F] [--follower-policy FILE] [--jobs J] [--distributed]
#       [--first-seed S] [--duration S]
#
# --follower-policy drives the followers with a learned policy (e.g.
# policies/convoy_follow_lowdim.pt; docs/learning.md) instead of the classical follower.
# Course k has seed first-seed + k (default 1). Each run goes to DIR/runs/<seed>_<terrain>/, its
# scenario to DIR/courses/. Runs in one process each (syndds_sim, byte-identical to a distributed
# run) unless --distributed (run_scenario.sh: one process per member), J at a time (default: the
# number of cores). Resumable: a run whose summary.json says "completed" is skipped, any other is
# run again. At the end: DIR/ensemble.csv (one row per run and follower: the metrics, no wall
# times, so an interrupted and resumed ensemble ends with the same file as an uninterrupted one)
# and DIR/runs.csv (one row per run: status, simulated and wall time, real-time factor), then the
# figures (DIR/figures/) and DIR/report.md (tools/ensemble_figures.py).
# Exit status: 0 every run completed, 2 some failed (listed), 1 bad command line, 130 interrupted.
set -u
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
BIN=${SYNDDS_BUILD_DIR:-$ROOT/build}/bin
die() { echo "run_ensemble: $1" >&2; exit "${2:-1}"; }  # message [exit status, default 1]

COURSES=""; OUTPUT=""; TERRAINS="rigid,scm_hard,scm_soft"; CONVOY=1L3F
JOBS=$(nproc 2>/dev/null || echo 1); DISTRIBUTED=0; FIRST=1; DURATION=(); POLICY=""
while [ $# -gt 0 ]; do
  case "$1" in
    --courses) [ $# -ge 2 ] || die "--courses needs a number"; COURSES=$2; shift ;;
    --output) [ $# -ge 2 ] || die "--output needs a directory"; OUTPUT=$2; shift ;;
    --terrains) [ $# -ge 2 ] || die "--terrains needs a list"; TERRAINS=$2; shift ;;
    --convoy) [ $# -ge 2 ] || die "--convoy needs a value"; CONVOY=$2; shift ;;
    --jobs) [ $# -ge 2 ] || die "--jobs needs a number"; JOBS=$2; shift ;;
    --first-seed) [ $# -ge 2 ] || die "--first-seed needs a number"; FIRST=$2; shift ;;
    --duration) [ $# -ge 2 ] || die "--duration needs seconds"; DURATION=(--duration "$2"); shift ;;
    --follower-policy) [ $# -ge 2 ] || die "--follower-policy needs a file"; POLICY=$2; shift ;;
    --distributed) DISTRIBUTED=1 ;;
    -h|--help) sed -n '2,19p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) die "unknown option: $1 (see --help)" ;;
  esac
  shift
done
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
for p in syndds_course syndds_sim; do
  [ -x "$BIN/$p" ] || die "$BIN/$p is missing: run launch_scripts/setup.sh first"
done
command -v python3 > /dev/null || die "python3 is needed to write the CSV files (apt-get install python3)"
if [ -n "$POLICY" ] && [ ! -f "$ROOT/config/$POLICY" ] && [ ! -f "$POLICY" ]; then
  die "--follower-policy: no file $POLICY (looked in config/ and here)"
fi
[ -n "$POLICY" ] && [ ! -f "$ROOT/config/$POLICY" ] && POLICY=$(cd "$(dirname "$POLICY")" && pwd)/$(basename "$POLICY")
mkdir -p "$OUTPUT/courses" "$OUTPUT/runs" || die "cannot create $OUTPUT"
# The courses are generated once: an ensemble folder belongs to one convoy and one follower.
setup="convoy=$CONVOY follower_policy=${POLICY:-classical}"
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
echo "run_ensemble: ${#ids[@]} runs ($COURSES courses x ${#terrains[@]} terrains, $CONVOY); $skipped finished before, ${#todo[@]} to run, $JOBS at a time"

# One run: the course's scenario (generated once), then the run itself; its log beside its folder.
run_one() {
  local id=$1 seed=${1%%_*} terrain=${1#*_}
  local scenario="$OUTPUT/courses/$id.yaml" dir="$OUTPUT/runs/$id" log="$OUTPUT/runs/$id.log"
  rm -rf "$dir"
  if [ ! -s "$scenario" ]; then
    "$BIN/syndds_course" --seed "$seed" --terrain "$terrain" --convoy "$CONVOY" \
        ${POLICY:+--follower-policy "$POLICY"} --output "$scenario.tmp" > "$log" 2>&1 &&
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
                "leader_max_speed_mps", "leader_mean_speed_mps"])
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
        if status != "completed" or not followers:
            e.writerow([seed, terrain, convoy, controller, status] + [""] * (3 + len(metrics) + 5))
            continue
        for m in sorted(followers, key=lambda m: m["position"]):
            head = leaders.get(m["leader"], {})
            e.writerow([seed, terrain, convoy, controller, status, m["id"], m["position"], m["leader"],
                        *[cell(m[k]) for k in metrics], m["obstacles_hit"], m["samples"],
                        cell(m["segment_length_m"]), cell(head.get("max_speed_mps")),
                        cell(head.get("mean_moving_speed_mps"))])
EOF
[ $? = 0 ] || die "could not write $OUTPUT/ensemble.csv" 2
echo "run_ensemble: $OUTPUT/ensemble.csv (metrics per run and follower), $OUTPUT/runs.csv (times)"
# Figures and report.md need Debian's matplotlib, which lives with the system's Python.
if /usr/bin/python3 -c "import matplotlib, numpy" 2> /dev/null; then
  /usr/bin/python3 "$ROOT/tools/ensemble_figures.py" "$OUTPUT" || die "could not draw the figures" 2
else
  echo "run_ensemble: no figures: install python3-matplotlib python3-numpy (launch_scripts/setup.sh does)" >&2
fi
if [ ${#failed[@]} -gt 0 ]; then
  echo "run_ensemble: ${#failed[@]} runs failed: ${failed[*]}" >&2
  exit 2
fi
