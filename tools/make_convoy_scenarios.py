#!/usr/bin/env python3
"""Writes the nine convoy scenarios of the paper's experiment into config/scenarios/convoy/:
{1L3F,2L2F,3L1F}_{rigid,scm_hard,scm_soft}.yaml, and beside them the emergency stop of a
leader with a follower behind it, leader_emergency_stop_{rigid,scm_hard,scm_soft}.yaml; the
same nine with the shipped learned
policy as followers, and 1L+1F scenarios of the learned follower and, beside them, the
classical one, into config/scenarios/learned/.

One shared S-shaped path with obstacles standing 3 m (edge to centre line) beside it; four
vehicles lined up 12 m apart on its straight lead-in (and leaders stopping 12 m apart on its
straight finish), leaders first (human-driven: path
followers with the paper's 0.47 m/s2 speed ramp), then followers (each follows the vehicle
ahead of it from its own GPS, compass, tachometer and that vehicle's V2V messages). The last
vehicle carries a chase camera that writes a video.

The files are committed; run this again after changing it (python3 tools/make_convoy_scenarios.py)
and commit the result. Obstacle positions are computed on the same centripetal Catmull-Rom
spline the controllers use (common/control/path.cpp).
"""
import json
import math
import pathlib

ROOT = pathlib.Path(__file__).resolve().parent.parent
OUT = ROOT / "config" / "scenarios" / "convoy"

PATH = [(0, 0), (20, 0), (40, 0), (65, 12), (90, 24), (115, 24), (140, 12), (165, 0),
        (185, 0), (200, 0)]
SPACING_M = 12.0            # start spacing between vehicles along the lead-in
TARGET_MPS = 8.0            # cap of the leaders' speed ramp
CLEARANCE_M = 3.0           # obstacle edge to path centre line
OBSTACLES = [  # (arc position m, side +1 left / -1 right, radius m)
    (30, 1, 0.6), (50, -1, 0.8), (70, 1, 0.6), (95, -1, 0.8),
    (120, 1, 0.6), (140, -1, 0.8), (160, 1, 0.6), (180, -1, 0.8)]
TERRAINS = {
    "rigid": {"end_time_s": 60, "block": "terrain: {type: rigid, friction: 0.8}"},
    "scm_hard": {"end_time_s": 70, "block": (
        "terrain:\n  type: scm\n  preset: hard\n  spacing_m: 0.05\n"
        "  area: {x_min_m: -45, x_max_m: 210, y_min_m: -10, y_max_m: 35}")},
    "scm_soft": {"end_time_s": 90, "block": (
        "terrain:\n  type: scm\n  preset: soft\n  spacing_m: 0.05\n"
        "  area: {x_min_m: -45, x_max_m: 210, y_min_m: -10, y_max_m: 35}")},
}
MIXES = {"1L3F": 1, "2L2F": 2, "3L1F": 3}
STANDSTILL_BUMPER_M = 5.0   # followers' standstill gap, bumper to bumper (HMMWV: 4.7 m long)
SEEDS = {"rigid": 101, "scm_hard": 102, "scm_soft": 103}


def catmull_rom(p0, p1, p2, p3, u):
    def knot(t, a, b):
        return t + max(math.sqrt(math.dist(a, b)), 1e-6)
    t0 = 0.0
    t1 = knot(t0, p0, p1)
    t2 = knot(t1, p1, p2)
    t3 = knot(t2, p2, p3)
    t = t1 + u * (t2 - t1)

    def lerp(a, b, ta, tb):
        return tuple((tb - t) / (tb - ta) * x + (t - ta) / (tb - ta) * y for x, y in zip(a, b))
    a1 = lerp(p0, p1, t0, t1)
    a2 = lerp(p1, p2, t1, t2)
    a3 = lerp(p2, p3, t2, t3)
    b1 = lerp(a1, a2, t0, t2)
    b2 = lerp(a2, a3, t1, t3)
    return lerp(b1, b2, t1, t2)


