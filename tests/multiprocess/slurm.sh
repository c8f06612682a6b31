#!/usr/bin/env bash
# A two-node Slurm cluster on one machine (tests/multiprocess/slurm_cluster.sh), and a run
# submitted to it with launch_scripts/slurm/run_scenario.sbatch. The run's output is in the
# cluster's temporary folder, which both nodes see, as a cluster's shared filesystem. The
# nodes have no multicast route, as on many clusters: the run finds its processes through the
# discovery server the batch script starts.
# The run must complete, its processes must have run on both nodes, and the recorded
# vehicles.csv must equal the single-process run's byte for byte.
# Needs root (ip netns) and Debian's slurm-wlm; exits 77 (skipped) without them.
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)
BIN=${SYNDDS_BIN_DIR:-$ROOT/build/bin}
SCENARIO=$ROOT/tests/multiprocess/scenarios/two_vehicles.yaml
. "$ROOT/tests/multiprocess/slurm_cluster.sh"
slurm_cluster_require
slurm_cluster_start

# The user's side: submit from a folder both nodes see, with a relative output folder.
cd "$WORK/job"
SBATCH=$ROOT/launch_scripts/slurm/run_scenario.sbatch
fail() {
  echo "slurm: $*"
  cat "$WORK"/job/*.out 2> /dev/null || true
  sed 's/\x1b\[[0-9;]*m//g' "$WORK/job/out/slurm/discovery.log" 2> /dev/null | tail -n 5 || true
  tail -n 3 "$WORK"/job/out/logs/*.log "$WORK"/log/slurm*.log 2> /dev/null || true
  exit 1
}

# A bad option ends the job at once, with the option named.
run_job bad -N 1 -n 1 "$SBATCH" "$SCENARIO" --transport tcp --bin-dir "$BIN"
[ "$state" = FAILED ] && [ "$exit_code" = 1:0 ] && grep -q -- "--transport 'tcp'" bad.out ||
  fail "a bad --transport: job ended $state with exit code $exit_code"

run_job run -N 2 -n 8 "$SBATCH" "$SCENARIO" --output out --bin-dir "$BIN"
[ "$state" = COMPLETED ] && [ "$exit_code" = 0:0 ] ||
  fail "the run's job ended $state (reason $reason) with exit code $exit_code"
grep -q "completed (summary.json status: completed)" run.out || fail "the job's output does not say completed"
grep -q '^  "status": "completed"' "$WORK/job/out/summary.json" || fail "summary.json does not say completed"
for n in "${NODES[@]}"; do
  grep -q " $n " "$WORK/job/out/logs/pids" || fail "no process of the run ran on $n"
done
"$BIN/syndds_sim" "$SCENARIO" --quiet --output "$WORK/single" > /dev/null
cmp "$WORK/job/out/vehicles.csv" "$WORK/single/vehicles.csv" ||
  fail "recorded run differs from the single-process run"
echo "slurm: a run on 2 nodes ($(cut -f2 "$WORK/job/out/slurm/tasks.tsv" | sort | uniq -c | xargs)), $(($(wc -l < "$WORK/job/out/vehicles.csv") - 1)) rows, identical to the single-process run"
