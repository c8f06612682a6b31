#!/usr/bin/env bash
# Soil traffic against the number of vehicles: N full vehicles on soft SCM soil (0.05 m) in
# straight 45 m lanes LANE m apart at up to 5 m/s, run in one process (syndds_sim; the deformation
# lists are the ones a distributed run sends, byte for byte). From the recorder's summary.json
# (the packed vertex lists as they travel, docs/outputs.md): bytes of deformation lists per
# frame in all, and what one vehicle receives per frame while every vehicle subscribes to every
# other's lists: the others' share, all * (N - 1) / N (the lanes are alike, so each vehicle
# writes about 1/N of the traffic). With --routing (terrain.scm.routing, docs/scm.md) a vehicle
# receives only the records addressed to it: the recorder's per-vehicle count of them
# (terrain.routed_bytes_per_vehicle_per_frame_mean), which the same run sends distributed.
#
#   tests/benchmarks/bench_soil_traffic.sh [--n "8 16 32"] [--lane-m 10] [--duration S]
#       [--routing] [--output DIR]
#
# Writes DIR/soil_traffic.csv and DIR/soil_traffic.md. Numbers go to docs/performance.md.
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)
BIN=${SYNDDS_BUILD_DIR:-$ROOT/build}/bin
NS="8 16 32"; LANE=10; DURATION=10; OUT=""; ROUTING=false
while [ $# -gt 0 ]; do
  case "$1" in
    --n) NS=$2; shift ;;
    --lane-m) LANE=$2; shift ;;
    --duration) DURATION=$2; shift ;;
    --output) OUT=$2; shift ;;
    --routing) ROUTING=true ;;
    -h|--help) sed -n '2,15p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) echo "bench_soil_traffic: unknown option $1" >&2; exit 1 ;;
  esac
  shift
done
[ -n "$OUT" ] || OUT="runs/soil-traffic-$(date +%Y%m%d-%H%M%S)"
mkdir -p "$OUT"
echo "n,lane_m,routing,frames,wall_s,deformation_bytes_per_frame_all,received_per_vehicle_per_frame,deformation_vertices_total" > "$OUT/soil_traffic.csv"
for n in $NS; do
  f=$OUT/soil_$n.yaml
  {
    echo "name: soil_traffic_$n"
    echo "time: {step_s: 0.002, heartbeat_s: 0.01, end_time_s: $DURATION}"
    echo "terrain:"
    echo "  type: scm"
    echo "  preset: soft"
    echo "  spacing_m: 0.05"
    echo "  routing: $ROUTING"
    echo "  area: {x_min_m: -10, x_max_m: 50, y_min_m: -5, y_max_m: $((LANE * n + 5))}"
    echo "vehicles:"
    for i in $(seq 1 "$n"); do
      echo "  - id: v$i"
      echo "    model: hmmwv"
      echo "    dynamics: full"
      echo "    controller:"
      echo "      type: path_follower"
      echo "      path: {waypoints: [[0, $((LANE * i))], [45, $((LANE * i))]]}"
      echo "      speed: {profile: ramp, accel_mps2: 1.0, target_mps: 5}"
    done
  } > "$f"
  "$BIN/syndds_sim" "$f" --quiet --output "$OUT/run_$n" --config-dir "$ROOT/config" > "$OUT/run_$n.log" 2>&1 ||
    { echo "bench_soil_traffic: N=$n failed: $(tail -n 2 "$OUT/run_$n.log")" >&2; exit 2; }
  /usr/bin/python3 - "$OUT/run_$n/summary.json" "$n" "$LANE" >> "$OUT/soil_traffic.csv" <<'EOF'
import json, sys
s = json.load(open(sys.argv[1]))
n = int(sys.argv[2])
t = s["terrain"]
per_frame = t["deformation_bytes_per_frame_mean"]
received = (t["routed_bytes_per_vehicle_per_frame_mean"] if t["routing"]
            else per_frame * (n - 1) / n)
print(f"{n},{sys.argv[3]},{str(t['routing']).lower()},{s['frames']},{s['wall_time_s']:.2f},"
      f"{per_frame:.0f},{received:.0f},{t['deformation_vertices_total']}")
EOF
  tail -n 1 "$OUT/soil_traffic.csv"
done
/usr/bin/python3 - "$OUT" <<'EOF'
import csv, pathlib, sys
out = pathlib.Path(sys.argv[1])
rows = list(csv.DictReader(open(out / "soil_traffic.csv")))
base = float(rows[0]["received_per_vehicle_per_frame"]) if rows else 1.0
lines = ["| vehicles | lanes (m) | routing | bytes per frame, all lists | received per vehicle per frame | vs first |",
         "|---|---|---|---|---|---|"]
for r in rows:
    rec = float(r["received_per_vehicle_per_frame"])
    lines.append(f"| {r['n']} | {r['lane_m']} | {r['routing']} | {r['deformation_bytes_per_frame_all']} | "
                 f"{r['received_per_vehicle_per_frame']} | {rec / base:.2f}x |")
(out / "soil_traffic.md").write_text("\n".join(lines) + "\n")
print("\n".join(lines))
EOF
