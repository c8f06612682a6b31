#!/usr/bin/env bash
# Weak scaling across hosts: N vehicles on one host against 2N on two, each host a network
# namespace pinned to a CPU of its own (bench_scaling.sh's hostsK mode: host k on CPU k-1; the
# coordinator and the recorder on host 1), so the second host brings its own core, as a second
# machine would. Efficiency = RTF(N on 1) / RTF(2N on 2): 1 when twice the work on twice the
# hardware runs as fast.
#
#   tests/benchmarks/bench_weak_scaling.sh [--terrain rigid|soft|soft_routed] [--n "4 8"] [--duration S]
#       [--layout per_member|per_host] [--recorder-host first|last] [--repeat R] [--ceiling]
#       [--placement interleaved|blocks] [--versus "BENCH_SCALING_OPTIONS"] [--output DIR]
#
# --layout per_host: each host's vehicles and controllers in one process (bench_scaling's
# hostgroupsK) instead of one process per member. --placement blocks (per_member): vehicles
# 1..N on host 1 and N+1..2N on host 2, as per_host groups them, instead of alternating (with
# lanes side by side, alternating puts every vehicle's neighbours on the other host).
# --recorder-host last: with 2 hosts the recorder runs on the second (the coordinator stays on
# the first). --repeat R: R pairs per N, the two runs of a pair one right after the other (a busy
# machine's speed drifts over minutes), and per N the median and range of the efficiency.
# --ceiling: each pair also runs two independent
# runs of N vehicles at once, one on each host and CPU, with nothing between them; their
# efficiency, RTF(N alone) / RTF(the slower of the two), bounds what any layout of 2N vehicles on
# the two CPUs can reach on this machine (the CPUs share caches, memory and the hypervisor).
# --versus "OPTS": an A/B comparison on this noisy machine: each pair runs the 1-host and 2-host
# runs as given (setting A), then again with OPTS added to both bench_scaling.sh commands
# (setting B, e.g. "--dds-profiles FILE" or "--build-dir DIR" for another build), so the
# two settings are compared minutes, not an invocation, apart; weak.md adds the median of B's
# RTF over A's for each host count.
#
# Needs root (ip netns) and at least 2 CPUs. Writes DIR/weak.csv (terrain, N, pair, setting,
# RTF on 1 host, RTF of 2N on 2 hosts, ratio, efficiency, load averages at the start; with
# --ceiling the two independent runs' RTFs and the ceiling) and DIR/weak.md; the bench_scaling outputs of each run
# (CPU seconds per kind of process) are in DIR/<N>x1, DIR/<2N>x2 and DIR/<N>x1_apart_cpuC
# (setting B: with _B at the end).
# Numbers go to docs/performance.md with the command and the machine's load.
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)
TERRAIN=rigid; NS="4 8"; DURATION=10; OUT=""; LAYOUT=per_member; RECORDER_HOST=first; REPEAT=1
CEILING=0; PLACEMENT=interleaved; VERSUS=""
while [ $# -gt 0 ]; do
  case "$1" in
    --terrain) TERRAIN=$2; shift ;;
    --n) NS=$2; shift ;;
    --duration) DURATION=$2; shift ;;
    --output) OUT=$2; shift ;;
    --layout) LAYOUT=$2; shift ;;
    --recorder-host) RECORDER_HOST=$2; shift ;;
    --repeat) REPEAT=$2; shift ;;
    --ceiling) CEILING=1 ;;
    --placement) PLACEMENT=$2; shift ;;
    --versus) VERSUS=$2; shift ;;
    -h|--help) sed -n '2,34p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) echo "bench_weak_scaling: unknown option $1" >&2; exit 1 ;;
  esac
  shift
done
[ "$(nproc)" -ge 2 ] || { echo "bench_weak_scaling: needs 2 CPUs" >&2; exit 1; }
[[ "$REPEAT" =~ ^[1-9][0-9]*$ ]] || { echo "bench_weak_scaling: --repeat takes a count >= 1" >&2; exit 1; }
case "$LAYOUT" in
  per_member) MODE=hosts ;;
  per_host) MODE=hostgroups ;;
  *) echo "bench_weak_scaling: --layout per_member or per_host" >&2; exit 1 ;;
