#!/usr/bin/env bash
# Weak scaling across hosts: N vehicles on one host against 2N on two, each host a network
# namespace pinned to a CPU of its own (bench_scaling.sh's hostsK mode: host k on CPU k-1; the
# coordinator and the recorder on host 1), so the second host brings its own core, as a second
# machine would. Efficiency = RTF(N on 1) / RTF(2N on 2): 1 when twice the work on twice the
# hardware runs as fast.
#
#   tests/benchmarks/bench_weak_scaling.sh [--terrain rigid|soft|soft_routed] [--n "4 8"] [--duration S]
#       [--layout per_member|per_host] [--recorder-host first|last] [--output DIR]
#
# --layout per_host: each host's vehicles and controllers in one process (bench_scaling's
# hostgroupsK) instead of one process per member. --recorder-host last: with 2 hosts the
# recorder runs on the second (the coordinator stays on the first).
#
# Needs root (ip netns) and at least 2 CPUs. Writes DIR/weak.csv (terrain, N, RTF on 1 host,
# RTF of 2N on 2 hosts, ratio, efficiency, CPU seconds per host... from bench_scaling's CSVs)
# and DIR/weak.md; the bench_scaling outputs of each run are in DIR/<N>x1 and DIR/<2N>x2.
# Numbers go to docs/performance.md with the command and the machine's load.
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)
TERRAIN=rigid; NS="4 8"; DURATION=10; OUT=""; LAYOUT=per_member; RECORDER_HOST=first
while [ $# -gt 0 ]; do
  case "$1" in
    --terrain) TERRAIN=$2; shift ;;
    --n) NS=$2; shift ;;
    --duration) DURATION=$2; shift ;;
    --output) OUT=$2; shift ;;
    --layout) LAYOUT=$2; shift ;;
    --recorder-host) RECORDER_HOST=$2; shift ;;
    -h|--help) sed -n '2,18p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) echo "bench_weak_scaling: unknown option $1" >&2; exit 1 ;;
  esac
  shift
done
[ "$(nproc)" -ge 2 ] || { echo "bench_weak_scaling: needs 2 CPUs" >&2; exit 1; }
case "$LAYOUT" in
  per_member) MODE=hosts ;;
  per_host) MODE=hostgroups ;;
  *) echo "bench_weak_scaling: --layout per_member or per_host" >&2; exit 1 ;;
esac
[ -n "$OUT" ] || OUT="runs/weak-$TERRAIN-$(date +%Y%m%d-%H%M%S)"
mkdir -p "$OUT"
echo "terrain,n,rtf_1host,rtf_2hosts,ratio,efficiency,load_start_1,load_start_2" > "$OUT/weak.csv"
for n in $NS; do
  two=$((2 * n))
  "$ROOT/tests/benchmarks/bench_scaling.sh" --terrain "$TERRAIN" --n "$n" --modes ${MODE}1 \
      --duration "$DURATION" --output "$OUT/${n}x1" > "$OUT/${n}x1.log" 2>&1 ||
    { echo "bench_weak_scaling: $n vehicles on 1 host failed: $(tail -n 3 "$OUT/${n}x1.log")" >&2; exit 2; }
  "$ROOT/tests/benchmarks/bench_scaling.sh" --terrain "$TERRAIN" --n "$two" --modes ${MODE}2 \
      --recorder-host "$RECORDER_HOST" --duration "$DURATION" --output "$OUT/${two}x2" > "$OUT/${two}x2.log" 2>&1 ||
    { echo "bench_weak_scaling: $two vehicles on 2 hosts failed: $(tail -n 3 "$OUT/${two}x2.log")" >&2; exit 2; }
  /usr/bin/python3 - "$OUT/${n}x1/scaling.csv" "$OUT/${two}x2/scaling.csv" "$TERRAIN" "$n" \
      >> "$OUT/weak.csv" <<'EOF'
import csv, sys
one = list(csv.DictReader(open(sys.argv[1])))[-1]
two = list(csv.DictReader(open(sys.argv[2])))[-1]
r1, r2 = float(one["rtf"]), float(two["rtf"])
print(f"{sys.argv[3]},{sys.argv[4]},{r1:.3f},{r2:.3f},{r2 / r1:.3f},{r1 / r2:.3f},"
      f"{one['load_start']},{two['load_start']}")
EOF
  tail -n 1 "$OUT/weak.csv"
done
/usr/bin/python3 - "$OUT" <<'EOF'
import csv, pathlib, sys
out = pathlib.Path(sys.argv[1])
rows = list(csv.DictReader(open(out / "weak.csv")))
lines = ["| terrain | N on 1 host (1 CPU) | RTF | 2N on 2 hosts (2 CPUs) | RTF | RTF ratio | efficiency | load at start |",
         "|---|---|---|---|---|---|---|---|"]
for r in rows:
    lines.append(f"| {r['terrain']} | {r['n']} | {r['rtf_1host']} | {2 * int(r['n'])} | "
                 f"{r['rtf_2hosts']} | {r['ratio']} | {r['efficiency']} | "
                 f"{r['load_start_1']}, {r['load_start_2']} |")
(out / "weak.md").write_text("\n".join(lines) + "\n")
print("\n".join(lines))
EOF
