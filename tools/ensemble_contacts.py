#!/usr/bin/python3
"""Where and how the vehicles of an ensemble touch obstacles, and what the speed deviation
follows: the measurements docs/ensemble.md gives for the paper's study.

    tools/ensemble_contacts.py DIR
    tools/ensemble_contacts.py --list DIR

Reads DIR/runs/<seed>_<terrain>/{summary.json,events.csv,vehicles.csv,metrics.json} and
DIR/courses/<seed>_<terrain>.yaml of every completed run; prints per terrain:
  - the leader's smallest distance from its reference point to an obstacle's edge over the run
    (median, 5th percentile, runs under 1.1 m: the HMMWV's half width);
  - per vehicle, its obstacle contacts (events.csv `collision` with `obstacle=`): how many,
    the speed at contact, the distance from the vehicle's reference point to that obstacle's
    edge at contact, and (followers) how many were on an obstacle the leader also touched;
  - per follower position, the time it reached the leader's start (metrics.json
    follower_start_time_s), m_as_avg, and m_as_avg over the leader's fastest frame (median of
    the per-run ratios).
With --list: one line per vehicle and obstacle it touched (its first contact), where it was
against the leader's track: the reference point's distance to the obstacle's edge at contact;
the leader's distance to that edge where its track passes nearest to the vehicle; the
difference (> 0: the vehicle that much nearer the obstacle than the leader was); the leader's
turn over the BEND_ARC_M of its track around that point and whether the obstacle is on its
inside or outside (straight under STRAIGHT_DEG); the vehicle's speed and steering at contact;
and whether the leader touched that obstacle too.
"""
import csv
import json
import pathlib
import re
import sys
from collections import defaultdict

import numpy as np

OBSTACLE = re.compile(r"id: (\w+), label: (\w+), shape: cylinder, position: \[([-0-9.e]+), "
                      r"([-0-9.e]+)\], radius_m: ([0-9.e]+)")
TERRAINS = ["rigid", "scm_hard", "scm_soft"]
HALF_WIDTH_M = 1.1
BEND_ARC_M = 10.0
STRAIGHT_DEG = 3.0


def tracks(path, every=5):
    """vehicle -> array of (time, x, y, speed, steering), every `every`-th frame."""
    rows = defaultdict(list)
    with open(path, newline="") as f:
        for r in csv.DictReader(f):
            if int(r["frame"]) % every == 0:
                rows[r["vehicle"]].append((float(r["time_s"]), float(r["x"]), float(r["y"]),
                                           float(r["speed_mps"]), float(r["steering"])))
    return {v: np.array(x) for v, x in rows.items()}


def contact_line(run, vehicle, name, label, centre, radius, time_s, track, leader_touched):
    """The --list line of one contact (the module's docstring says what each number is)."""
    x = track[vehicle]
    i = int(np.argmin(abs(x[:, 0] - time_s)))
    p = x[i, 1:3]
    edge = np.hypot(*(p - centre)) - radius
    leader = track["l1"][:, 1:3]
    j = int(np.argmin(np.hypot(*(leader - p).T)))
    leader_edge = np.hypot(*(leader[j] - centre)) - radius
    arc = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(leader, axis=0).T))])
    a = int(np.searchsorted(arc, arc[j] - BEND_ARC_M / 2))
    b = min(int(np.searchsorted(arc, arc[j] + BEND_ARC_M / 2)), len(leader) - 1)
    bend = "straight"
    if j - a >= 1 and b - j >= 1:  # the headings at the window's ends
        t1, t2 = leader[a + 1] - leader[a], leader[b] - leader[b - 1]
        turn = np.degrees(np.arctan2(t1[0] * t2[1] - t1[1] * t2[0], t1 @ t2))
        left = t1[0] * (centre[1] - leader[j][1]) - t1[1] * (centre[0] - leader[j][0]) > 0
        side = "inside" if (turn > 0) == left else "outside"
        bend = f"turn {turn:+.0f} deg, {side if abs(turn) >= STRAIGHT_DEG else 'straight'}"
    return (f"{run} {vehicle} {name} ({label}, r {radius:.2f} m) t {time_s:.2f} s: "
            f"edge {edge:.2f} m, leader's {leader_edge:.2f} m there, nearer by "
            f"{leader_edge - edge:+.2f} m; {bend}; speed {x[i, 3]:.2f} m/s, steering "
            f"{x[i, 4]:+.2f}; leader touched it: {'yes' if leader_touched else 'no'}")


