#!/usr/bin/env bash
# Runs a command in a private network namespace with only loopback (multicast routed to lo), so
# DDS tests never see, or disturb, other DDS traffic on the machine. Falls back to running the
# command as is where namespaces are not allowed (tests then rely on their own domain ids).
if [ "${SYNDDS_NO_NETNS:-0}" != 1 ] && unshare -n true 2>/dev/null; then
  exec unshare -n sh -c 'ip link set lo up && ip link set lo multicast on &&
    ip route add 224.0.0.0/4 dev lo 2>/dev/null; exec "$@"' sh "$@"
fi
exec "$@"
