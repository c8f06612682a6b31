#!/usr/bin/env bash
# Three "hosts" on one machine: network namespaces joined by a bridge, each host with its own
# /dev/shm (processes of one host share it, as on a real machine; no host sees another's) and
# its own copy of config/. The
# coordinator and recorder run on host 1, the vehicles on host 2, the controllers on host 3.
# The recorded run must equal the single-process run byte for byte.
#
#   multihost.sh multicast          default discovery (multicast on the bridge)
#   multihost.sh discovery-server   every multicast packet dropped by nftables on every host
#                                   (checked: some were dropped); a Fast DDS discovery server
#                                   on host 1 (the setup for networks without multicast)
#   multihost.sh udp                like multicast, with --transport udp
#   multihost.sh secure             like multicast, with DDS Security: the folder of
#                                   make_security.sh copied to each host without the CA's key;
#                                   every process authenticates each of the 5 others
#   multihost.sh partition          the default scenario (its three vehicles and the sensor
#                                   process on host 2) cut off the network for 15 s, longer
#                                   than the 10 s DDS lease: the run aborts naming all four as
#                                   lost and no member of the other hosts. Every process in its
#                                   own pid namespace (the lease decides, as between machines);
#                                   frame deadline 30 s, so that the lease speaks first. The
#                                   cut-off members end without waiting for the lost
#                                   coordinator's readers.
#   multihost.sh lossy-two-paths    every host drops 10 % of what it sends (nftables, at
#                                   random) and has a second address on a second subnet; the
#                                   lossy-network profile (heartbeats and NACK suppression
#                                   1 ms, made from config/dds/profiles.xml as docs/deployment.md
#                                   says): the run completes identical, packets were dropped,
#                                   and the second path carried traffic.
#   multihost.sh lossy-redundant    every host drops 10 % of what it sends, one address each;
#                                   --transport udp_redundant (every datagram sent to two ports
#                                   of its receiver) and the lossy-network profile: the run
#                                   completes identical, packets were dropped, and every process
#                                   listens on two data ports.
# Needs root (ip netns); exits 77 (skipped) without it.
set -euo pipefail
MODE=${1:-multicast}
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)
BIN=${SYNDDS_BIN_DIR:-$ROOT/build/bin}
[ "$(id -u)" -eq 0 ] && ip netns list > /dev/null 2>&1 || { echo "multihost: needs root"; exit 77; }

TAG=sy$$
WORK=$(mktemp -d)
HOSTS=(h1 h2 h3)
# shellcheck source=../netns_hosts.sh
source "$ROOT/tests/netns_hosts.sh"
cleanup() {
  for p in $(jobs -p); do { kill -9 "$p" && wait "$p"; } 2> /dev/null || true; done
  hosts_down
  rm -rf "$WORK"
}
trap cleanup EXIT

multicast=on
case "$MODE" in
  discovery-server|lossy-two-paths|lossy-redundant)
    command -v nft > /dev/null || { echo "multihost: needs nft (Debian package nftables)"; exit 77; } ;;
esac
[ "$MODE" = discovery-server ] && multicast=off
[ "$MODE" = lossy-two-paths ] && export NETNS_PATHS=2
hosts_up "$TAG" "$WORK" "$multicast" "${HOSTS[@]}"
for h in "${HOSTS[@]}"; do
  # Each host has its own copy of the configuration: nothing is shared on disk.
  cp -r "$ROOT/config" "$WORK/$h/config"
  if [ "$MODE" = partition ]; then
    sed 's/frame_timeout_s: 10$/frame_timeout_s: 30/' "$ROOT/config/scenarios/default.yaml" \
      > "$WORK/$h/scenario.yaml"
    grep -q 'frame_timeout_s: 30$' "$WORK/$h/scenario.yaml" || { echo "multihost: no frame_timeout_s"; exit 1; }
  else
    cp "$ROOT/tests/multiprocess/scenarios/two_vehicles.yaml" "$WORK/$h/scenario.yaml"
  fi
done

