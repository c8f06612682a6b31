#!/usr/bin/env bash
# Runs a command in a private network namespace with only loopback (multicast routed to lo) and
# a private /dev/shm, so DDS tests never see, or disturb, other DDS traffic on the machine, and
# never meet the shared-memory files that killed processes of earlier runs leave behind (Fast
# DDS then fails to open its ports for minutes). The /dev/shm goes away with the namespace.
# Falls back to a network namespace alone, then to running the command as is, where namespaces
# are not allowed (tests then rely on their own domain ids).
if [ "${SYNDDS_NO_NETNS:-0}" != 1 ] && unshare -n -m true 2>/dev/null; then
  exec unshare -n -m sh -c 'mount -t tmpfs -o mode=1777 tmpfs /dev/shm &&
    ip link set lo up && ip link set lo multicast on &&
    ip route add 224.0.0.0/4 dev lo 2>/dev/null; exec "$@"' sh "$@"
fi
if [ "${SYNDDS_NO_NETNS:-0}" != 1 ] && unshare -n true 2>/dev/null; then
  exec unshare -n sh -c 'ip link set lo up && ip link set lo multicast on &&
    ip route add 224.0.0.0/4 dev lo 2>/dev/null; exec "$@"' sh "$@"
fi
exec "$@"
