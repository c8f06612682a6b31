#!/usr/bin/env bash
# The paper's leader on a straight: one HMMWV (full dynamics) drives 260 m east with the
# 0.47 m/s2 speed ramp and no cap, on rigid ground, SCM hard and SCM soft, one single-process
# run each. Prints, per terrain, when (time, distance, speed) the automatic transmission first
# engaged each gear, and the time, speed and gear at 150 m (a typical course's length) and at
# 15 s. docs/ensemble.md uses it to explain the gears of the study's leaders.
#   tools/ramp_gears.sh [OUTPUT_DIR]   (default: a temporary folder, removed at the end)
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
BIN=${SYNDDS_BUILD_DIR:-$ROOT/build}/bin
[ -x "$BIN/syndds_sim" ] || { echo "ramp_gears: $BIN/syndds_sim is missing: build first" >&2; exit 1; }
if [ $# -ge 1 ]; then OUT=$1; mkdir -p "$OUT"; else OUT=$(mktemp -d); trap 'rm -rf "$OUT"' EXIT; fi
for t in rigid hard soft; do
  if [ $t = rigid ]; then
    terrain="terrain: {type: rigid, friction: 0.8}"
  else
    terrain="terrain: {type: scm, preset: $t, spacing_m: 0.05, area: {x_min_m: -5, x_max_m: 265, y_min_m: -4, y_max_m: 4}}"
  fi
  cat > "$OUT/straight_$t.yaml" <<YAML
name: straight_ramp_$t
seed: 1
time: {step_s: 0.002, heartbeat_s: 0.01, end_time_s: 40}
$terrain
vehicles:
  - id: l1
    model: hmmwv
    dynamics: full
    start: {x: 0, y: 0, yaw_deg: 0}
    controller:
      type: path_follower
      path: {waypoints: [[0, 0], [260, 0]]}
      speed: {profile: ramp, target_mps: 20}
YAML
  "$BIN/syndds_sim" "$OUT/straight_$t.yaml" --output "$OUT/$t" --quiet --config-dir "$ROOT/config" \
    > "$OUT/$t.log" 2>&1 || { echo "ramp_gears: the $t run failed: $OUT/$t.log" >&2; exit 1; }
done
python3 - "$OUT" <<'PY'
import csv, pathlib, sys
out = pathlib.Path(sys.argv[1])
print("terrain  first frame in each gear (time s / x m / speed m/s)       at x = 150 m (t, v, gear)   v at 15 s")
for t in ("rigid", "hard", "soft"):
    first, at150, v15 = {}, None, None
    for r in csv.DictReader(open(out / t / "vehicles.csv")):
        time, x, v, g = float(r["time_s"]), float(r["x"]), float(r["speed_mps"]), int(r["gear"])
        if g > 0 and g not in first:
            first[g] = f"{g}: {time:.1f} / {x:.0f} / {v:.1f}"
        if at150 is None and x >= 150:
            at150 = f"{time:.1f} s, {v:.2f} m/s, gear {g}"
        if abs(time - 15.0) < 1e-6:
            v15 = f"{v:.2f}"
    print(f"{t:8} {', '.join(first[g] for g in sorted(first)):58} {at150 or 'not reached in 40 s':27} {v15}")
PY
