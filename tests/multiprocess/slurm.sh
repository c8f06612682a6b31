#!/usr/bin/env bash
# A two-node Slurm cluster on one machine, and a run submitted to it with
# launch_scripts/slurm/run_scenario.sbatch. Each node is a network namespace with its own
# hostname and /dev/shm (processes of one node share it, no node sees another's), the two joined
# by a veth pair; slurmctld runs on node 1, a slurmd on each, munged with a key made for the
# test. Everything (configuration, state, logs, the run's output) is in one temporary folder,
# which both nodes see, as a cluster's shared filesystem; nothing is written to /etc.
# The run must complete, its processes must have run on both nodes, and the recorded
# vehicles.csv must equal the single-process run's byte for byte.
# Needs root (ip netns) and Debian's slurm-wlm; exits 77 (skipped) without them.
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)
BIN=${SYNDDS_BIN_DIR:-$ROOT/build/bin}
SCENARIO=$ROOT/tests/multiprocess/scenarios/two_vehicles.yaml
skip() { echo "slurm: $*; skipped"; exit 77; }
[ "$(id -u)" -eq 0 ] && ip netns list > /dev/null 2>&1 || skip "needs root (ip netns)"
for p in slurmctld slurmd sbatch sinfo scontrol munged nsenter unshare; do
  command -v "$p" > /dev/null || skip "$p not found (Debian package slurm-wlm)"
done

TAG=sl$$
NET=10.78.$(( $$ % 200 + 20 ))
WORK=$(mktemp -d)
NODES=(n1 n2)
PIDS=()
cleanup() {
  for p in "${PIDS[@]}"; do kill -TERM "$p" 2> /dev/null || true; done
  for p in "${PIDS[@]}"; do
    for _ in $(seq 50); do kill -0 "$p" 2> /dev/null || break; sleep 0.1; done
    kill -KILL "$p" 2> /dev/null || true
    wait "$p" 2> /dev/null || true
  done
  # Whatever a slurmd started and left behind (slurmstepd, tasks) lives in a node's namespace.
  for n in "${NODES[@]}"; do
    for p in $(ip netns pids "$TAG$n" 2> /dev/null); do kill -KILL "$p" 2> /dev/null || true; done
    ip netns del "$TAG$n" 2> /dev/null || true
  done
  rm -rf "$WORK"
}
trap cleanup EXIT

# Network: n1 (10.78.x.1) and n2 (10.78.x.2) on a veth pair; no multicast route, as on many
# clusters: the run finds its processes through the discovery server the batch script starts.
for n in "${NODES[@]}"; do ip netns add "$TAG$n"; done
ip link add "${TAG}a" type veth peer name "${TAG}b"
ip link set "${TAG}a" netns "${TAG}n1"
ip link set "${TAG}b" netns "${TAG}n2"
i=0
for n in "${NODES[@]}"; do
  i=$((i + 1))
  dev=$([ "$n" = n1 ] && echo "${TAG}a" || echo "${TAG}b")
  ip -n "$TAG$n" link set lo up
  ip -n "$TAG$n" link set "$dev" name eth0
  ip -n "$TAG$n" addr add "$NET.$i/24" dev eth0
  ip -n "$TAG$n" link set eth0 multicast off
  ip -n "$TAG$n" link set eth0 up
done
printf '127.0.0.1 localhost\n%s.1 n1\n%s.2 n2\n' "$NET" "$NET" > "$WORK/hosts"

# munged refuses a socket folder others cannot enter, and a key others can read.
chmod 755 "$WORK"
mkdir -p "$WORK/key" "$WORK/run" "$WORK/log" "$WORK/state" "$WORK/n1" "$WORK/n2" "$WORK/job"
chmod 700 "$WORK/key"
head -c 1024 /dev/urandom > "$WORK/key/munge.key"
chmod 400 "$WORK/key/munge.key"
SOCKET=$WORK/run/munge.socket
nice munged -F --key-file="$WORK/key/munge.key" --socket="$SOCKET" --pid-file="$WORK/run/munged.pid" \
  --seed-file="$WORK/key/munged.seed" --log-file="$WORK/log/munged.log" > /dev/null 2>&1 &
