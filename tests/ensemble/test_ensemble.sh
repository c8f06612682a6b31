#!/usr/bin/env bash
# launch_scripts/run_ensemble.sh end to end: two courses on two terrains give every CSV column
# and row, the six figures and report.md; an ensemble interrupted after its first run resumes
# (finished runs skipped) and ends with the same ensemble.csv as the uninterrupted one; a run
# that fails is listed and the others go on; --paper makes its courses on the paper's protocol,
# keeps its first course's chase video and writes paper_comparison.md.
#   tests/ensemble/test_ensemble.sh BUILD_DIR
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)
export SYNDDS_BUILD_DIR=$1
E=$ROOT/launch_scripts/run_ensemble.sh
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
fail() { echo "FAIL: $*" >&2; for f in "$work"/*.log; do echo "---- $f"; cat "$f"; done >&2; exit 1; }
args=(--courses 2 --terrains rigid,scm_hard --duration 30)

"$E" "${args[@]}" --jobs 2 --output "$work/a" > "$work/a.log" 2>&1 || fail "ensemble a failed"
header="seed,terrain,convoy,controller,status,follower,position,leader,m_p_avg,m_p_max,m_as_avg,m_as_max,m_rs_avg,m_rs_max,obstacles_hit,samples,segment_length_m,leader_max_speed_mps,leader_mean_speed_mps,leader_lost_events,stuck"
[ "$(head -n1 "$work/a/ensemble.csv")" = "$header" ] || fail "ensemble.csv header: $(head -n1 "$work/a/ensemble.csv")"
[ "$(tail -n +2 "$work/a/ensemble.csv" | wc -l)" = 12 ] || fail "ensemble.csv: not 2 courses x 2 terrains x 3 followers rows"
# Every row: a completed run with all six metrics (after 30 s every follower has driven past the first 10 m of the leader's track), no leader lost and no follower stuck.
awk -F, 'NR > 1 && ($4 != "classical" || $5 != "completed" || $9 == "" || $10 == "" || $11 == "" || $12 == "" || $13 == "" || $14 == "" || $18 <= 0 || $19 <= 0 || $19 > $18 || $20 != 0 || $21 != 0) {exit 1}' \
    "$work/a/ensemble.csv" || fail "ensemble.csv has an incomplete row: $(cat "$work/a/ensemble.csv")"
[ "$(head -n1 "$work/a/runs.csv")" = "seed,terrain,status,sim_time_s,wall_time_s,real_time_factor" ] || fail "runs.csv header"
[ "$(grep -c ',completed,' "$work/a/runs.csv")" = 4 ] || fail "runs.csv: not 4 completed runs"
# The figures and the report that embeds them.
for f in trajectories along_path metrics_boxplots obstacles_hit leader_speed real_time_factor; do
  [ -s "$work/a/figures/$f.png" ] || fail "figures/$f.png missing"
  grep -q "(figures/$f.png)" "$work/a/report.md" || fail "report.md does not show $f.png"
  [ "$(head -c 8 "$work/a/figures/$f.png" | od -An -tx1 | tr -d ' \n')" = 89504e470d0a1a0a ] ||
    fail "figures/$f.png is not a PNG"
done
grep -q "^| scm_hard | 3 | " "$work/a/report.md" || fail "report.md has no row for scm_hard, follower 3"

# Interrupted once its first run is complete (bounded wait), then resumed.
"$E" "${args[@]}" --jobs 1 --output "$work/b" > "$work/b1.log" 2>&1 &
pid=$!
for _ in $(seq 1 1500); do
  grep -q '"status": *"completed"' "$work/b/runs/1_rigid/summary.json" 2>/dev/null && break
  kill -0 "$pid" 2>/dev/null || break
  sleep 0.1
done
grep -q '"status": *"completed"' "$work/b/runs/1_rigid/summary.json" || fail "first run of b never completed"
kill -INT "$pid"
code=0; wait "$pid" || code=$?
[ "$code" = 130 ] || [ "$code" = 0 ] || fail "interrupted ensemble exited $code"
"$E" "${args[@]}" --jobs 1 --output "$work/b" > "$work/b2.log" 2>&1 || fail "resumed ensemble failed"
grep -q "[1-4] finished before" "$work/b2.log" || fail "the resumed ensemble did not skip the finished runs"
cmp "$work/a/ensemble.csv" "$work/b/ensemble.csv" || fail "resumed ensemble.csv differs from the uninterrupted one"
# A third call has nothing to do and writes the same file again.
"$E" "${args[@]}" --output "$work/b" > "$work/b3.log" 2>&1 || fail "third call failed"
grep -q "4 finished before, 0 to run" "$work/b3.log" || fail "third call ran something"
cmp "$work/a/ensemble.csv" "$work/b/ensemble.csv" || fail "ensemble.csv changed on a call with nothing to run"
# A failed run is listed, not fatal: course 2's scenario is broken before the ensemble starts
# (a course file is generated only when missing); course 1 still runs, the CSV lists both, the
# figures are drawn, the exit status is 2 and the failure is named.
mkdir -p "$work/c/courses"
printf 'name: broken\nvehicles: 3\n' > "$work/c/courses/2_rigid.yaml"
code=0
"$E" --courses 2 --terrains rigid --duration 30 --output "$work/c" > "$work/c.log" 2>&1 || code=$?
[ "$code" = 2 ] || fail "ensemble with a broken run exited $code, not 2"
grep -q "1 runs failed: 2_rigid" "$work/c.log" || fail "the failed run is not named"
grep -q "^1,rigid,1L3F,classical,completed,f1," "$work/c/ensemble.csv" || fail "course 1 missing: $(cat "$work/c/ensemble.csv")"
grep -q "^2,rigid,1L3F,classical,no summary,,,,,,,,,,,,,,,,$" "$work/c/ensemble.csv" || fail "the failed run's row: $(cat "$work/c/ensemble.csv")"
grep -q "^2,rigid,no summary,,,$" "$work/c/runs.csv" || fail "runs.csv: $(cat "$work/c/runs.csv")"
grep -q "Runs that did not complete: 2_rigid (no summary)" "$work/c/report.md" || fail "report.md does not list the failed run"
grep -q "2_rigid.yaml" "$work/c/runs/2_rigid.log" || fail "the failed run's log does not name its scenario"
[ -s "$work/c/figures/along_path.png" ] || fail "no figures after a failed run"
# An ensemble folder belongs to one convoy and one follower: another --follower-policy on it
# is refused (its courses were generated for the classical follower).
code=0
"$E" --courses 2 --terrains rigid --duration 30 --output "$work/c" \
    --follower-policy policies/convoy_follow_lowdim.pt > "$work/c2.log" 2>&1 || code=$?
[ "$code" = 1 ] || fail "a changed follower on an existing ensemble exited $code, not 1"
grep -q "was made with convoy=1L3F follower_policy=classical" "$work/c2.log" || fail "no reason given: $(cat "$work/c2.log")"
# The paper's study: its protocol is recorded with the folder and in each course, the first
# course carries the chase video (a still per terrain), and the comparison with the paper is
# written. Contradictory options are refused.
"$E" --paper --courses 1 --terrains rigid --duration 8 --output "$work/p" > "$work/p.log" 2>&1 ||
  fail "paper study failed"
[ "$(cat "$work/p/ensemble.setup")" = "convoy=1L3F follower_policy=classical protocol=paper" ] ||
  fail "ensemble.setup: $(cat "$work/p/ensemble.setup")"
grep -q "^name: convoy_course_paper_1_rigid$" "$work/p/courses/1_rigid.yaml" || fail "not a paper course"
grep -q "target_mps: 1[0-9]" "$work/p/courses/1_rigid.yaml" || fail "the paper's ramp is capped: $(grep target_mps "$work/p/courses/1_rigid.yaml")"
[ -s "$work/p/runs/1_rigid/sensors/f3/chase_camera.avi" ] || fail "no chase video on the first course"
[ -s "$work/p/paper_comparison.md" ] || fail "no paper_comparison.md"
code=0
"$E" --paper --protocol current --output "$work/q" > "$work/q.log" 2>&1 || code=$?
[ "$code" = 1 ] && grep -q "leave --protocol current out" "$work/q.log" || fail "--paper --protocol current: $code $(cat "$work/q.log")"
code=0
"$E" --protocol paper --courses 1 --terrains rigid --duration 8 --output "$work/c" > "$work/c3.log" 2>&1 || code=$?
[ "$code" = 1 ] && grep -q "not convoy=1L3F follower_policy=classical protocol=paper" "$work/c3.log" ||
  fail "another protocol on an existing ensemble: $code $(cat "$work/c3.log")"
echo "ok"
