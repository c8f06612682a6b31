#!/usr/bin/env bash
# Runs under launch_scripts/slurm/run_scenario.sbatch on the two-node test cluster
# (tests/multiprocess/slurm_cluster.sh) that need more than starting processes:
#   recover   on_member_loss: recover with checkpoints, and the viewer (--view) on the first
#             node answering while the run goes on; vehicle/a, placed on the node without
#             the coordinator, is killed with SIGKILL mid-run: its node's launcher restarts it
#             (it learns that the run goes on from the coordinator's status file on the shared
#             folder) and the run completes byte-identical to the single-process run.
#   security  DDS Security (launch_scripts/make_security.sh): every process authenticates with
#             its own identity across the two nodes; the run completes byte-identical.
# Needs root (ip netns) and Debian's slurm-wlm; exits 77 (skipped) without them.
set -euo pipefail
MODE=${1:?usage: slurm_launch.sh recover|security}
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)
BIN=${SYNDDS_BIN_DIR:-$ROOT/build/bin}
SLURM_CLUSTER_PREFIX="slurm $MODE"
SLURM_JOB_WAIT_S=150
. "$ROOT/tests/multiprocess/slurm_cluster.sh"
slurm_cluster_require
case "$MODE" in
  recover|security) ;;
  *) echo "slurm_launch.sh: unknown mode $MODE (recover, security)"; exit 2 ;;