EXTRA=()
SIM_EXTRA=()
case "$MODE" in
  multicast) ;;
  udp) EXTRA=(--transport udp) ;;
  secure)
    SYNDDS_BUILD_DIR=$(dirname "$BIN") "$ROOT/launch_scripts/make_security.sh" \
      "$ROOT/tests/multiprocess/scenarios/two_vehicles.yaml" --output "$WORK/security" > "$WORK/make_security.log"
    for h in "${HOSTS[@]}"; do
      cp -r "$WORK/security" "$WORK/$h/security" && rm "$WORK/$h/security/ca.key.pem"
    done
    # 20 s simulated (2 by default): a pair that exchanges nothing (the two controllers) has
    # time to finish its handshake, whose first message is resent a second later when the
    # peer did not know the sender yet.
    EXTRA=(--log-level debug --duration 20); SIM_EXTRA=(--duration 20); SECURE_DIRS=1 ;;
  partition) EXTRA=(--realtime --duration 60); export NETNS_PIDNS=1 ;;
  lossy-two-paths|lossy-redundant)
    sed 's|<nanosec>100000000</nanosec>|<nanosec>1000000</nanosec>|' "$ROOT/config/dds/profiles.xml" \
      > "$WORK/lossy.xml"
    [ "$(grep -c '<nanosec>1000000</nanosec></heartbeatPeriod>' "$WORK/lossy.xml")" -ge 3 ] &&
      [ "$(grep -c '<nanosec>1000000</nanosec></nackSupressionDuration>' "$WORK/lossy.xml")" -ge 3 ] ||
      { echo "multihost: the lossy recipe no longer matches profiles.xml"; exit 1; }
    EXTRA=(--dds-profiles "$WORK/lossy.xml")
    [ "$MODE" = lossy-redundant ] && EXTRA+=(--transport udp_redundant)
    hosts_loss 10 ;;
  discovery-server)
    on_host h1 "$WORK/discovery.log" fast-discovery-server -i 0 -l "$NET.1" -p 11811
    EXTRA=(--discovery-server "$NET.1:11811") ;;
  *) echo "multihost: unknown mode $MODE" >&2; exit 2 ;;
esac