PIDS+=($!)

: > "$WORK/plugstack.conf"
export SLURM_CONF=$WORK/slurm.conf
cat > "$SLURM_CONF" <<EOF
ClusterName=syndds-test
SlurmctldHost=n1($NET.1)
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$SOCKET
StateSaveLocation=$WORK/state
SlurmdSpoolDir=$WORK/%n
SlurmctldPidFile=$WORK/run/slurmctld.pid
SlurmdPidFile=$WORK/%n/slurmd.pid
SlurmctldLogFile=$WORK/log/slurmctld.log
SlurmdLogFile=$WORK/log/slurmd-%n.log
PlugStackConfig=$WORK/plugstack.conf
ProctrackType=proctrack/pgid
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
MpiDefault=none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
ReturnToService=2
SlurmdParameters=config_overrides
NodeName=n1 NodeAddr=$NET.1 CPUs=4 State=UNKNOWN
NodeName=n2 NodeAddr=$NET.2 CPUs=4 State=UNKNOWN
PartitionName=test Nodes=n1,n2 Default=YES MaxTime=10 State=UP
EOF

on_node() {  # node log command...: run in the node's network namespace, hostname and /dev/shm
  local n=$1 log=$2; shift 2
  # nsenter, not ip netns exec: that remounts /sys, without the cgroup mounts slurmd reads.
  nice nsenter --net="/run/netns/$TAG$n" unshare -u -m sh -c \
    'hostname "$0" && mount -t tmpfs tmpfs /dev/shm && mount --bind "$1" /etc/hosts && shift && exec "$@"' \
    "$n" "$WORK/hosts" "$@" > "$log" 2>&1 &
  PIDS+=($!)
}
in_n1() { ip netns exec "${TAG}n1" "$@"; }  # Slurm's commands, as a user on node 1 runs them

for _ in $(seq 50); do [ -S "$SOCKET" ] && break; sleep 0.1; done
[ -S "$SOCKET" ] || { echo "slurm: munged did not start"; cat "$WORK/log/munged.log"; exit 1; }
on_node n1 "$WORK/log/slurmctld.out" slurmctld -D -c -f "$SLURM_CONF"
for n in "${NODES[@]}"; do on_node "$n" "$WORK/log/slurmd-$n.out" slurmd -D -f "$SLURM_CONF"; done

idle=""
for _ in $(seq 100); do  # up to 20 s for both nodes to register
  idle=$(in_n1 sinfo -h -N -o '%N %t' 2> /dev/null | awk '$2 == "idle"' | wc -l)
  [ "$idle" = 2 ] && break
  sleep 0.2
done
if [ "$idle" != 2 ]; then
  echo "slurm: the cluster did not come up"; in_n1 sinfo -N 2>&1 || true
  tail -n 5 "$WORK"/log/*; exit 1
fi

# The user's side: submit from a folder both nodes see, with a relative output folder.
cd "$WORK/job"
SBATCH=$ROOT/launch_scripts/slurm/run_scenario.sbatch
state=""; exit_code=""; reason=""
run_job() {  # name sbatch-arguments...: submit, wait until the job has ended, set state etc.
  local name=$1 job info; shift
  job=$(in_n1 sbatch --parsable -t 5 -o "$WORK/job/$name.out" "$@")
  for _ in $(seq 240); do  # up to 60 s
    info=$(in_n1 scontrol show job -o "$job" 2> /dev/null)
    state=$(sed -n 's/.* JobState=\([A-Z_]*\).*/\1/p' <<< "$info")
    case "$state" in COMPLETED|FAILED|CANCELLED|TIMEOUT|NODE_FAIL|OUT_OF_MEMORY|BOOT_FAIL|DEADLINE) break ;; esac
    sleep 0.25
  done
  exit_code=$(sed -n 's/.* ExitCode=\([0-9:]*\).*/\1/p' <<< "$info")
  reason=$(sed -n 's/.* Reason=\([^ ]*\).*/\1/p' <<< "$info")
}
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
