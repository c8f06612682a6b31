#!/usr/bin/env bash
# Runs the nine convoy scenarios of the paper's experiment (config/scenarios/convoy/:
# 1L3F, 2L2F, 3L1F on rigid, SCM hard and SCM soft ground) and writes one table of results.
#
#   launch_scripts/run_convoy_suite.sh [--output DIR] [--mode distributed|single-process|both]
#       [--only PATTERN] [--domain D] [--learned]
#
# --learned: the same nine with the shipped learned policy as followers
# (config/scenarios/learned/, docs/learning.md).
#
# Each run goes to DIR/<scenario>-<mode>/ (default DIR: runs/convoy-suite-<date>); the table,
# DIR/convoy_suite.md, is printed at the end. Columns: real-time factor, the first leader's
# maximum speed and the time it took to reach x = 190 m (the path's end is at 200 m), and over
# the followers: mean and worst cross-track distance to the track of the vehicle followed,
# smallest distance gap (centre to centre), smallest bumper gap (box to box) and the longest
# time a follower spent below its standstill gap, obstacles hit and leader-lost events. Exit status 0 when every run
# completed, 2 otherwise (the table says which).
set -u
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
OUTPUT=""; MODE=distributed; ONLY=""; PASS=(); SET=convoy
die() { echo "run_convoy_suite: $*" >&2; exit 1; }
while [ $# -gt 0 ]; do
  case "$1" in
    --output) [ $# -ge 2 ] || die "--output needs a directory"; OUTPUT=$2; shift ;;
    --mode) [ $# -ge 2 ] || die "--mode needs a value"; MODE=$2; shift ;;
    --only) [ $# -ge 2 ] || die "--only needs a pattern"; ONLY=$2; shift ;;
    --domain) [ $# -ge 2 ] || die "--domain needs a value"; PASS+=(--domain "$2"); shift ;;
    --learned) SET=learned ;;
    -h|--help) sed -n '2,16p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) die "unknown option: $1 (see --help)" ;;
  esac
  shift
done
case "$MODE" in distributed) modes=(distributed) ;; single-process) modes=(single-process) ;;
  both) modes=(distributed single-process) ;; *) die "--mode must be distributed, single-process or both" ;;
esac
command -v python3 > /dev/null || die "python3 is needed to write the table (apt-get install python3)"
[ -n "$OUTPUT" ] || OUTPUT="runs/convoy-suite-$(date +%Y%m%d-%H%M%S)"
mkdir -p "$OUTPUT" || die "cannot create $OUTPUT"

failed=0
for scenario in "$ROOT"/config/scenarios/$SET/{1L3F,2L2F,3L1F}_*.yaml; do
  name=$(basename "$scenario" .yaml)
  [ -n "$ONLY" ] && [[ "$name" != *$ONLY* ]] && continue
  for mode in "${modes[@]}"; do
    dir="$OUTPUT/$name-$mode"
    rm -rf "$dir"
    args=(--output "$dir" "${PASS[@]}")
    [ "$mode" = single-process ] && args+=(--single-process)
    echo "run_convoy_suite: $name ($mode)"
    if ! "$ROOT/launch_scripts/run_scenario.sh" "$scenario" "${args[@]}" > "$OUTPUT/$name-$mode.log" 2>&1; then
      echo "run_convoy_suite: $name ($mode) failed: $(tail -n 1 "$OUTPUT/$name-$mode.log")" >&2
      failed=1
    fi
  done
done

python3 - "$OUTPUT" <<'EOF'
import csv, json, pathlib, sys
out = pathlib.Path(sys.argv[1])
rows = ["| scenario | mode | status | RTF | leader max speed (m/s) | leader at x=190 (s) "
        "| cross-track mean / max (m) | min distance gap (m) | min bumper gap (m) "
        "| below standstill (s) | obstacles hit | leader lost | stuck |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
for run in sorted(p for p in out.iterdir() if p.is_dir()):
    name, _, mode = run.name.rpartition("-")
    if name.endswith("-single"):  # "single-process" split on its dash
        name, mode = name[:-len("-single")], "single-process"
    summary_file = run / "summary.json"
    if not summary_file.exists():
        rows.append(f"| {name} | {mode} | no summary | | | | | | | | | | |")
        continue
    s = json.loads(summary_file.read_text())
    leader = s["vehicles"][0]
    arrival = "-"
    with open(run / "vehicles.csv") as f:
        for r in csv.DictReader(f):
            if r["vehicle"] == leader["id"] and float(r["x"]) >= 190.0:
                arrival = f"{float(r['time_s']):.1f}"
                break
    convoy = s.get("convoy", [])
    if convoy:
        xt_mean = sum(c["cross_track_m"]["mean"] for c in convoy) / len(convoy)
        xt_max = max(c["cross_track_m"]["max"] for c in convoy)
        gap = min(c["distance_gap_m"]["min"] for c in convoy)
        bumper = min(c["bumper_gap_m"]["min"] for c in convoy)
        below = max(c["time_below_standstill_s"] for c in convoy)
        hits = sum(c["obstacles_hit"] for c in convoy)
        lost = sum(c["leader_lost_events"] for c in convoy)
        stuck = sum(1 for c in convoy if c.get("stuck"))  # followers stopped for good
        followers = (f"{xt_mean:.2f} / {xt_max:.2f} | {gap:.1f} | {bumper:.2f} | {below:.2f} "
                     f"| {hits} | {lost} | {stuck}")
    else:
        followers = "- | - | - | - | - | - | -"
    rows.append(f"| {name} | {mode} | {s['status']} | {s.get('real_time_factor', 0):.3f} "
                f"| {leader['max_speed_mps']:.2f} | {arrival} | {followers} |")
table = "\n".join(rows) + "\n"
(out / "convoy_suite.md").write_text(table)
print(table)
EOF
echo "table: $OUTPUT/convoy_suite.md"
# The paper's Table 1 (top-down trajectories) needs Debian's matplotlib, with the system's Python.
if /usr/bin/python3 -c "import matplotlib, numpy" 2> /dev/null; then
  /usr/bin/python3 "$ROOT/tools/convoy_suite_figures.py" "$OUTPUT" \
    || echo "run_convoy_suite: no trajectories figure (tools/convoy_suite_figures.py failed)" >&2
else
  echo "run_convoy_suite: no trajectories figure: install python3-matplotlib python3-numpy (launch_scripts/setup.sh does)" >&2
fi
[ "$failed" = 0 ] || exit 2
