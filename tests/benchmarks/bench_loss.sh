#!/usr/bin/env bash
# Packet loss between hosts: a scenario on three network-namespace "hosts" (tests/netns_hosts.sh:
# own address and /dev/shm each; coordinator and recorder on h1, vehicle I with its controller
# and sensors on host (I-1) mod 3 + 1), each host dropping a share of the packets it sends at
# random (nftables). Per run: how it ended, the real-time factor, whether vehicles.csv equals the
# single-process run, and whether any member was declared lost. Needs root and nft.
#
#   tests/benchmarks/bench_loss.sh [--loss "0 10 30"] [--runs N] [--duration S]
#       [--dds-profiles FILE] [--paths 1|2] [--transport udp|udp_redundant] [SCENARIO]
#
# Defaults: config/scenarios/default.yaml, 10 simulated seconds, 2 runs per loss level.
# --paths 2: every host has a second address on a second subnet (two networks): Fast DDS sends
# each datagram to both, and the loss drops each copy on its own (docs/deployment.md).
# --transport udp_redundant: one address, every participant listening on two ports per kind:
# each datagram is sent twice over the one path.
set -uo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)
BIN=${SYNDDS_BUILD_DIR:-$ROOT/build}/bin
LOSSES="0 10 30"; RUNS=2; DURATION=10; PROFILES=(); TRANSPORT=udp; SCENARIO=$ROOT/config/scenarios/default.yaml
while [ $# -gt 0 ]; do
  case "$1" in
    --loss) LOSSES=$2; shift ;;
    --runs) RUNS=$2; shift ;;
    --duration) DURATION=$2; shift ;;
    --dds-profiles) PROFILES=(--dds-profiles "$(realpath "$2")"); shift ;;
    --transport) TRANSPORT=$2; shift ;;
    --paths)
      case "$2" in 1|2) export NETNS_PATHS=$2 ;; *) echo "bench_loss: --paths 1 or 2" >&2; exit 1 ;; esac
      shift ;;
    -h|--help) sed -n '2,16p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) SCENARIO=$(realpath "$1") ;;
  esac
  shift
done
[ "$(id -u)" = 0 ] || { echo "bench_loss: needs root (network namespaces)" >&2; exit 77; }
command -v nft > /dev/null || { echo "bench_loss: needs nft (apt-get install nftables)" >&2; exit 77; }
export SYNDDS_CONFIG_DIR=${SYNDDS_CONFIG_DIR:-$ROOT/config}
WORK=$(mktemp -d)
source "$ROOT/tests/netns_hosts.sh"
trap 'hosts_down; rm -rf "$WORK"' EXIT
"$BIN/syndds_sim" "$SCENARIO" --duration "$DURATION" --output "$WORK/single" --quiet \
  > "$WORK/single.log" 2>&1 || { cat "$WORK/single.log"; exit 1; }
vehicles=($(awk -F, 'NR > 1 && !seen[$3]++ {print $3}' "$WORK/single/vehicles.csv"))
echo "machine: $(nproc) CPUs, load average $(cut -d' ' -f1-3 /proc/loadavg); $(basename "$SCENARIO"), ${DURATION} s; profiles: ${PROFILES[1]:-default}; network paths: ${NETNS_PATHS:-1}; transport: $TRANSPORT"
echo "| loss % | run | end | RTF | vehicles.csv = single process | members declared lost |"
echo "|---|---|---|---|---|---|"
n=0
for loss in $LOSSES; do
  for run in $(seq 1 "$RUNS"); do
    n=$((n + 1))
    hosts_up "sl$n" "$WORK/hosts$n" on h1 h2 h3
    [ "$loss" -gt 0 ] && hosts_loss "$loss"
    out="$WORK/run$n"
    mkdir -p "$out/logs"
    pids=()
    while IFS=$'\t' read -r member cmd; do
      host=h1
      for i in "${!vehicles[@]}"; do
        case "$member" in */"${vehicles[$i]}") host=h$(( i % 3 + 1 )) ;; esac
      done
      on_host "$host" "$out/logs/${member//\//_}.log" sh -c "exec $cmd"
      pids+=($!)
    done < <("$BIN/syndds_plan" "$SCENARIO" --duration "$DURATION" --format launcher \
               --output "$out" --run-id "loss$n" --transport "$TRANSPORT" "${PROFILES[@]}")
    for p in "${pids[@]}"; do wait "$p"; done
    rtf=$(sed -n 's/.*"real_time_factor": *\([0-9.]*\).*/\1/p' "$out/summary.json" 2>/dev/null | head -n1)
    status=$(sed -n 's/.*"status": *"\([a-z]*\)".*/\1/p' "$out/summary.json" 2>/dev/null | head -n1)
    same=no; cmp -s "$WORK/single/vehicles.csv" "$out/vehicles.csv" && same=yes
    # Members declared lost: those that ended the run and those recovered, from the status.
    lost=$(python3 -c 'import json, sys; s = json.load(open(sys.argv[1])); print(len(s.get("lost", [])) + sum(len(r["members"]) for r in s.get("recovery_list", [])))' \
           "$out/logs/run_status.json" 2>/dev/null || echo "-")
    printf '| %s | %s | %s | %s | %s | %s |\n' "$loss" "$run" "${status:-none}" "${rtf:--}" "$same" "$lost"
    hosts_down
  done
done
