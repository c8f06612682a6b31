#!/usr/bin/env bash
# Scaling benchmark: real-time factor against the number of full-dynamics vehicles, each with
# its own path-follower process, plus the recorder and the coordinator (the launcher, a private
# network namespace when allowed), and the same scenario in one process (syndds_sim); with the
# CPU time each kind of process used, sampled from /proc, so the cost per frame can be split.
#
#   tests/benchmarks/bench_scaling.sh [--terrain rigid|soft|soft_routed] [--n "8 16 24 32"]
#       [--modes "distributed per_vehicle single"] [--duration S] [--output DIR]
#       [--dds-profiles FILE] [--recorder-host last] [--cpu-offset C]
#       [--placement interleaved|blocks] [--build-dir DIR] [--heartbeat S] [--recorder-in-group]
#       [--recorder-skip "commands ..."]
#
# Modes: distributed = one process per member (the default layout); per_vehicle = a vehicle and
# its controller in one syndds_group process; groupsK = the vehicles spread over K processes;
# single = every agent in one process (syndds_sim, no DDS); single_full = the same with SCM
# interest management off (every vehicle merges every rut at once); hostsK = one process per member on K
# "hosts" (network namespaces on a bridge, each with its own address and /dev/shm, host k pinned
# to CPU (k-1) mod the CPU count; coordinator and recorder on host 1, vehicle vI and its
# controller on host (I-1) mod K + 1, or with --placement blocks on host ceil(I K / N), so that
# neighbouring lanes share a host as with hostgroupsK; needs root; with --recorder-host last the
# recorder runs on host K instead, so the two services' work is spread over the first and the
# last host; with
# --cpu-offset C host k is pinned to CPU (k-1+C) mod the CPU count, so that two runs of hosts1
# at once can each have a CPU of their own);
# hostgroupsK = the same hosts with the vehicles and controllers of each host in one process
# (the plan's K groups, --processes K: group k on host k). See docs/deployment.md, "Processes".
# --recorder-in-group (hostgroupsK only): the recorder is a member of the last host's group
# process (syndds_group --member recorder) instead of a process of its own (so on host K,
# whatever --recorder-host says). --recorder-skip "F ...": the scenario's recorder.skip (files
# neither written nor subscribed to, docs/outputs.md).
# rigid: N vehicles on rigid ground driving closed loops 10 m apart at 8 m/s. soft: N vehicles
# on soft SCM soil at 0.05 m, straight lanes 5 m apart at up to 5 m/s (the soil covers the
# lanes only); soft_routed: the same with soil routing (docs/scm.md, "Routing"). Writes
# DIR/scaling.csv (one row per terrain, N and mode: processes, frames, wall time, RTF, CPU seconds per process kind and in all, the vehicles.csv digest and the recorder's
# SCM grid hash), DIR/scaling.md (the same as a table, and whether every mode of an N recorded
# byte-identical results; exit status 2 if not) and, with Debian's matplotlib, DIR/scaling.png
# (RTF against N). DIR defaults to a new folder
# under runs/. Programs: build/bin, or DIR/bin with --build-dir (or $SYNDDS_BUILD_DIR/bin), so
# that two builds can be compared (bench_weak_scaling.sh --versus "--build-dir DIR"). Numbers go
# to docs/performance.md with the command and the machine's load. --heartbeat S: the scenario's
# synchronisation period (default 0.01 s, the shipped scenarios'); the controllers act once a
# period, so another value is another scenario, for measuring what a frame costs.
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)
BIN=${SYNDDS_BUILD_DIR:-$ROOT/build}/bin
TERRAIN=rigid; NS="8 16 24 32"; MODES="distributed per_vehicle single"; DURATION=10; OUT=""
PROFILES=(); RECORDER_IN_GROUP=0; RECORDER_SKIP=""; RECORDER_HOST=first; CPU_OFFSET=0; PLACEMENT=interleaved; HEARTBEAT=0.01
while [ $# -gt 0 ]; do
  case "$1" in
    --terrain) TERRAIN=$2; shift ;;
    --n) NS=$2; shift ;;
    --modes) MODES=$2; shift ;;
    --duration) DURATION=$2; shift ;;
    --output) OUT=$2; shift ;;
    --dds-profiles) PROFILES=(--dds-profiles "$2"); shift ;;
    --recorder-host) RECORDER_HOST=$2; shift ;;
    --cpu-offset) CPU_OFFSET=$2; shift ;;
    --placement) PLACEMENT=$2; shift ;;
    --build-dir) export SYNDDS_BUILD_DIR=$2; BIN=$2/bin; shift ;;
    --heartbeat) HEARTBEAT=$2; shift ;;
    --recorder-in-group) RECORDER_IN_GROUP=1 ;;
    --recorder-skip) RECORDER_SKIP=$2; shift ;;
    -h|--help) sed -n '2,42p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) echo "bench_scaling: unknown option $1" >&2; exit 1 ;;
  esac
  shift