def sample_path(w, spacing=0.2):
    n = len(w)

    def get(i):
        if i < 0:
            return tuple(2 * a - b for a, b in zip(w[0], w[1]))
        if i >= n:
            return tuple(2 * a - b for a, b in zip(w[n - 1], w[n - 2]))
        return w[i]
    pts = [w[0]]
    for k in range(n - 1):
        p0, p1, p2, p3 = get(k - 1), get(k), get(k + 1), get(k + 2)
        steps = max(1, math.ceil(math.dist(p1, p2) / spacing))
        for j in range(1, steps + 1):
            pts.append(catmull_rom(p0, p1, p2, p3, j / steps))
    return pts


def point_at(pts, s):
    acc = 0.0
    for a, b in zip(pts, pts[1:]):
        d = math.dist(a, b)
        if acc + d >= s:
            u = (s - acc) / d
            pos = (a[0] + u * (b[0] - a[0]), a[1] + u * (b[1] - a[1]))
            tangent = ((b[0] - a[0]) / d, (b[1] - a[1]) / d)
            return pos, tangent
        acc += d
    raise ValueError(f"arc position {s} beyond the path")


def fmt_pts(pts):
    return "[" + ", ".join(f"[{x:g}, {y:g}]" for x, y in pts) + "]"


def follower_rig(policy):
    """The rig a follower driven by `policy` needs: the "sensors" of the policy's metadata
    (config/<policy stem>.json, written by syndds_train); convoy for the classical follower."""
    if not policy:
        return "convoy"
    meta = ROOT / "config" / pathlib.Path(policy).with_suffix(".json")
    return json.loads(meta.read_text()).get("sensors", "convoy") if meta.exists() else "convoy"


def scenario(mix, terrain, policy=None):
    """One of the nine convoys; with `policy`, its followers are that learned policy."""
    leaders = MIXES[mix]
    pts = sample_path(PATH)
    t = TERRAINS[terrain]
    lines = [
        f"# Convoy {mix} on {terrain.replace('_', ' ')} ground (the paper's mixed-convoy experiment):",
        f"# {leaders} human-driven leader(s) on a planned S-shaped path (speed ramp 0.47 m/s2 up to",
        f"# {TARGET_MPS:g} m/s), {4 - leaders} autonomous follower(s) that know only their own GPS,",
        "# compass and wheel speeds and the V2V messages of the vehicle ahead. Obstacles stand 3 m",
        "# beside the path. The last vehicle's chase camera writes a video (sensors/<id>/).",
    ] + ([f"# The followers are the learned policy {policy}",
          "# (docs/learning.md), each steering along the convoy head's trail (it hears the head's",
          "# V2V too) and keeping its gap to the vehicle ahead."] if policy else []) + [
        "# Generated by tools/make_convoy_scenarios.py: edit that, not this file.",
        f"name: {'learned' if policy else 'convoy'}_{mix}_{terrain}",
        f"seed: {SEEDS[terrain]}",
        f"time: {{step_s: 0.002, heartbeat_s: 0.01, end_time_s: {t['end_time_s']}}}",
        "coordinator: {join_timeout_s: 30, frame_timeout_s: 20}",
        t["block"],
        "obstacles:",
    ]
    for i, (s, side, r) in enumerate(OBSTACLES):
        (x, y), (tx, ty) = point_at(pts, s)
        off = side * (CLEARANCE_M + r)
        ox, oy = x - ty * off, y + tx * off
        label = "tree" if r < 0.7 else "rock"
        lines.append(f"  - {{id: {label}{i + 1}, label: {label}, shape: cylinder, "
                     f"position: [{ox:.3f}, {oy:.3f}], radius_m: {r:g}, height_m: 3}}")
    lines.append("vehicles:")
    for k in range(4):
        vid = f"l{k + 1}" if k < leaders else f"f{k - leaders + 1}"
        x0 = -SPACING_M * k + 0.0  # no "-0"
        last = k == 3
        lines.append(f"  - id: {vid}")
        lines.append("    model: hmmwv")
        lines.append("    dynamics: full")
        lines.append(f"    start: {{x: {x0:g}, y: 0, yaw_deg: 0}}")
        rig = follower_rig(policy) if k >= leaders else "convoy"
        if last:
            lines.append(f"    sensors: {{rig: {rig}_chase, video: true}}")
        else:
            lines.append(f"    sensors: {rig}")
        lines.append("    v2v: {rate_hz: 10, latency_s: 0.0, drop_probability: 0.0}")
        lines.append("    controller:")
        if k < leaders:
            # Each leader starts and stops SPACING_M behind the one ahead: the same path, cut
            # short at the end, so that no two vehicles are sent to the same place.
            end_x = PATH[-1][0] - SPACING_M * k
            path = ([(x0, 0)] if x0 != 0 else []) + [p for p in PATH if p[0] < end_x]
            path.append((end_x, 0))
            lines.append("      type: path_follower")
            lines.append(f"      path: {{waypoints: {fmt_pts(path)}}}")
            lines.append(f"      speed: {{profile: ramp, target_mps: {TARGET_MPS:g}}}")
        else:
            ahead = f"l{k}" if k - 1 < leaders else f"f{k - leaders}"
            if policy:
                # A learned follower steers along the convoy head's trail (docs/convoy.md, step 8).
                lines += ["      type: policy", f"      follow: {ahead}", "      trail: head",
                          f"      model: {policy}"]
            else:
                lines.append("      type: follower")
                lines.append(f"      follow: {ahead}")
                lines.append("      gap: {time_s: 1.0, "
                             f"standstill_bumper_m: {STANDSTILL_BUMPER_M:g}}}")
    return "\n".join(lines) + "\n"


