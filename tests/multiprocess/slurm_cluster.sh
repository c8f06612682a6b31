# shellcheck shell=bash disable=SC2034  # (state, exit_code, ... are for the caller)
# A two-node Slurm cluster on one machine, for tests; sourced, not run:
#
#   . "$ROOT/tests/multiprocess/slurm_cluster.sh"
#   slurm_cluster_require                  # exits 77 (skipped) unless it can be built here
#   slurm_cluster_start                    # builds it; an EXIT trap tears it down
#   run_job NAME [sbatch options] SCRIPT [ARGS...]   # submits from n1, waits for the end
#
# Each node (n1, n2) is a network namespace with its own hostname and /dev/shm (processes of one
# node share it, no node sees another's), the two joined by a veth pair without multicast;
# slurmctld runs on node 1, a slurmd on each (4 CPUs each, partition "test", MaxTime 10 min),
# munged with a key made for the cluster. Everything (configuration, state, logs) is in one
# temporary folder, WORK, which both nodes see, as a cluster's shared filesystem; nothing is
# written to /etc. Needs root (ip netns) and Debian's slurm-wlm and munge. Written for a caller
# running bash with `set -euo pipefail`.
#
# Read (set them before calling the functions; all optional):
#   SLURM_CLUSTER_PREFIX   prefix of the messages it prints (default: slurm)
#   SLURM_JOB_WAIT_S       how long run_job waits for a job to end, in seconds (default: 60)
# Set:
#   WORK                   the cluster's folder; WORK/job is free for the test's own files (the
#                          nodes see it at the same path); removed at exit
#   NODES                  the node names, (n1 n2)
#   NET                    the nodes' network, NET.1 is n1 and NET.2 is n2 (/24)
#   TAG                    prefix of the namespaces (TAGn1, TAGn2) and the veth devices
#   SLURM_CONF             the cluster's slurm.conf (exported, so Slurm's commands use it)
#   state exit_code reason job   by run_job: the job's final JobState (e.g. COMPLETED, FAILED;
#                          the last one seen if it did not end in time), ExitCode ("1:0"),
#                          Reason and id
# Functions:
#   slurm_cluster_require  exits 77 with the reason unless run as root with ip netns and
#                          slurmctld, slurmd, sbatch, sinfo, scontrol, munged, nsenter, unshare
#   slurm_cluster_start    builds the cluster and waits (up to 20 s) until both nodes are idle;
#                          exits 1, with the daemons' logs, if they do not come up
#   in_n1 COMMAND...       runs a command in node 1's network namespace, as a user there would
#                          run Slurm's commands (sbatch, squeue, scontrol, ...)
#   on_node NODE LOG COMMAND...   starts a daemon in a node (its namespace, hostname and
#                          /dev/shm), in the background, output to LOG; stopped at exit
#   run_job NAME ARGS...   sbatch --parsable -t 5 -o WORK/job/NAME.out ARGS... from node 1, then
#                          polls the job until it has ended (at most SLURM_JOB_WAIT_S)
#   submit_job NAME ARGS...   the submission alone (sets job); wait_job: the waiting alone
#   slurm_cluster_cleanup  stops every daemon and whatever the nodes still run, deletes the
#                          namespaces and WORK; the EXIT trap. A test that needs an EXIT trap of
#                          its own sets it after slurm_cluster_start and calls this from it.

SLURM_CLUSTER_PREFIX=${SLURM_CLUSTER_PREFIX:-slurm}
SLURM_JOB_WAIT_S=${SLURM_JOB_WAIT_S:-60}
PIDS=()
NODES=(n1 n2)
TAG=""; NET=""; WORK=""
state=""; exit_code=""; reason=""; job=""

slurm_cluster_require() {
  local p
  if ! { [ "$(id -u)" -eq 0 ] && ip netns list > /dev/null 2>&1; }; then
    echo "$SLURM_CLUSTER_PREFIX: needs root (ip netns); skipped"; exit 77
  fi
  for p in slurmctld slurmd sbatch sinfo scontrol munged nsenter unshare; do
    command -v "$p" > /dev/null || { echo "$SLURM_CLUSTER_PREFIX: $p not found (Debian package slurm-wlm); skipped"; exit 77; }
  done
}