RUN_ID=multihost-$$
plan() {  # host -> plan lines for that host's copy
  "$BIN/syndds_plan" "$WORK/$1/scenario.yaml" --format launcher --run-id "$RUN_ID" --domain 3 \
    --config-dir "$WORK/$1/config" --output "$WORK/$1/out" --bin-dir "$BIN" "${EXTRA[@]}" \
    ${SECURE_DIRS:+--security-dir "$WORK/$1/security"}
}
host_of() {
  case "$1" in
    coordinator|recorder) echo h1 ;;
    vehicle/*|sensor/*) echo h2 ;;
    *) echo h3 ;;
  esac
}
pids=()
for h in "${HOSTS[@]}"; do
  while IFS=$'\t' read -r member cmd; do
    [ "$(host_of "$member")" = "$h" ] || continue
    on_host "$h" "$WORK/${member//\//_}.log" sh -c "exec $cmd"
    pids+=($!)
  done < <(plan "$h")
done

if [ "$MODE" = partition ]; then
  rows() { [ -f "$WORK/h1/out/vehicles.csv" ] && wc -l < "$WORK/h1/out/vehicles.csv" || echo 0; }
  for _ in $(seq 600); do [ "$(rows)" -gt 300 ] && break; sleep 0.1; done
  [ "$(rows)" -gt 300 ] || { echo "multihost (partition): the run never got going"; tail -n 5 "$WORK"/*.log; exit 1; }
  ip netns exec "${TAG}h2" ip link set eth0 down
  # The stimulus (a partition of a given length), not a wait for a condition.
  sleep 15
  ip netns exec "${TAG}h2" ip link set eth0 up
  for p in "${pids[@]}"; do wait "$p" || true; done
  reason=$(grep -h "run aborted" "$WORK/coordinator.log" || true)
  echo "multihost (partition): $reason"
  for m in vehicle/lead vehicle/loop vehicle/scurve sensor/lead; do
    grep -q "[ ,]$m[ ,].*lost" <<< "$reason" || { echo "multihost (partition): $m not named lost"; exit 1; }
  done
  if grep -Eq "(controller/|recorder).*lost" <<< "$reason"; then
    echo "multihost (partition): a member of another host was named lost"; exit 1
  fi
  # The cut-off members lost the coordinator by its lease: they end at once, without waiting
  # for its readers (unmatched with the lease) to match theirs.
  if grep -l "did not match within" "$WORK"/*.log; then
    echo "multihost (partition): a member waited for a coordinator it knew was lost"; exit 1
  fi
  echo "multihost (partition): every member of the cut-off host named lost, no other"
  exit 0
fi

status=0
for p in "${pids[@]}"; do
  wait "$p" || status=1
done
if [ $status -ne 0 ] || [ ! -f "$WORK/h1/out/vehicles.csv" ]; then
  echo "multihost ($MODE): a process failed"; tail -n 5 "$WORK"/*.log; exit 1
fi
"$BIN/syndds_sim" "$ROOT/tests/multiprocess/scenarios/two_vehicles.yaml" --quiet \
  --output "$WORK/single" "${SIM_EXTRA[@]}" > /dev/null
if ! cmp "$WORK/h1/out/vehicles.csv" "$WORK/single/vehicles.csv"; then
  echo "multihost ($MODE): recorded run differs from the single-process run"; exit 1
fi
if [ "$MODE" = secure ]; then
  for member in coordinator recorder vehicle_a vehicle_b controller_a controller_b; do
    log=$WORK/$member.log
    n=$(grep -c "DDS Security: participant .* authenticated$" "$log" || true)
    [ "$n" -eq 5 ] || { echo "multihost (secure): $(basename "$log") authenticated $n of 5 participants"; exit 1; }
  done
  echo "multihost (secure): every process authenticated the 5 others"
fi
if [ "$MODE" = discovery-server ]; then
  # The block was real: Fast DDS tried multicast and every packet was dropped.
  dropped=0
  for h in "${HOSTS[@]}"; do dropped=$((dropped + $(multicast_dropped "$h"))); done
  if [ "$dropped" -eq 0 ]; then
    echo "multihost ($MODE): no multicast packet was dropped: the block was not exercised"; exit 1
  fi
  echo "multihost ($MODE): $dropped multicast packets dropped by nftables"
fi
if [ "$MODE" = lossy-two-paths ]; then
  dropped=0; second=0
  for h in "${HOSTS[@]}"; do
    dropped=$((dropped + $(loss_dropped "$h"))); second=$((second + $(second_path_packets "$h")))
  done
  [ "$dropped" -gt 0 ] || { echo "multihost ($MODE): no packet was dropped: the loss was not exercised"; exit 1; }
  [ "$second" -gt 0 ] || { echo "multihost ($MODE): nothing came by the second path"; exit 1; }
  echo "multihost ($MODE): $dropped packets dropped, $second received on the second addresses"
fi
if [ "$MODE" = lossy-redundant ]; then
  dropped=0
  for h in "${HOSTS[@]}"; do dropped=$((dropped + $(loss_dropped "$h"))); done
  [ "$dropped" -gt 0 ] || { echo "multihost ($MODE): no packet was dropped: the loss was not exercised"; exit 1; }
  for member in coordinator recorder vehicle_a vehicle_b controller_a controller_b; do
    grep -Eq "transport udp_redundant: unicast ports [0-9]+ [0-9]+ \(discovery\), [0-9]+ [0-9]+ \(data\)" \
      "$WORK/$member.log" || { echo "multihost ($MODE): $member does not listen on two ports"; exit 1; }
  done
  echo "multihost ($MODE): $dropped packets dropped, every process on two ports per kind"
fi
echo "multihost ($MODE): 3 hosts, $(($(wc -l < "$WORK/h1/out/vehicles.csv") - 1)) rows, identical to the single-process run"
