#!/usr/bin/env bash
# launch_scripts/run_ensemble.sh --slurm on a two-node Slurm cluster started for the test
# (tests/multiprocess/slurm_cluster.sh; the ensemble's folder is in the cluster's shared
# folder): a 4-course study run locally and as an array job (--slurm --wait) ends with
# byte-identical ensemble.csv files, and its runs ran on both nodes (each task asks for a whole
# node's 4 CPUs, so the two that run at a time are on different nodes). After one run's
# summary.json is deleted, the same command submits exactly that run and the CSV is the same
# again. --slurm-args is split as a shell splits words (a quoted comment reaches sbatch whole).
# Also: --slurm without sbatch on PATH, --wait without --slurm and an unmatched quote in
# --slurm-args are refused.
#   tests/ensemble/test_ensemble_slurm.sh BUILD_DIR
# Needs root (ip netns) and Debian's slurm-wlm; exits 77 (skipped) without them.
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)
export SYNDDS_BUILD_DIR=$1
E=$ROOT/launch_scripts/run_ensemble.sh
SLURM_CLUSTER_PREFIX=slurm_ensemble
. "$ROOT/tests/multiprocess/slurm_cluster.sh"
slurm_cluster_require
slurm_cluster_start
cd "$WORK/job"
fail() {
  echo "FAIL: $*" >&2
  for f in "$WORK"/job/*.log "$WORK"/job/ens/slurm/*.out; do
    [ -f "$f" ] && { echo "---- $f"; cat "$f"; }
  done >&2
  tail -n 5 "$WORK"/job/ens/runs/*.log "$WORK"/log/slurm*.log >&2 2> /dev/null || true
  exit 1
}
# Short runs (rigid ground, 20 simulated seconds: every follower has left the start, so every
# metric has a value), 2 at a time.
args=(--courses 4 --terrains rigid --duration 20 --jobs 2)

# Refusals, before anything is submitted.
mkdir -p nosbatch
for p in bash env dirname nproc; do ln -s "$(command -v "$p")" "nosbatch/$p"; done
code=0
PATH=$WORK/job/nosbatch "$E" "${args[@]}" --output refused --slurm > nosbatch.log 2>&1 || code=$?
[ "$code" = 1 ] && grep -q -- "--slurm needs Slurm's sbatch on PATH" nosbatch.log ||
  fail "--slurm without sbatch: exit $code, $(cat nosbatch.log)"
code=0
"$E" "${args[@]}" --output refused --wait > nowait.log 2>&1 || code=$?
[ "$code" = 1 ] && grep -q -- "--wait needs --slurm" nowait.log || fail "--wait without --slurm: exit $code"
code=0
"$E" "${args[@]}" --output refused --slurm --slurm-args "-p test --comment 'unclosed" > quote.log 2>&1 || code=$?
[ "$code" = 1 ] && grep -q -- "--slurm-args: cannot split" quote.log ||
  fail "an unmatched quote in --slurm-args: exit $code, $(cat quote.log)"
[ ! -e refused ] || fail "a refused command created its output folder"

"$E" "${args[@]}" --output "$WORK/job/local" > local.log 2>&1 || fail "the local ensemble failed"
[ "$(grep -c ',completed,' local/runs.csv)" = 4 ] || fail "local runs.csv: not 4 completed runs"

# As a user on node 1 submits it, with a relative output folder; at most 100 s.
slurm_args=(--slurm --slurm-args "-p test -c 4 --comment 'a study of 4'" --wait --output ens)
in_n1 timeout 100 "$E" "${args[@]}" "${slurm_args[@]}" > slurm1.log 2>&1 || fail "--slurm --wait failed ($?)"
grep -q "0 finished before, 4 to submit, 2 at a time" slurm1.log || fail "not 4 runs submitted"
read -r _ array1 < ens/slurm/jobs
[ "$(ls ens/slurm/task-"${array1}"_*.out | wc -l)" = 4 ] || fail "not 4 tasks in array job $array1"
for n in "${NODES[@]}"; do
  grep -q "ensemble_task.sbatch: run [0-9]*_rigid on $n " ens/slurm/task-"${array1}"_*.out ||
    fail "no run of array job $array1 ran on $n"
done
cmp local/ensemble.csv ens/ensemble.csv || fail "the Slurm ensemble.csv differs from the local one"
[ "$(grep -c ',completed,' ens/runs.csv)" = 4 ] || fail "Slurm runs.csv: not 4 completed runs"
# --slurm-args is split as a shell would: the quoted comment reached sbatch as one value.
job_info=$(in_n1 scontrol show job -o "$array1")
[[ $job_info == *"Comment=a study of 4 "* ]] ||
  fail "array job $array1 has not the comment 'a study of 4': $job_info"
grep -q "^| rigid | 3 | " ens/report.md || fail "the gather job wrote no report.md"

# Resume: one run lost its summary; only it is submitted, and the CSV is the same again.
rm ens/runs/2_rigid/summary.json
in_n1 timeout 100 "$E" "${args[@]}" "${slurm_args[@]}" > slurm2.log 2>&1 || fail "the resumed --slurm --wait failed ($?)"
grep -q "3 finished before, 1 to submit" slurm2.log || fail "the resumed study did not submit 1 run"
[ "$(cat ens/slurm/todo.txt)" = 2_rigid ] || fail "todo.txt: $(cat ens/slurm/todo.txt)"
read -r _ array2 < ens/slurm/jobs
[ "$array2" != "$array1" ] || fail "no new array job"
[ "$(ls ens/slurm/task-"${array2}"_*.out | wc -l)" = 1 ] || fail "array job $array2 does not have exactly one task"
grep -q "run 2_rigid on n[12] " ens/slurm/task-"${array2}"_0.out || fail "the resumed task did not run 2_rigid"
cmp local/ensemble.csv ens/ensemble.csv || fail "the resumed Slurm ensemble.csv differs from the local one"
echo "ok: 4 runs on $(cat ens/slurm/task-"${array1}"_*.out | grep -o ' on n[12] ' | sort | uniq -c | xargs), identical to the local ensemble; 1 run resubmitted"