done
case "$RECORDER_HOST" in first|last) ;; *) echo "bench_scaling: --recorder-host first or last" >&2; exit 1 ;; esac
[[ "$CPU_OFFSET" =~ ^[0-9]+$ ]] || { echo "bench_scaling: --cpu-offset takes a CPU number" >&2; exit 1; }
[[ "$HEARTBEAT" =~ ^0\.[0-9]+$ ]] || { echo "bench_scaling: --heartbeat takes seconds below 1 (0.01)" >&2; exit 1; }
case "$PLACEMENT" in interleaved|blocks) ;; *) echo "bench_scaling: --placement interleaved or blocks" >&2; exit 1 ;; esac
case "$TERRAIN" in rigid|soft|soft_routed) ;; *) echo "bench_scaling: --terrain rigid, soft or soft_routed" >&2; exit 1 ;; esac
for mode in $MODES; do
  case "$mode" in
    distributed|per_vehicle|single|single_full) ;;
    groups[1-9]|groups[1-9][0-9]) ;;
    hosts[1-9]|hostgroups[1-9])
      [ "$(id -u)" -eq 0 ] || { echo "bench_scaling: mode $mode needs root (ip netns)" >&2; exit 1; } ;;
    *) echo "bench_scaling: unknown mode '$mode' (distributed, per_vehicle, groupsK, hostsK, hostgroupsK, single, single_full)" >&2
       exit 1 ;;
  esac
  if [ "$RECORDER_IN_GROUP" = 1 ] && [[ "$mode" != hostgroups* ]]; then
    echo "bench_scaling: --recorder-in-group applies to hostgroupsK modes only, not '$mode'" >&2
    exit 1
  fi
done
[ -n "$OUT" ] || OUT="runs/scaling-$TERRAIN-$(date +%Y%m%d-%H%M%S)"
mkdir -p "$OUT"
WORK=$(mktemp -d)
# shellcheck source=../netns_hosts.sh
source "$ROOT/tests/netns_hosts.sh"
trap 'hosts_down; rm -rf "$WORK"' EXIT
NCPU=$(nproc)

scenario() {  # $1 = N [$2 = SCM interest radius]; prints the file
  local n=$1 f=$WORK/scaling_$1${2:+_r$2}.yaml
  {
    echo "name: scaling_${TERRAIN}_$n"
    echo "time: {step_s: 0.002, heartbeat_s: $HEARTBEAT, end_time_s: $DURATION}"
    echo "coordinator: {join_timeout_s: 120, frame_timeout_s: 60}"
    [ -z "$RECORDER_SKIP" ] || echo "recorder: {skip: [$(echo $RECORDER_SKIP | sed 's/ /, /g')]}"
    if [ "$TERRAIN" != rigid ]; then
      echo "terrain:"
      echo "  type: scm"
      echo "  preset: soft"
      echo "  spacing_m: 0.05"
      echo "  area: {x_min_m: -10, x_max_m: 70, y_min_m: -5, y_max_m: $((5 * n + 5))}"
      [ -z "${2:-}" ] || echo "  interest_radius_m: $2"
      [ "$TERRAIN" != soft_routed ] || echo "  routing: true"
    fi
    echo "vehicles:"
    for i in $(seq 1 "$n"); do
      echo "  - id: v$i"
      echo "    model: hmmwv"
      echo "    dynamics: full"
      echo "    controller:"
      echo "      type: path_follower"
      if [ "$TERRAIN" != rigid ]; then
        local y=$((5 * i))
        echo "      path: {waypoints: [[0, $y], [60, $y]]}"
        echo "      speed: {profile: ramp, accel_mps2: 1.0, target_mps: 5}"
      else
        local y=$((10 * i))
        echo "      path: {waypoints: [[0, $y], [200, $y], [200, $((y + 200))]], closed: true}"
        echo "      speed: {target_mps: 8}"
      fi
    done
  } > "$f"
  echo "$f"
}