esac
[ "$MODE" != security ] || command -v openssl > /dev/null || { echo "slurm $MODE: needs openssl; skipped"; exit 77; }
slurm_cluster_start
cd "$WORK/job"
SBATCH=$ROOT/launch_scripts/slurm/run_scenario.sbatch
OUT=$WORK/job/out
fail() {
  echo "slurm $MODE: $*"
  cat "$WORK"/job/*.out 2> /dev/null || true
  tail -n 3 "$OUT"/logs/*.log "$WORK"/log/slurm*.log 2> /dev/null || true
  exit 1
}
# The files that must equal the single-process run's: all but the logs, the checkpoints, the
# summaries (wall times), recoveries.csv, launch.args and the Slurm files.
results() {
  (cd "$1" && find . -type f ! -path './logs/*' ! -path './checkpoints/*' ! -path './slurm/*' \
     ! -name 'summary.*' ! -name recoveries.csv ! -name launch.args | sort)
}
same_as_single() {  # scenario [options]
  "$BIN/syndds_sim" "$@" --quiet --output "$WORK/single" > "$WORK/single.log" 2>&1 ||
    fail "the single-process run failed: $(tail -n 1 "$WORK/single.log")"
  [ "$(results "$OUT")" = "$(results "$WORK/single")" ] ||
    fail "the runs wrote different files: $(diff <(results "$OUT") <(results "$WORK/single") | tr '\n' ' ')"
  local f
  for f in $(results "$OUT"); do
    cmp "$OUT/$f" "$WORK/single/$f" || fail "$f differs from the single-process run's"
  done
}

if [ "$MODE" = recover ]; then
  SCENARIO=$WORK/job/recoverable.yaml
  sed -e 's/end_time_s: 2.0/end_time_s: 8.0/' \
      -e 's/on_member_loss: abort}/on_member_loss: recover, rejoin_timeout_s: 60}/' \
      "$ROOT/tests/multiprocess/scenarios/two_vehicles.yaml" > "$SCENARIO"
  echo "checkpoint: {every_s: 1.0}" >> "$SCENARIO"
  grep -q "on_member_loss: recover" "$SCENARIO" || fail "could not make the recoverable scenario"
  # In real time (8 s): long enough to kill a member mid-run on a fast machine.
  submit_job run -N 2 -n 8 "$SBATCH" "$SCENARIO" --output out --bin-dir "$BIN" --log-level warn --realtime \
    --view --view-port 0
  # Killed once a checkpoint is complete and the run is past it (frame 250 of 800 recorded).
  victim=""
  for _ in $(seq 600); do  # up to 120 s
    if compgen -G "$OUT/checkpoints/*/complete.yaml" > /dev/null &&
       [ "$(wc -l < "$OUT/vehicles.csv" 2> /dev/null || echo 0)" -gt 500 ]; then
      victim=$(awk '$1 == "vehicle/a" { print $2, $3 }' "$OUT/logs/pids" | tail -n 1)
      break
    fi
    state=$(in_n1 scontrol show job -o "$job" 2> /dev/null | sed -n 's/.* JobState=\([A-Z_]*\).*/\1/p')
    case "$state" in RUNNING|PENDING|CONFIGURING|"") ;; *) fail "the job ended ($state) before vehicle/a could be killed" ;; esac
    sleep 0.2
  done
  [ -n "$victim" ] || fail "the run did not reach a checkpoint and frame 250 in time"
  # The viewer (--view) runs beside the coordinator on n1 and answers there.
  url=$(sed -n 's/.*viewer at \(http[^ ]*\).*/\1/p' run.out | head -n 1)
  [ -n "$url" ] || fail "the job's output names no viewer URL"
  hostport=${url#http://}; hostport=${hostport%%/*}
  reply=$(in_n1 timeout 10 bash -c 'exec 3<>"/dev/tcp/${1%:*}/${1##*:}" && printf "GET / HTTP/1.0\r\nHost: %s\r\n\r\n" "$1" >&3 && head -c 12 <&3' _ "$hostport") || true
  [[ $reply == "HTTP/1."?" 200" ]] || fail "the viewer at $url (on n1) does not answer: '$reply'"
  read -r node pid <<< "$victim"
  [ "$node" = n2 ] || fail "vehicle/a ran on $node: expected the node without the coordinator (n2)"
  kill -KILL "$pid"
  wait_job
  [ "$state" = COMPLETED ] && [ "$exit_code" = 0:0 ] ||
    fail "the run's job ended $state (reason $reason) with exit code $exit_code"
  grep -q "vehicle/a was killed by signal 9; restarting it" run.out || fail "the launcher on n2 did not restart vehicle/a"
  [ "$(awk '$1 == "vehicle/a" && $2 == "n2"' "$OUT/logs/pids" | wc -l)" = 2 ] ||
    fail "vehicle/a was not started twice on n2: $(cat "$OUT/logs/pids")"
  grep -q ',vehicle/a,' "$OUT/recoveries.csv" || fail "no recovery of vehicle/a in recoveries.csv"
  same_as_single "$SCENARIO" --realtime
  echo "slurm recover: vehicle/a killed on n2 (pid $pid), restarted by n2's launcher, run byte-identical to the single-process run ($(($(wc -l < "$OUT/vehicles.csv") - 1)) rows)"
else
  SCENARIO=$ROOT/tests/multiprocess/scenarios/two_vehicles.yaml
  "$ROOT/launch_scripts/make_security.sh" "$SCENARIO" --output "$WORK/job/security" > "$WORK/job/make_security.log" 2>&1 ||
    fail "make_security.sh failed: $(tail -n 3 "$WORK/job/make_security.log")"
  # Secured processes find each other by multicast discovery (run_scenario.sbatch --multicast):
  # the test cluster's network gets multicast for this run.
  for n in "${NODES[@]}"; do
    ip -n "$TAG$n" link set eth0 multicast on
    ip -n "$TAG$n" route add 224.0.0.0/4 dev eth0
  done
  # Without --multicast the script refuses at once, naming the reason.
  run_job nomulticast -N 1 -n 1 "$SBATCH" "$SCENARIO" --bin-dir "$BIN" --security-dir "$WORK/job/security"
  [ "$state" = FAILED ] && grep -q -- "--security-dir needs --multicast" nomulticast.out ||
    fail "--security-dir without --multicast: job ended $state"
  # In real time for 4 s: a pair that exchanges no data (controller/a and vehicle/b) must still
  # finish its handshake before the run ends, and a first handshake message sent before the peer
  # knew the sender is only resent after a while.
  run_job run -N 2 -n 8 "$SBATCH" "$SCENARIO" --output out --bin-dir "$BIN" --transport udp \
    --security-dir "$WORK/job/security" --log-level debug --multicast --realtime --duration 4
  [ "$state" = COMPLETED ] && [ "$exit_code" = 0:0 ] ||
    fail "the run's job ended $state (reason $reason) with exit code $exit_code"
  for n in "${NODES[@]}"; do
    grep -q " $n " "$OUT/logs/pids" || fail "no process of the run ran on $n"
  done
  # Each process authenticated each of the 5 others (the participant listener's debug line).
  for log in "$OUT"/logs/{coordinator,recorder,vehicle_a,vehicle_b,controller_a,controller_b}.log; do
    n=$(grep -c " authenticated$" "$log" || true)
    [ "$n" = 5 ] || fail "$(basename "$log") authenticated $n participants, not 5"
  done
  same_as_single "$SCENARIO" --duration 4
  echo "slurm security: 6 processes on 2 nodes, each authenticated the 5 others, run byte-identical to the single-process run"
fi