esac
[ -n "$OUT" ] || OUT="runs/weak-$TERRAIN-$(date +%Y%m%d-%H%M%S)"
mkdir -p "$OUT"
echo "terrain,n,pair,setting,rtf_1host,rtf_2hosts,ratio,efficiency,load_start_1,load_start_2,rtf_apart_cpu0,rtf_apart_cpu1,ceiling" > "$OUT/weak.csv"
for n in $NS; do
  two=$((2 * n))
  for pair in $(seq 1 "$REPEAT"); do
    for setting in A B; do
      extra=()
      if [ "$setting" = B ]; then
        [ -n "$VERSUS" ] || continue
        read -r -a extra <<< "$VERSUS"
      fi
      tag=""
      [ "$REPEAT" = 1 ] || tag="_$pair"
      [ "$setting" = A ] || tag="${tag}_B"
      one_dir=$OUT/${n}x1$tag two_dir=$OUT/${two}x2$tag
      "$ROOT/tests/benchmarks/bench_scaling.sh" --terrain "$TERRAIN" --n "$n" --modes ${MODE}1 \
          --duration "$DURATION" --output "$one_dir" "${extra[@]}" > "$one_dir.log" 2>&1 ||
        { echo "bench_weak_scaling: $n vehicles on 1 host failed: $(tail -n 3 "$one_dir.log")" >&2; exit 2; }
      "$ROOT/tests/benchmarks/bench_scaling.sh" --terrain "$TERRAIN" --n "$two" --modes ${MODE}2 \
          --recorder-host "$RECORDER_HOST" --placement "$PLACEMENT" --duration "$DURATION" \
          --output "$two_dir" "${extra[@]}" > "$two_dir.log" 2>&1 ||
        { echo "bench_weak_scaling: $two vehicles on 2 hosts failed: $(tail -n 3 "$two_dir.log")" >&2; exit 2; }
      apart=()
      if [ "$CEILING" = 1 ]; then
        # Two runs of N at once, each on a host (and CPU) of its own, sharing nothing but the machine.
        for cpu in 0 1; do
          "$ROOT/tests/benchmarks/bench_scaling.sh" --terrain "$TERRAIN" --n "$n" --modes ${MODE}1 \
              --cpu-offset "$cpu" --duration "$DURATION" --output "$OUT/${n}x1_apart_cpu$cpu$tag" \
              "${extra[@]}" > "$OUT/${n}x1_apart_cpu$cpu$tag.log" 2>&1 &
          apart+=($!)
        done
        for p in "${apart[@]}"; do
          wait "$p" || { echo "bench_weak_scaling: the independent runs of $n vehicles failed" >&2; exit 2; }
        done
        apart=("$OUT/${n}x1_apart_cpu0$tag/scaling.csv" "$OUT/${n}x1_apart_cpu1$tag/scaling.csv")
      fi
      /usr/bin/python3 - "$one_dir/scaling.csv" "$two_dir/scaling.csv" "$TERRAIN" "$n" "$pair" \
          "$setting" "${apart[@]}" >> "$OUT/weak.csv" <<'EOF'
import csv, sys
one = list(csv.DictReader(open(sys.argv[1])))[-1]
two = list(csv.DictReader(open(sys.argv[2])))[-1]
r1, r2 = float(one["rtf"]), float(two["rtf"])
apart = ",,"
if len(sys.argv) > 7:
    a, b = (float(list(csv.DictReader(open(f)))[-1]["rtf"]) for f in sys.argv[7:9])
    apart = f"{a:.3f},{b:.3f},{r1 / max(a, b):.3f}"
print(f"{sys.argv[3]},{sys.argv[4]},{sys.argv[5]},{sys.argv[6]},{r1:.3f},{r2:.3f},{r2 / r1:.3f},"
      f"{r1 / r2:.3f},{one['load_start']},{two['load_start']},{apart}")
EOF
      tail -n 1 "$OUT/weak.csv"
    done
  done
done
/usr/bin/python3 - "$OUT" "$VERSUS" <<'EOF'
import csv, pathlib, sys
out = pathlib.Path(sys.argv[1])
rows = list(csv.DictReader(open(out / "weak.csv")))
ceiling = any(r["ceiling"] for r in rows)
extra = (" two runs of N apart (CPU 0, CPU 1): RTF | ceiling |", "---|---|") if ceiling else ("", "")
versus = any(r["setting"] == "B" for r in rows)
lines = ([f"Setting B: bench_scaling.sh options {sys.argv[2]!r} added to A's.", ""] if versus else []) + \
        ["| terrain | N on 1 host (1 CPU) | pair | setting | RTF | 2N on 2 hosts (2 CPUs) | RTF | RTF ratio | efficiency | load at start |" + extra[0],
         "|---|---|---|---|---|---|---|---|---|---|" + extra[1]]
for r in rows:
    lines.append(f"| {r['terrain']} | {r['n']} | {r['pair']} | {r['setting']} | {r['rtf_1host']} | {2 * int(r['n'])} | "
                 f"{r['rtf_2hosts']} | {r['ratio']} | {r['efficiency']} | "
                 f"{r['load_start_1']}, {r['load_start_2']} |" +
                 (f" {r['rtf_apart_cpu0']}, {r['rtf_apart_cpu1']} | {r['ceiling']} |" if ceiling else ""))

def spread(values):
    v = sorted(values)
    mid = len(v) // 2
    median = v[mid] if len(v) % 2 else (v[mid - 1] + v[mid]) / 2
    return f"median {median:.3f}, range {v[0]:.3f}-{v[-1]:.3f} over {len(v)} pair(s)"

for n in dict.fromkeys(r["n"] for r in rows):
    for setting in ("A", "B") if versus else ("A",):
        pick = [r for r in rows if r["n"] == n and r["setting"] == setting]
        name = f"N = {n}, setting {setting}" if versus else f"N = {n}"
        lines.append(f"\n{name}: efficiency {spread(float(r['efficiency']) for r in pick)}")
        if ceiling:
            lines.append(f"{name}: ceiling (two independent runs of N) "
                         f"{spread(float(r['ceiling']) for r in pick)}")
    if versus:
        a = {r["pair"]: r for r in rows if r["n"] == n and r["setting"] == "A"}
        b = {r["pair"]: r for r in rows if r["n"] == n and r["setting"] == "B"}
        for col, what in (("rtf_1host", f"{n} on 1 host"), ("rtf_2hosts", f"{2 * int(n)} on 2 hosts")):
            ratios = [float(b[p][col]) / float(a[p][col]) for p in a if p in b]
            lines.append(f"N = {n}: RTF of B / A, {what}: {spread(ratios)} (below 1: B faster)")
(out / "weak.md").write_text("\n".join(lines) + "\n")
print("\n".join(lines))
EOF
