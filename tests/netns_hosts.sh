# Several "hosts" on one machine, sourced by tests and benchmarks (needs root): network
# namespaces joined by a bridge, each host with its own address (NET.k) and its own /dev/shm
# (processes of one host share it, as on a real machine; no host sees another's), optionally
# pinned to CPUs of its own.
#
#   source tests/netns_hosts.sh
#   hosts_up TAG WORK MULTICAST h1 h2 ...   # MULTICAST: on (route 224.0.0.0/4) or off
#                                            # (off: nftables drops every multicast packet a
#                                            # host sends or receives, counted; needs nft)
#   multicast_dropped h1                     # packets the host's rule dropped so far
#   hosts_loss PERCENT                       # every host drops PERCENT % of the packets it
#                                            # sends to the others, at random (nftables numgen)
#   second_path_packets h1                   # with NETNS_PATHS=2: packets the host received
#                                            # on its second address so far (counted)
#   loss_dropped h1                          # packets hosts_loss dropped there so far
#
# NETNS_PATHS=2: every host has a second address on a second subnet (NET2.k), as a host on two
# networks has; Fast DDS announces a unicast locator per address and sends each datagram to
# every one, so a packet is lost only if both copies are (docs/deployment.md, "Lossy networks").
#   on_host h1 LOG command...                # in the background; $! is its pid
#   hosts_down                               # also on EXIT if the caller traps it
#
# Sets NET and NET2 (the hosts' /24 prefixes) and HOST_CPUS[h] (a taskset CPU list; empty: any CPU).

NETNS_TAG=""; NETNS_WORK=""; NETNS_HOSTS=(); declare -gA HOST_CPUS=()

hosts_up() {
  NETNS_TAG=$1; NETNS_WORK=$2; local multicast=$3; shift 3
  NETNS_HOSTS=("$@")
  NET=10.77.$(( $$ % 200 + 20 )); NET2=10.78.$(( $$ % 200 + 20 ))
  ip netns add "${NETNS_TAG}br"
  ip -n "${NETNS_TAG}br" link add br0 type bridge
  ip -n "${NETNS_TAG}br" link set br0 up
  local i=0 h
  for h in "${NETNS_HOSTS[@]}"; do
    i=$((i + 1))
    ip netns add "$NETNS_TAG$h"
    ip link add "$NETNS_TAG${h}a" type veth peer name "$NETNS_TAG${h}b"
    ip link set "$NETNS_TAG${h}a" netns "$NETNS_TAG$h"
    ip link set "$NETNS_TAG${h}b" netns "${NETNS_TAG}br"
    ip -n "$NETNS_TAG$h" link set lo up
    ip -n "$NETNS_TAG$h" link set "$NETNS_TAG${h}a" name eth0
    ip -n "$NETNS_TAG$h" addr add "$NET.$i/24" dev eth0
    if [ "${NETNS_PATHS:-1}" = 2 ]; then
      ip -n "$NETNS_TAG$h" addr add "$NET2.$i/24" dev eth0
      ip netns exec "$NETNS_TAG$h" nft -f - <<NFT
table inet syndds_paths {
  chain in { type filter hook input priority 0; ip daddr $NET2.0/24 counter; }
}
NFT
    fi
    ip -n "$NETNS_TAG$h" link set eth0 up
    ip -n "${NETNS_TAG}br" link set "$NETNS_TAG${h}b" master br0
    ip -n "${NETNS_TAG}br" link set "$NETNS_TAG${h}b" up
    # Multicast is routed either way; "off" drops it with nftables, as a network without
    # multicast would (Fast DDS still sends its discovery to the multicast group: taking the
    # route or the link flag away only changed where it failed, not whether it was tried).
    ip -n "$NETNS_TAG$h" route add 224.0.0.0/4 dev eth0
    if [ "$multicast" != on ]; then
      ip netns exec "$NETNS_TAG$h" nft -f - <<'NFT'
table inet syndds_nomulticast {
  chain out { type filter hook output priority 0; ip daddr 224.0.0.0/4 counter drop; }
  chain in { type filter hook input priority 0; ip daddr 224.0.0.0/4 counter drop; }
}
NFT
    fi
    mkdir -p "$NETNS_WORK/$h/shm"
    mount -t tmpfs tmpfs "$NETNS_WORK/$h/shm"
  done
}

multicast_dropped() {  # host: packets its nftables rules dropped (both directions)
  nft_counted "$1" syndds_nomulticast
}

nft_counted() {  # host table: packets counted by the table's rules (0 if there is no table)
  { ip netns exec "$NETNS_TAG$1" nft list table inet "$2" 2> /dev/null || true; } |
    awk '/counter packets/ {for (i = 1; i < NF; ++i) if ($i == "packets") n += $(i + 1)}
         END {print n + 0}'
}
second_path_packets() { nft_counted "$1" syndds_paths; }
loss_dropped() { nft_counted "$1" syndds_loss; }

hosts_loss() {  # percent: random loss of what each host sends on its link (not within a host)
  local h
  for h in "${NETNS_HOSTS[@]}"; do
    ip netns exec "$NETNS_TAG$h" nft -f - <<NFT
table inet syndds_loss {
  chain out { type filter hook output priority 0; oifname "eth0" numgen random mod 100 < $1 counter drop; }
}
NFT
  done
}

on_host() {  # host log command... : run in the host's network namespace, /dev/shm and CPUs
  local h=$1 log=$2; shift 2
  local pin=()
  [ -n "${HOST_CPUS[$h]:-}" ] && pin=(taskset -c "${HOST_CPUS[$h]}")
  # NETNS_PIDNS=1: each process in its own pid namespace too, so that no process takes
  # another host's processes for its own machine's (they share the kernel's boot id) and
  # failure detection across hosts goes by the DDS lease, as between real machines.
  local ns=(-m)
  [ "${NETNS_PIDNS:-0}" = 1 ] && ns=(-m -p -f --kill-child --mount-proc)
  ip netns exec "$NETNS_TAG$h" "${pin[@]}" unshare "${ns[@]}" sh -c \
    'mount --bind "$0" /dev/shm && exec "$@"' "$NETNS_WORK/$h/shm" "$@" > "$log" 2>&1 &
}

hosts_down() {
  local h
  for h in "${NETNS_HOSTS[@]}"; do
    ip netns del "$NETNS_TAG$h" 2> /dev/null || true
    umount "$NETNS_WORK/$h/shm" 2> /dev/null || true
  done
  ip netns del "${NETNS_TAG}br" 2> /dev/null || true
  NETNS_HOSTS=()
}