def list_contacts(out):
    def seed_first(run):
        seed, _, terrain = run.name.partition("_")
        return (int(seed), terrain) if seed.isdigit() else (1 << 62, run.name)
    for run in sorted((out / "runs").iterdir(), key=seed_first):
        events = run / "events.csv"
        if not run.is_dir() or not events.exists():
            continue
        contacts = [e for e in csv.DictReader(open(events, newline=""))
                    if e["kind"] == "collision" and "obstacle=" in e["detail"]]
        if not contacts:
            continue
        obstacles = {o: (label, float(x), float(y), float(r)) for o, label, x, y, r in
                     OBSTACLE.findall((out / "courses" / f"{run.name}.yaml").read_text())}
        track = tracks(run / "vehicles.csv", every=1)
        names = [e["detail"].split()[0].split("=", 1)[1] for e in contacts]
        by_leader = {n for e, n in zip(contacts, names) if e["vehicle"] == "l1"}
        seen = set()
        for e, name in zip(contacts, names):
            if (e["vehicle"], name) in seen:
                continue
            seen.add((e["vehicle"], name))
            label, cx, cy, r = obstacles[name]
            print(contact_line(run.name, e["vehicle"], name, label, np.array([cx, cy]), r,
                               float(e["time_s"]), track, name in by_leader))


def main():
    if len(sys.argv) == 3 and sys.argv[1] == "--list":
        list_contacts(pathlib.Path(sys.argv[2]))
        return
    if len(sys.argv) != 2 or sys.argv[1].startswith("-"):
        sys.exit("usage: tools/ensemble_contacts.py [--list] DIR")
    out = pathlib.Path(sys.argv[1])
    stats = defaultdict(lambda: defaultdict(list))
    for run in sorted((out / "runs").iterdir()):
        summary = run / "summary.json"
        if not run.is_dir() or not summary.exists() or '"completed"' not in summary.read_text():
            continue
        terrain = run.name.split("_", 1)[1]
        obstacles = {o: (float(x), float(y), float(r)) for o, _, x, y, r in
                     OBSTACLE.findall((out / "courses" / f"{run.name}.yaml").read_text())}
        track = tracks(run / "vehicles.csv")
        s = stats[terrain]
        leader = track["l1"]
        centres = np.array(list(obstacles.values()))
        clear = (np.linalg.norm(leader[:, None, 1:3] - centres[None, :, :2], axis=2)
                 - centres[None, :, 2]).min(axis=1)
        s["leader_clearance"].append(clear.min())
        contacts = [e for e in csv.DictReader(open(run / "events.csv", newline=""))
                    if e["kind"] == "collision" and "obstacle=" in e["detail"]]
        touched_by_leader = {e["detail"].split()[0] for e in contacts if e["vehicle"] == "l1"}
        for e in contacts:
            v, name = e["vehicle"], e["detail"].split()[0]
            x = track[v]
            i = int(np.argmin(abs(x[:, 0] - float(e["time_s"]))))
            cx, cy, r = obstacles[name.split("=", 1)[1]]
            s[f"{v} speed"].append(x[i, 3])
            s[f"{v} edge"].append(np.hypot(x[i, 1] - cx, x[i, 2] - cy) - r)
            s[f"{v} after leader"].append(v != "l1" and name in touched_by_leader)
        metrics = json.loads((run / "metrics.json").read_text())
        vmax = max(m["max_speed_mps"] for m in metrics["leaders"])
        for m in metrics["followers"]:
            p = m["position"]
            s[f"lag {p}"].append(m["follower_start_time_s"])
            s[f"m_as_avg {p}"].append(m["m_as_avg"])
            s[f"m_as_avg/vmax {p}"].append(m["m_as_avg"] / vmax)
    for terrain in [t for t in TERRAINS if t in stats] + sorted(set(stats) - set(TERRAINS)):
        s = stats[terrain]
        c = np.array(s["leader_clearance"])
        print(f"{terrain}: {len(c)} runs; leader's closest approach (reference point to an "
              f"obstacle's edge) median {np.median(c):.2f} m, 5 % {np.percentile(c, 5):.2f} m, "
              f"under {HALF_WIDTH_M} m in {(c < HALF_WIDTH_M).sum()} runs")
        for v in ("l1", "f1", "f2", "f3"):
            speeds = s[f"{v} speed"]
            if not speeds:
                print(f"  {v}: no contact")
                continue
            line = (f"  {v}: {len(speeds)} contacts, speed median {np.median(speeds):.2f} m/s, "
                    f"reference point to the obstacle's edge median {np.median(s[f'{v} edge']):.2f} m")
            if v != "l1":
                line += f", {sum(s[f'{v} after leader'])} on an obstacle the leader also touched"
            print(line)
        for p in (1, 2, 3):
            if s[f"lag {p}"]:
                print(f"  follower {p}: reached the leader's start after {np.median(s[f'lag {p}']):.2f} s; "
                      f"m_as_avg {np.median(s[f'm_as_avg {p}']):.3f} m/s, over the leader's fastest "
                      f"frame {np.median(s[f'm_as_avg/vmax {p}']):.3f} (medians)")


if __name__ == "__main__":
    main()