slurm_cluster_cleanup() {
  local p n
  for p in "${PIDS[@]}"; do kill -TERM "$p" 2> /dev/null || true; done
  for p in "${PIDS[@]}"; do
    for _ in $(seq 50); do kill -0 "$p" 2> /dev/null || break; sleep 0.1; done
    kill -KILL "$p" 2> /dev/null || true
    wait "$p" 2> /dev/null || true
  done
  # Whatever a slurmd started and left behind (slurmstepd, tasks) lives in a node's namespace.
  [ -n "$TAG" ] || return 0
  for n in "${NODES[@]}"; do
    for p in $(ip netns pids "$TAG$n" 2> /dev/null); do kill -KILL "$p" 2> /dev/null || true; done
    ip netns del "$TAG$n" 2> /dev/null || true
  done
  [ -z "$WORK" ] || rm -rf "$WORK"
}

on_node() {  # node log command...: run in the node's network namespace, hostname and /dev/shm
  local n=$1 log=$2; shift 2
  # nsenter, not ip netns exec: that remounts /sys, without the cgroup mounts slurmd reads.
  nice nsenter --net="/run/netns/$TAG$n" unshare -u -m sh -c \
    'hostname "$0" && mount -t tmpfs tmpfs /dev/shm && mount --bind "$1" /etc/hosts && shift && exec "$@"' \
    "$n" "$WORK/hosts" "$@" > "$log" 2>&1 &
  PIDS+=($!)
}

in_n1() { ip netns exec "${TAG}n1" "$@"; }  # Slurm's commands, as a user on node 1 runs them

slurm_cluster_start() {
  local n i dev socket idle
  TAG=sl$$
  NET=10.78.$(( $$ % 200 + 20 ))
  WORK=$(mktemp -d)
  trap slurm_cluster_cleanup EXIT

  # Network: n1 (NET.1) and n2 (NET.2) on a veth pair; no multicast route, as on many clusters.
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
  socket=$WORK/run/munge.socket
  nice munged -F --key-file="$WORK/key/munge.key" --socket="$socket" --pid-file="$WORK/run/munged.pid" \
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
AuthInfo=socket=$socket
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

  for _ in $(seq 50); do [ -S "$socket" ] && break; sleep 0.1; done
  [ -S "$socket" ] || { echo "$SLURM_CLUSTER_PREFIX: munged did not start"; cat "$WORK/log/munged.log"; exit 1; }
  on_node n1 "$WORK/log/slurmctld.out" slurmctld -D -c -f "$SLURM_CONF"
  for n in "${NODES[@]}"; do on_node "$n" "$WORK/log/slurmd-$n.out" slurmd -D -f "$SLURM_CONF"; done

  idle=""
  for _ in $(seq 100); do  # up to 20 s for both nodes to register
    idle=$(in_n1 sinfo -h -N -o '%N %t' 2> /dev/null | awk '$2 == "idle"' | wc -l)
    [ "$idle" = 2 ] && break
    sleep 0.2
  done
  if [ "$idle" != 2 ]; then
    echo "$SLURM_CLUSTER_PREFIX: the cluster did not come up"; in_n1 sinfo -N 2>&1 || true
    tail -n 5 "$WORK"/log/*; exit 1
  fi
}

run_job() {  # name sbatch-arguments...: submit, wait until the job has ended, set state etc.
  submit_job "$@"
  wait_job
}
submit_job() {  # name sbatch-arguments...: submit, set job
  local name=$1; shift
  job=$(in_n1 sbatch --parsable -t 5 -o "$WORK/job/$name.out" "$@")
  job=${job%%;*}
}
wait_job() {  # waits until job has ended (at most SLURM_JOB_WAIT_S), sets state etc.
  local info=""
  for _ in $(seq $((SLURM_JOB_WAIT_S * 4))); do  # every 0.25 s
    info=$(in_n1 scontrol show job -o "$job" 2> /dev/null) || true
    state=$(sed -n 's/.* JobState=\([A-Z_]*\).*/\1/p' <<< "$info")
    case "$state" in COMPLETED|FAILED|CANCELLED|TIMEOUT|NODE_FAIL|OUT_OF_MEMORY|BOOT_FAIL|DEADLINE) break ;; esac
    sleep 0.25
  done
  exit_code=$(sed -n 's/.* ExitCode=\([0-9:]*\).*/\1/p' <<< "$info")
  reason=$(sed -n 's/.* Reason=\([^ ]*\).*/\1/p' <<< "$info")
}