# The leader's emergency stop: a straight 250 m path, the leader ramping up at 1 m/s2 to
# 8 m/s and braking fully (controller.stop_at_s) at a time tools/leader_emergency_stop.py
# draws; one classical follower starting 12 m (centre to centre) behind it.
STOP_LENGTH_M = 250.0
STOP_TARGET_MPS = 8.0
STOP_ACCEL_MPS2 = 1.0
STOP_DEFAULT_S = 12.0        # the shipped files' stop time: at 8 m/s, the follower settled
STOP_AFTER_S = 10.0          # simulated after the stop: both stopped, the follower settled
STOP_SEEDS = {"rigid": 201, "scm_hard": 202, "scm_soft": 203}
STOP_TERRAINS = {
    "rigid": "terrain: {type: rigid, friction: 0.8}",
    "scm_hard": ("terrain:\n  type: scm\n  preset: hard\n  spacing_m: 0.05\n"
                 "  area: {x_min_m: -20, x_max_m: 255, y_min_m: -5, y_max_m: 5}"),
    "scm_soft": ("terrain:\n  type: scm\n  preset: soft\n  spacing_m: 0.05\n"
                 "  area: {x_min_m: -20, x_max_m: 255, y_min_m: -5, y_max_m: 5}"),
}


def emergency_stop(terrain, stop_at_s=STOP_DEFAULT_S):
    """The leader brakes fully at stop_at_s; the follower must stop behind it."""
    return "\n".join([
        f"# Leader emergency stop on {terrain.replace('_', ' ')} ground: the leader ramps up at "
        f"{STOP_ACCEL_MPS2:g} m/s2 to {STOP_TARGET_MPS:g} m/s",
        f"# on a straight path and brakes fully at t = {stop_at_s:g} s (controller.stop_at_s); a "
        "classical follower",
        "# behind it must stop without touching it (docs/convoy.md, \"Leader emergency stop\").",
        "# Generated by tools/make_convoy_scenarios.py: edit that, not this file;",
        "# tools/leader_emergency_stop.py runs it with random stop times.",
        f"name: leader_emergency_stop_{terrain}",
        f"seed: {STOP_SEEDS[terrain]}",
        f"time: {{step_s: 0.002, heartbeat_s: 0.01, end_time_s: {stop_at_s + STOP_AFTER_S:g}}}",
        "coordinator: {join_timeout_s: 30, frame_timeout_s: 20}",
        STOP_TERRAINS[terrain],
        "vehicles:",
        "  - id: l1",
        "    model: hmmwv",
        "    dynamics: full",
        "    start: {x: 0, y: 0, yaw_deg: 0}",
        "    sensors: convoy",
        "    v2v: {rate_hz: 10, latency_s: 0.0, drop_probability: 0.0}",
        "    controller:",
        "      type: path_follower",
        f"      path: {{waypoints: [[0, 0], [{STOP_LENGTH_M:g}, 0]]}}",
        f"      speed: {{profile: ramp, target_mps: {STOP_TARGET_MPS:g}, "
        f"accel_mps2: {STOP_ACCEL_MPS2:g}}}",
        f"      stop_at_s: {stop_at_s:g}",
        "  - id: f1",
        "    model: hmmwv",
        "    dynamics: full",
        f"    start: {{x: {-SPACING_M:g}, y: 0, yaw_deg: 0}}",
        "    sensors: convoy",
        "    controller:",
        "      type: follower",
        "      follow: l1",
        f"      gap: {{time_s: 1.0, standstill_bumper_m: {STANDSTILL_BUMPER_M:g}}}",
    ]) + "\n"