# CPU seconds (user + system) of every syndds_* process, sampled every 0.5 s while $1 runs;
# the last sample of each process counts. Prints "kind seconds" lines.
cpu_by_kind() {
  local pid=$1 tick
  tick=$(getconf CLK_TCK)
  declare -A last=() kind=()
  while kill -0 "$pid" 2>/dev/null; do
    for stat in /proc/[0-9]*/stat; do
      local line
      # The read builtin, not cat: a fork per process twice a second cost 7 % of the CPU at
      # 50 processes (perf), which the benchmark would then measure as the run's.
      read -r line 2>/dev/null < "$stat" || continue
      local comm=${line#*(}; comm=${comm%%)*}
      [[ "$comm" == syndds_* ]] || continue
      local rest=${line##*) }
      read -r -a f <<< "$rest"
      local p=${stat#/proc/}; p=${p%/stat}
      last[$p]=$((f[11] + f[12]))
      kind[$p]=$comm
    done
    sleep 0.5
  done
  for p in "${!last[@]}"; do echo "${kind[$p]} ${last[$p]}"; done |
    awk -v tick="$tick" '{s[$1] += $2} END {for (k in s) printf "%s %.2f\n", k, s[k] / tick}'
}

# Mode hostsK: every planned process in the network namespace of its host (see the header),
# waited for; fails if any process fails. Logs in OUT/logs/.
run_on_hosts() {  # scenario out K N [grouped]
  local file=$1 out=$2 k_hosts=$3 n_vehicles=$4 grouped=${5:-} k member cmd h i failed=0 group=0
  local hosts=() pids=()
  for k in $(seq 1 "$k_hosts"); do
    hosts+=("h$k")
    HOST_CPUS[h$k]=$(( (k - 1 + CPU_OFFSET) % NCPU ))
  done
  hosts_up "sb$$" "$WORK/hosts" on "${hosts[@]}"
  trap hosts_down EXIT
  mkdir -p "$out/logs"
  local plan
  local layout=()
  [ -z "$grouped" ] || layout=(--processes "$k_hosts")
  plan=$("$BIN/syndds_plan" "$file" --format launcher --run-id "scaling-$(basename "$out")-$$" \
         --output "$out" --bin-dir "$BIN" --config-dir "$ROOT/config" "${layout[@]}" \
         "${PROFILES[@]}") || return 1
  if [ -n "$grouped" ] && [ "$RECORDER_IN_GROUP" = 1 ]; then
    # The recorder's line goes; the last group's command gets it as one more member.
    plan=$(printf '%s\n' "$plan" | awk -F'\t' '
      $1 == "recorder" { next }
      { line[++n] = $0; if ($1 ~ /^group\//) last = n }
      END { for (i = 1; i <= n; i++) print line[i] (i == last ? " --member recorder" : "") }')
  fi
  while IFS=$'\t' read -r member cmd; do
    case "$member" in
      group/*) group=$((group + 1)); h=h$group ;;  # the plan's K groups, one per host
      */v*)
        i=${member##*/v}
        if [ "$PLACEMENT" = blocks ]; then
          h=h$(( (i * k_hosts + n_vehicles - 1) / n_vehicles ))
        else
          h=h$(( (i - 1) % k_hosts + 1 ))
        fi ;;
      recorder) [ "$RECORDER_HOST" = first ] && h=h1 || h=h$k_hosts ;;
      *) h=h1 ;;  # the coordinator
    esac
    on_host "$h" "$out/logs/${member//\//_}.log" sh -c "exec $cmd"
    pids+=($!)
  done <<< "$plan"
  for p in "${pids[@]}"; do wait "$p" || failed=1; done
  [ $failed = 0 ] || { tail -n 3 "$out"/logs/*.log; return 1; }
}

echo "terrain,n,mode,processes,frames,wall_s,rtf,cpu_coordinator_s,cpu_vehicles_s,cpu_controllers_s,cpu_groups_s,cpu_recorder_s,cpu_sim_s,cpu_total_s,load_start,vehicles_csv_sha256,grid_hash" > "$OUT/scaling.csv"
for n in $NS; do
  file=$(scenario "$n")
  for mode in $MODES; do
    load=$(cut -d' ' -f1 /proc/loadavg)
    out=$WORK/out_${n}_$mode
    rm -rf "$out"
    if [[ "$mode" == hosts* ]]; then
      processes=$((2 * n + 2))
      run_on_hosts "$file" "$out" "${mode#hosts}" "$n" > "$WORK/launch.log" 2>&1 &
    elif [[ "$mode" == hostgroups* ]]; then
      processes=$((${mode#hostgroups} + 2 - RECORDER_IN_GROUP))
      run_on_hosts "$file" "$out" "${mode#hostgroups}" "$n" grouped > "$WORK/launch.log" 2>&1 &
    elif [[ "$mode" != single* ]]; then
      case "$mode" in
        distributed) layout=per_member; processes=$((2 * n + 2)) ;;
        per_vehicle) layout=per_vehicle; processes=$((n + 2)) ;;
        groups*) layout=${mode#groups}; processes=$((layout + 2)) ;;
      esac
      "$ROOT/tests/netns_exec.sh" "$ROOT/launch_scripts/run_scenario.sh" "$file" --output "$out" \
          --processes "$layout" "${PROFILES[@]}" > "$WORK/launch.log" 2>&1 &
    else
      sim_file=$file
      [ "$mode" = single ] || sim_file=$(scenario "$n" 0)
      "$BIN/syndds_sim" "$sim_file" --output "$out" --quiet --config-dir "$ROOT/config" \
          > "$WORK/launch.log" 2>&1 &
      processes=1
    fi
    runner=$!
    cpu_by_kind "$runner" > "$WORK/cpu.txt"
    if ! wait "$runner"; then
      echo "bench_scaling: $TERRAIN N=$n $mode failed (logs kept in $OUT/failed_${n}_$mode):" >&2
      tail -5 "$WORK/launch.log" >&2
      mkdir -p "$OUT/failed_${n}_$mode"
      cp -r "$WORK/launch.log" "$out/logs" "$out/summary.json" "$OUT/failed_${n}_$mode/" 2>/dev/null || true
      echo "$TERRAIN,$n,$mode,$processes,,,,,,,,,,,$load,," >> "$OUT/scaling.csv"
      continue
    fi
    /usr/bin/python3 - "$out/summary.json" "$WORK/cpu.txt" "$TERRAIN" "$n" "$mode" "$processes" "$load" \
        "$out/vehicles.csv" >> "$OUT/scaling.csv" <<'EOF'
import hashlib, json, sys
summary, cpu_file, terrain, n, mode, processes, load, vehicles = sys.argv[1:]
s = json.load(open(summary))
cpu = dict((k, float(v)) for k, v in (line.split() for line in open(cpu_file) if line.strip()))
kinds = ["syndds_coordina", "syndds_vehicle", "syndds_controll", "syndds_group", "syndds_recorder",
         "syndds_sim"]
cells = [f"{cpu.get(k, 0.0):.2f}" for k in kinds] + [f"{sum(cpu.values()):.2f}"]
digest = hashlib.sha256(open(vehicles, "rb").read()).hexdigest()[:16]
grid = s.get("terrain", {}).get("grid_hash", "")
print(",".join([terrain, n, mode, processes, str(s["frames"]), f"{s['wall_time_s']:.2f}",
                f"{s['real_time_factor']:.3f}"] + cells + [load, digest, grid]))
EOF
    tail -n 1 "$OUT/scaling.csv"
  done
done

/usr/bin/python3 - "$OUT" <<'EOF'
import csv, pathlib, sys
out = pathlib.Path(sys.argv[1])
rows = list(csv.DictReader(open(out / "scaling.csv")))
lines = ["| terrain | vehicles | mode | processes | RTF | wall (s) | CPU s: coordinator / vehicles / "
         "controllers / groups / recorder / sim / all | load at start |",
         "|---|---|---|---|---|---|---|---|"]
for r in rows:
    cpu = " / ".join(r[k] or "-" for k in ["cpu_coordinator_s", "cpu_vehicles_s",
                                            "cpu_controllers_s", "cpu_groups_s", "cpu_recorder_s",
                                            "cpu_sim_s", "cpu_total_s"])
    lines.append(f"| {r['terrain']} | {r['n']} | {r['mode']} | {r['processes']} | "
                 f"{r['rtf'] or 'failed'} | {r['wall_s'] or '-'} | {cpu} | {r['load_start']} |")
same = True
for n in sorted({r["n"] for r in rows}, key=int):
    results = {(r["vehicles_csv_sha256"], r["grid_hash"]) for r in rows if r["n"] == n and r["rtf"]}
    modes = " ".join(r["mode"] for r in rows if r["n"] == n and r["rtf"])
    if len(results) == 1:
        sha, grid = results.pop()
        lines.append(f"\nN = {n}: vehicles.csv (sha256 {sha}...)"
                     f"{' and SCM grid hash ' + grid if grid else ''} byte-identical in: {modes}")
    elif results:
        same = False
        lines.append(f"\nN = {n}: RESULTS DIFFER between modes: " + "; ".join(
            f"{r['mode']} {r['vehicles_csv_sha256']} {r['grid_hash']}" for r in rows if r["n"] == n))
(out / "scaling.md").write_text("\n".join(lines) + "\n")
print("\n".join(lines))
try:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
except ImportError:
    sys.exit(0 if same else 2)
fig, ax = plt.subplots(figsize=(6, 4))
for mode in sorted({r["mode"] for r in rows}):
    pts = [(int(r["n"]), float(r["rtf"])) for r in rows if r["mode"] == mode and r["rtf"]]
    if pts:
        ax.plot(*zip(*sorted(pts)), "o-", label=mode)
ax.axhline(1.0, color="k", lw=0.8, ls="--")
ax.set_xlabel("vehicles (full dynamics, each with its controller)")
ax.set_ylabel("real-time factor (wall / simulated)")
ax.set_title(f"{rows[0]['terrain'] if rows else ''}: RTF against vehicles")
ax.legend()
fig.tight_layout()
fig.savefig(out / "scaling.png", dpi=100)
sys.exit(0 if same else 2)
EOF
echo "bench_scaling: $OUT/scaling.csv, scaling.md, scaling.png"