LEARNED_OUT = ROOT / "config" / "scenarios" / "learned"
LEARNED_TARGET_MPS = 5.0    # the convoy-follow environment's leader (docs/learning.md)
LEARNED_GAP_M = 15.0        # its optimal gap and start gap
POLICY = "policies/convoy_follow_camera.pt"


def learned(terrain, follower):
    """1L+1F on the same path and obstacles: the shipped learned policy or the classical
    follower behind a leader at the training's target speed, for side-by-side metrics."""
    text = scenario("3L1F", terrain)  # for its header lines: terrain and obstacles
    head = text.split("vehicles:\n")[0].split("\n")
    kind = "learned policy" if follower == "policy" else "classical follower"
    lines = [
        f"# 1L+1F on {terrain.replace('_', ' ').replace('scm', 'SCM')} ground with the {kind}: the convoy path and",
        f"# obstacles of config/scenarios/convoy/, the leader's ramp up to {LEARNED_TARGET_MPS:g} m/s (the",
        "# convoy-follow environment's), the follower starting 15 m behind (docs/learning.md).",
        "# Generated by tools/make_convoy_scenarios.py: edit that, not this file.",
        f"name: learned_1L1F_{terrain}_{follower}",
    ] + [line for line in head if not line.startswith("#") and not line.startswith("name:")]
    lines += [
        "vehicles:",
        "  - id: l1", "    model: hmmwv", "    dynamics: full",
        "    start: {x: 0, y: 0, yaw_deg: 0}", "    sensors: convoy",
        "    v2v: {rate_hz: 10, latency_s: 0.0, drop_probability: 0.0}",
        "    controller:", "      type: path_follower",
        f"      path: {{waypoints: {fmt_pts(PATH)}}}",
        f"      speed: {{profile: ramp, target_mps: {LEARNED_TARGET_MPS:g}}}",
        "  - id: f1", "    model: hmmwv", "    dynamics: full",
        f"    start: {{x: {-LEARNED_GAP_M:g}, y: 0, yaw_deg: 0}}",
        f"    sensors: {follower_rig(POLICY) if follower == 'policy' else 'convoy'}",
        "    controller:",
    ]
    if follower == "policy":
        lines += ["      type: policy", "      follow: l1", f"      model: {POLICY}"]
    else:
        lines += ["      type: follower", "      follow: l1",
                  f"      gap: {{time_s: 1.0, standstill_bumper_m: {STANDSTILL_BUMPER_M:g}}}"]
    return "\n".join(lines) + "\n"


def main():
    OUT.mkdir(parents=True, exist_ok=True)
    for mix in MIXES:
        for terrain in TERRAINS:
            (OUT / f"{mix}_{terrain}.yaml").write_text(scenario(mix, terrain))
    for terrain in STOP_TERRAINS:
        (OUT / f"leader_emergency_stop_{terrain}.yaml").write_text(emergency_stop(terrain))
    print(f"wrote {len(MIXES) * len(TERRAINS) + len(STOP_TERRAINS)} scenarios to "
          f"{OUT.relative_to(ROOT)}")
    LEARNED_OUT.mkdir(parents=True, exist_ok=True)
    for mix in MIXES:
        for terrain in TERRAINS:
            (LEARNED_OUT / f"{mix}_{terrain}.yaml").write_text(scenario(mix, terrain, POLICY))
    for terrain in TERRAINS:
        for follower in ("policy", "classical"):
            (LEARNED_OUT / f"1L1F_{terrain}_{follower}.yaml").write_text(learned(terrain, follower))
    print(f"wrote {len(MIXES) * len(TERRAINS) + 2 * len(TERRAINS)} scenarios to "
          f"{LEARNED_OUT.relative_to(ROOT)}")


if __name__ == "__main__":
    main()
