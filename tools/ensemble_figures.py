#!/usr/bin/python3
"""Figures and report.md of an ensemble directory written by launch_scripts/run_ensemble.sh.

    tools/ensemble_figures.py DIR

Reads DIR/ensemble.csv, DIR/runs.csv, DIR/ensemble.setup, the runs' vehicles.csv (once each,
shared by every figure that needs it), metrics_samples.csv and sensors/f3/chase_camera.avi (when
recorded) and the courses' scenarios; writes DIR/figures/{trajectories,along_path,
metrics_boxplots,obstacles_hit,leader_speed,real_time_factor,planned_paths,driven_paths,
leader_gears}.png, DIR/figures/chase_<terrain>.jpg (or .png, whichever is smaller; only for
terrains with a chase video), DIR/paper_comparison.md (tools/paper_comparison.py) and
DIR/report.md.
Needs Debian's python3-matplotlib and python3-numpy (launch_scripts/setup.sh installs them).
"""
import csv
import io
import json
import pathlib
import re
import sys
import traceback
from collections import defaultdict

import matplotlib

matplotlib.use("Agg")  # files only, no display
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

METRICS = [("m_p_avg", "path deviation, mean (m)"), ("m_p_max", "path deviation, max (m)"),
           ("m_as_avg", "abs. speed deviation, mean (m/s)"),
           ("m_as_max", "abs. speed deviation, max (m/s)"),
           ("m_rs_avg", "rel. speed deviation, mean (-)"), ("m_rs_max", "rel. speed deviation, max (-)")]
TERRAIN_ORDER = ["rigid", "scm_hard", "scm_soft"]
OBSTACLE = re.compile(r"position: \[([-0-9.e]+), ([-0-9.e]+)\], radius_m: ([0-9.e]+)")
TARGET = re.compile(r"target_mps: ([0-9.e]+)")
WAYPOINTS = re.compile(r"waypoints: (\[\[.*?\]\])")
FOLLOWER_STRIDE = 20  # frames between the followers' points kept for the driven paths (0.2 s)
LEADER_STRIDE = 5  # frames between the leaders' points kept (0.05 s: a gear is held >= 1 s)
PLOT_STRIDE = 4  # of the leaders' points kept, those drawn (every 20th frame)
MOVING_MPS = 0.5  # the leader counts as moving from this speed (metrics.json's mean speed too)
CHASE_VIDEO = pathlib.Path("sensors") / "f3" / "chase_camera.avi"


def read_csv(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def terrains_of(rows):
    seen = {r["terrain"] for r in rows}
    return [t for t in TERRAIN_ORDER if t in seen] + sorted(seen - set(TERRAIN_ORDER))


def shown_course(runs):
    """The course the per-course figures show: the first whose runs all completed, else the first."""
    seeds = list(dict.fromkeys(r["seed"] for r in runs))
    for seed in seeds:
        if all(r["status"] == "completed" for r in runs if r["seed"] == seed):
            return seed
    return seeds[0]


def trajectories(out, runs, figures):
    """Top-down view of one course on each terrain: obstacles and every vehicle's track."""
    seed = shown_course(runs)
    terrains = [r["terrain"] for r in runs if r["seed"] == seed]
    fig, axes = plt.subplots(1, len(terrains), figsize=(5 * len(terrains), 5), squeeze=False)
    for ax, terrain in zip(axes[0], terrains):
        run_id = f"{seed}_{terrain}"
        scenario = (out / "courses" / f"{run_id}.yaml").read_text()
        for x, y, r in OBSTACLE.findall(scenario):
            ax.add_patch(plt.Circle((float(x), float(y)), float(r), color="0.6"))
        tracks = defaultdict(lambda: ([], []))
        vehicles = out / "runs" / run_id / "vehicles.csv"
        if vehicles.exists():
            for row in read_csv(vehicles):
                tracks[row["vehicle"]][0].append(float(row["x"]))
                tracks[row["vehicle"]][1].append(float(row["y"]))
        for vehicle, (xs, ys) in tracks.items():
            ax.plot(xs, ys, lw=1.2, label=vehicle)
        ax.set_title(f"course {seed}, {terrain}")
        ax.set_xlim(-35, 105)
        ax.set_ylim(-35, 105)
        ax.set_aspect("equal")
        ax.set_xlabel("x east (m)")
        ax.set_ylabel("y north (m)")
        ax.legend(loc="lower right", fontsize=8)
    fig.tight_layout()
    fig.savefig(figures / "trajectories.png", dpi=100)
    plt.close(fig)


def along_path(out, runs, figures):
    """Path deviation (top) and speeds of the leader and the followers (bottom) against the
    distance along the leader's path, on one course and each terrain (metrics_samples.csv)."""
    seed = shown_course(runs)
    terrains = [r["terrain"] for r in runs if r["seed"] == seed]
    fig, axes = plt.subplots(2, len(terrains), figsize=(5 * len(terrains), 7), squeeze=False,
                             sharex=True)
    for column, terrain in enumerate(terrains):
        top, bottom = axes[0][column], axes[1][column]
        path = out / "runs" / f"{seed}_{terrain}" / "metrics_samples.csv"
        series = defaultdict(lambda: defaultdict(list))
        if path.exists():
            for row in read_csv(path):
                s = series[(int(row["position"]), row["follower"], row["leader"])]
                for key in ("arc_m", "path_m", "leader_speed_mps", "follower_speed_mps"):
                    s[key].append(float(row[key]))
        leader_drawn = set()
        for (position, follower, leader), s in sorted(series.items()):
            top.plot(s["arc_m"], s["path_m"], lw=1, color=f"C{position - 1}", label=follower)
            bottom.plot(s["arc_m"], s["follower_speed_mps"], lw=1, color=f"C{position - 1}",
                        label=follower)
            # The leader's speed along its own path: the longest series has all of it.
            if leader not in leader_drawn:
                longest = max((v for k, v in series.items() if k[2] == leader),
                              key=lambda v: len(v["arc_m"]))
                bottom.plot(longest["arc_m"], longest["leader_speed_mps"], lw=1.5, color="k",
                            label=f"{leader} (leader)")
                leader_drawn.add(leader)
        top.set_title(f"course {seed}, {terrain}")
        top.set_ylabel("path deviation (m)")
        bottom.set_ylabel("speed (m/s)")
        bottom.set_xlabel("distance along the leader's path (m)")
        if not series:
            top.text(0.5, 0.5, "no samples", transform=top.transAxes, ha="center")
        else:
            top.legend(fontsize=8)
            bottom.legend(fontsize=8, loc="lower center")
        top.set_ylim(bottom=0)
        bottom.set_ylim(bottom=0)
    fig.tight_layout()
    fig.savefig(figures / "along_path.png", dpi=100)
    plt.close(fig)


def target_speed(out, seed, terrain):
    """The first leader's target speed in the course's scenario (None if unreadable)."""
    try:
        found = TARGET.search((out / "courses" / f"{seed}_{terrain}.yaml").read_text())
    except OSError:
        return None
    return float(found.group(1)) if found else None


def leader_runs(rows):
    """One row per run (its first follower's row carries the leader's speeds)."""
    seen, out = set(), []
    for r in rows:
        key = (r["seed"], r["terrain"])
        if key not in seen and r["leader_mean_speed_mps"]:
            seen.add(key)
            out.append(r)
    return out


def leader_speed(out, rows, figures):
    """The leaders' fastest frame and mean speed while moving, per terrain, against the target."""
    terrains = terrains_of(rows)
    runs = leader_runs(rows)
    fig, ax = plt.subplots(figsize=(7, 4))
    for t_index, terrain in enumerate(terrains):
        sel = [r for r in runs if r["terrain"] == terrain]
        for offset, key, marker, label in [(-0.12, "leader_max_speed_mps", "^", "maximum"),
                                           (0.12, "leader_mean_speed_mps", "o", "mean while moving")]:
            values = [float(r[key]) for r in sel]
            ax.plot([t_index + offset] * len(values), values, marker, color=f"C{t_index}",
                    alpha=0.7, label=label if t_index == 0 else None)
        targets = {target_speed(out, r["seed"], terrain) for r in sel} - {None}
        for target in targets:
            ax.plot([t_index - 0.3, t_index + 0.3], [target, target], "k--", lw=1,
                    label="target" if t_index == 0 else None)
    ax.set_xticks(range(len(terrains)))
    ax.set_xticklabels(terrains)
    ax.set_ylabel("leader speed (m/s)")
    ax.set_ylim(bottom=0)
    ax.legend(fontsize=8, loc="lower left")
    fig.tight_layout()
    fig.savefig(figures / "leader_speed.png", dpi=100)
    plt.close(fig)


def boxplots(rows, figures):
    """The six metrics per terrain, one box per follower position."""
    terrains = terrains_of(rows)
    positions = sorted({int(r["position"]) for r in rows if r["position"]})
    fig, axes = plt.subplots(2, 3, figsize=(15, 8))
    width = 0.8 / max(1, len(positions))
    for ax, (key, label) in zip(axes.flat, METRICS):
        for p_index, position in enumerate(positions):
            data, where = [], []
            for t_index, terrain in enumerate(terrains):
                values = [float(r[key]) for r in rows if r["terrain"] == terrain and r[key]
                          and r["position"] and int(r["position"]) == position]
                data.append(values if values else [np.nan])
                where.append(t_index + (p_index - (len(positions) - 1) / 2) * width)
            box = ax.boxplot(data, positions=where, widths=width * 0.9, patch_artist=True,
                             manage_ticks=False)
            for patch in box["boxes"]:
                patch.set_facecolor(f"C{p_index}")
            ax.plot([], [], color=f"C{p_index}", lw=6, label=f"follower {position}")
        ax.set_xticks(range(len(terrains)))
        ax.set_xticklabels(terrains)
        ax.set_title(label)
    axes.flat[0].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(figures / "metrics_boxplots.png", dpi=100)
    plt.close(fig)


def obstacles_hit(rows, figures):
    """Obstacles hit, summed over the courses, per terrain and follower position."""
    terrains = terrains_of(rows)
    positions = sorted({int(r["position"]) for r in rows if r["position"]})
    fig, ax = plt.subplots(figsize=(7, 4))
    width = 0.8 / max(1, len(positions))
    for p_index, position in enumerate(positions):
        hits = [sum(int(r["obstacles_hit"]) for r in rows if r["terrain"] == t and r["position"]
                    and int(r["position"]) == position) for t in terrains]
        ax.bar(np.arange(len(terrains)) + (p_index - (len(positions) - 1) / 2) * width, hits,
               width, label=f"follower {position}", color=f"C{p_index}")
    ax.set_xticks(range(len(terrains)))
    ax.set_xticklabels(terrains)
    ax.set_ylabel("obstacles hit (sum over courses)")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(figures / "obstacles_hit.png", dpi=100)
    plt.close(fig)


def real_time_factor(runs, figures):
    """Wall time / simulated time of every run."""
    terrains = terrains_of(runs)
    fig, ax = plt.subplots(figsize=(7, 4))
    for t_index, terrain in enumerate(terrains):
        values = [float(r["real_time_factor"]) for r in runs
                  if r["terrain"] == terrain and r["real_time_factor"]]
        ax.plot([t_index] * len(values), values, "o", color=f"C{t_index}", alpha=0.7)
    ax.set_xticks(range(len(terrains)))
    ax.set_xticklabels(terrains)
    ax.set_ylabel("real-time factor (wall / simulated)")
    ax.set_ylim(bottom=0)
    fig.tight_layout()
    fig.savefig(figures / "real_time_factor.png", dpi=100)
    plt.close(fig)


def save_small(fig, path, dpi=80):
    """Save a figure as PNG with at most 256 colours (Pillow's quantisation: figures of many
    thin translucent lines shrink 2-4x), or as matplotlib writes it when Pillow is missing."""
    try:
        from PIL import Image
    except ImportError:
        fig.savefig(path, dpi=dpi)
        return
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=dpi)
    buffer.seek(0)
    Image.open(buffer).convert("RGB").quantize(256).save(path, optimize=True)


def course_scenario(out, seed, terrain):
    """The text of a course's scenario (None if unreadable)."""
    try:
        return (out / "courses" / f"{seed}_{terrain}.yaml").read_text()
    except OSError:
        return None


def planned_path(scenario):
    """The first leader's planned waypoints [(x, y), ...] of a scenario's text (None if absent)."""
    found = WAYPOINTS.search(scenario or "")
    return [tuple(p) for p in json.loads(found.group(1))] if found else None


def obstacles_of(scenario):
    return [(float(x), float(y), float(r)) for x, y, r in OBSTACLE.findall(scenario or "")]


def vehicle_rows(path, stride_of):
    """The rows of a vehicles.csv, split, per vehicle, every stride_of(vehicle)-th frame:
    (header, {vehicle: [[field, ...], ...]}). The recorder writes every frame with the same
    vehicles in the same order, so each vehicle's rows are a slice of the lines (checked:
    anything else is read line by line)."""
    with open(path) as f:
        lines = f.read().split("\n")
    header = lines[0].split(",")
    body = [line for line in lines[1:] if line]
    i_frame, i_vehicle = header.index("frame"), header.index("vehicle")
    first = body[0].split(",", 1)[0] if body else ""
    n = next((i for i, line in enumerate(body) if not line.startswith(first + ",")), len(body))
    out = {}
    if body and len(body) % n == 0:
        for v in range(n):
            vehicle = body[v].split(",")[i_vehicle]
            stride = stride_of(vehicle)
            offset = (-int(first)) % stride  # rows of frames that are multiples of the stride
            rows = [line.split(",") for line in body[v + offset * n::n * stride]]
            frames = [int(r[i_frame]) for r in rows]
            if (vehicle in out or any(r[i_vehicle] != vehicle for r in rows)
                    or frames != list(range(frames[0], frames[0] + stride * len(rows), stride)
                                      if rows else [])):
                break
            out[vehicle] = rows
        else:
            return header, out
    out = defaultdict(list)
    for line in body:
        row = line.split(",")
        if int(row[i_frame]) % stride_of(row[i_vehicle]) == 0:
            out[row[i_vehicle]].append(row)
    return header, out


def read_tracks(out, rows, runs):
    """One pass over each completed run's vehicles.csv, shared by the figures and the paper
    comparison: {run_id: {"leaders": {id: {"t", "x", "y", "speed", "gear": arrays, every
    LEADER_STRIDE-th frame}}, "followers": {id: (position, x array, y array), every
    FOLLOWER_STRIDE-th frame}}}. A vehicle is a follower when ensemble.csv has a row for it, a
    leader otherwise."""
    positions = {(r["seed"], r["terrain"], r["follower"]): int(r["position"])
                 for r in rows if r["position"]}
    tracks = {}
    for run in runs:
        if run["status"] != "completed":
            continue
        run_id = f"{run['seed']}_{run['terrain']}"
        position = {v: p for (seed, terrain, v), p in positions.items()
                    if (seed, terrain) == (run["seed"], run["terrain"])}
        try:
            header, by_vehicle = vehicle_rows(
                out / "runs" / run_id / "vehicles.csv",
                lambda v: FOLLOWER_STRIDE if v in position else LEADER_STRIDE)
        except (OSError, ValueError, IndexError):
            continue
        index = {k: header.index(k) for k in ("time_s", "x", "y", "speed_mps", "gear")}
        track = {"leaders": {}, "followers": {}}
        for vehicle, vrows in by_vehicle.items():
            columns = np.array([[r[i] for i in index.values()] for r in vrows], float).reshape(-1, 5)
            t, x, y, speed, gear = columns.T
            if vehicle in position:
                track["followers"][vehicle] = (position[vehicle], x, y)
            else:
                track["leaders"][vehicle] = {"t": t, "x": x, "y": y, "speed": speed, "gear": gear}
        tracks[run_id] = track
    return tracks


def planned_paths(out, runs, figures):
    """The paper's Fig. 12: every course's planned leader path (one terrain's scenario per
    seed) and, faint, the obstacles that every course has (the fixed ones)."""
    seeds = list(dict.fromkeys(r["seed"] for r in runs))
    scenarios = []
    for seed in seeds:
        terrain = terrains_of([r for r in runs if r["seed"] == seed])[0]
        scenarios.append(course_scenario(out, seed, terrain))
    paths = [p for p in map(planned_path, scenarios) if p]
    fields = [obstacles_of(s) for s in scenarios if s]
    # The fixed obstacles: at the same place in every course (drawn at their largest radius:
    # the paper's protocol shrinks each course's obstacles to the path).
    common = set.intersection(*[{(x, y) for x, y, _ in f} for f in fields]) if fields else set()
    radius = defaultdict(float)
    for field in fields:
        for x, y, r in field:
            if (x, y) in common:
                radius[(x, y)] = max(radius[(x, y)], r)
    fig, ax = plt.subplots(figsize=(5.5, 5.5))
    for (x, y), r in sorted(radius.items()):
        ax.add_patch(plt.Circle((x, y), r, color="0.85", zorder=0))
    from matplotlib.collections import LineCollection
    crowd = max(1, len(paths))  # fainter lines the more there are
    ax.add_collection(LineCollection(paths, linewidths=0.6 if crowd > 20 else 1.0, colors="C0",
                                     alpha=float(np.clip(45 / crowd, 0.35, 0.9))))
    if paths:
        ax.plot(*paths[0][0], "ko", ms=4)
        ax.plot(*paths[0][-1], "k*", ms=8)
        ax.annotate("start", paths[0][0], xytext=(4, -10), textcoords="offset points", fontsize=8)
        ax.annotate("goal", paths[0][-1], xytext=(-22, 6), textcoords="offset points", fontsize=8)
    else:
        ax.text(0.5, 0.5, "no planned paths", transform=ax.transAxes, ha="center")
    ax.set_title(f"{len(paths)} planned leader paths", fontsize=10)
    ax.set_xlim(-5, 105)
    ax.set_ylim(-5, 105)
    ax.set_aspect("equal")
    ax.set_xlabel("x east (m)")
    ax.set_ylabel("y north (m)")
    fig.tight_layout()
    save_small(fig, figures / "planned_paths.png")
    plt.close(fig)


def driven_paths(tracks, rows, figures):
    """The paper's Fig. 18: every vehicle's driven path in every completed run, per terrain,
    leaders black, followers coloured by position."""
    from matplotlib.collections import LineCollection
    terrains = terrains_of(rows) or TERRAIN_ORDER[:1]
    fig, axes = plt.subplots(1, len(terrains), figsize=(4.2 * len(terrains), 4.4), squeeze=False)
    for ax, terrain in zip(axes[0], terrains):
        by_position = defaultdict(list)
        for run_id, track in tracks.items():
            if run_id.split("_", 1)[1] != terrain:
                continue
            for position, xs, ys in track["followers"].values():
                by_position[position].append(np.column_stack([xs, ys]))
            for leader in track["leaders"].values():
                by_position[0].append(np.column_stack([leader["x"][::PLOT_STRIDE],
                                                       leader["y"][::PLOT_STRIDE]]))
        for position in sorted(by_position):  # the leaders below, the last follower on top
            color = "k" if position == 0 else f"C{position - 1}"
            ax.add_collection(LineCollection(by_position[position], linewidths=0.4, colors=color,
                                             alpha=0.3))
            ax.plot([], [], color=color, label="leader" if position == 0 else f"follower {position}")
        runs_shown = len({run_id for run_id in tracks if run_id.split("_", 1)[1] == terrain})
        ax.set_title(f"{terrain}: {runs_shown} runs", fontsize=10)
        ax.set_xlim(-30, 105)
        ax.set_ylim(-30, 105)
        ax.set_aspect("equal")
        ax.set_xlabel("x east (m)")
        ax.legend(fontsize=7, loc="lower right")
    axes[0][0].set_ylabel("y north (m)")
    fig.tight_layout()
    save_small(fig, figures / "driven_paths.png")
    plt.close(fig)


def leader_gear_stats(tracks):
    """Per terrain: the leaders' highest gear in each run, and the frames in each gear while
    moving (speed >= MOVING_MPS), summed over the runs."""
    highest, frames = defaultdict(list), defaultdict(lambda: defaultdict(int))
    for run_id, track in tracks.items():
        terrain = run_id.split("_", 1)[1]
        for leader in track["leaders"].values():
            highest[terrain].append(int(leader["gear"].max()))
            gears, counts = np.unique(leader["gear"][leader["speed"] >= MOVING_MPS],
                                      return_counts=True)
            for gear, count in zip(gears, counts):
                frames[terrain][int(gear)] += int(count)
    return highest, frames


def leader_gears(tracks, rows, figures):
    """Share of runs by the leader's highest gear (left), share of the moving time in each gear
    (right), per terrain."""
    highest, frames = leader_gear_stats(tracks)
    terrains = [t for t in terrains_of(rows) if t in highest]
    gears = sorted({g for t in terrains for g in highest[t]} |
                   {g for t in terrains for g in frames[t]}) or [0]
    gears = list(range(min(gears), max(gears) + 1))
    fig, axes = plt.subplots(1, 2, figsize=(9, 3.6))
    width = 0.8 / max(1, len(terrains))
    for t_index, terrain in enumerate(terrains):
        shift = (t_index - (len(terrains) - 1) / 2) * width
        runs_n = len(highest[terrain])
        axes[0].bar(np.array(gears) + shift, [100 * highest[terrain].count(g) / runs_n
                                              for g in gears],
                    width, color=f"C{t_index}", label=f"{terrain} ({runs_n} runs)")
        total = sum(frames[terrain].values()) or 1
        axes[1].bar(np.array(gears) + shift, [100 * frames[terrain][g] / total for g in gears],
                    width, color=f"C{t_index}", label=terrain)
    for ax, title in zip(axes, ["leader's highest gear in a run", "leader's time in gear while moving"]):
        ax.set_xticks(gears)
        ax.set_xlabel("gear (0: neutral)")
        ax.set_title(title, fontsize=10)
        ax.set_ylim(0, 100)
    axes[0].set_ylabel("share of runs (%)")
    axes[1].set_ylabel(f"share of frames at >= {MOVING_MPS} m/s (%)")
    axes[0].legend(fontsize=8)
    if not terrains:
        axes[0].text(0.5, 0.5, "no vehicles.csv", transform=axes[0].transAxes, ha="center")
    fig.tight_layout()
    save_small(fig, figures / "leader_gears.png")
    plt.close(fig)


def avi_frames(data):
    """(offset, length) of each video frame of an AVI file's bytes: its '00dc'/'00db' chunks,
    found by walking the RIFF lists; in an MJPG AVI each is a complete JPEG. Falls back to
    scanning for JPEG start/end markers (FFD8FF ... FFD9) when the RIFF walk finds none."""
    frames = []

    def walk(pos, end):
        while pos + 8 <= end:
            fourcc, size = data[pos:pos + 4], int.from_bytes(data[pos + 4:pos + 8], "little")
            if fourcc in (b"RIFF", b"LIST"):
                walk(pos + 12, min(end, pos + 8 + size))
            elif fourcc[2:] in (b"dc", b"db") and data[pos + 8:pos + 10] == b"\xff\xd8":
                frames.append((pos + 8, size))
            pos += 8 + size + (size & 1)

    walk(0, len(data))
    if frames:
        return frames
    start = data.find(b"\xff\xd8\xff")
    while start >= 0:
        end = data.find(b"\xff\xd9", start)
        if end < 0:
            break
        frames.append((start, end + 2 - start))
        start = data.find(b"\xff\xd8\xff", end + 2)
    return frames


def chase_stills(out, runs, figures):
    """The paper's Fig. 10: for each terrain, the frame of the first run (in seed order) with a
    chase video (sensors/f3/chase_camera.avi) closest to the middle of the run, kept as its JPEG
    bytes (figures/chase_<terrain>.jpg) or as PNG if that is smaller. Returns
    [(terrain, file name, run_id, frame time s)]."""
    stills = []
    for terrain in terrains_of(runs):
        for run in sorted((r for r in runs if r["terrain"] == terrain), key=lambda r: int(r["seed"])):
            run_dir = out / "runs" / f"{run['seed']}_{terrain}"
            video = run_dir / CHASE_VIDEO
            if not video.exists():
                continue
            data = video.read_bytes()
            frames = avi_frames(data)
            if not frames:
                continue
            try:
                times = [float(r["time_s"]) for r in read_csv(video.parent / "frames.csv")
                         if r["sensor"] == "chase_camera"]
            except (OSError, KeyError, ValueError):
                times = []
            if len(times) == len(frames):  # the frame nearest half the run's simulated time
                middle = (float(run["sim_time_s"]) / 2 if run.get("sim_time_s")
                          else (times[0] + times[-1]) / 2)
                index = int(np.argmin([abs(t - middle) for t in times]))
                time = times[index]
            else:  # no usable frame times: the middle frame
                index, time = len(frames) // 2, None
            offset, length = frames[index]
            jpeg = data[offset:offset + length]
            name, payload = f"chase_{terrain}.jpg", jpeg
            try:
                from PIL import Image
                png = io.BytesIO()
                Image.open(io.BytesIO(jpeg)).save(png, format="PNG", optimize=True)
                if png.tell() < len(jpeg):
                    name, payload = f"chase_{terrain}.png", png.getvalue()
            except ImportError:
                pass
            for stale in figures.glob(f"chase_{terrain}.*"):
                stale.unlink()
            (figures / name).write_bytes(payload)
            stills.append((terrain, name, run_dir.name, time))
            break
    return stills


def report(out, rows, runs, stills):
    terrains = terrains_of(rows)
    positions = sorted({int(r["position"]) for r in rows if r["position"]})
    seeds = sorted({int(r["seed"]) for r in runs})
    failed = [f"{r['seed']}_{r['terrain']} ({r['status']})" for r in runs
              if r["status"] != "completed"]
    controllers = sorted({r["controller"] for r in rows if r.get("controller")})
    lines = [f"# Ensemble report: {len(seeds)} courses x {len(terrains)} terrains",
             "", f"Courses (seeds) {seeds[0]}..{seeds[-1]}; {len(runs)} runs, "
             f"{len(runs) - len(failed)} completed; followers: {', '.join(controllers) or '-'}. "
             "Definitions: docs/ensemble.md, docs/convoy.md.",
             "", "Median over the courses (terrain, follower position):", "",
             "| terrain | follower | " + " | ".join(k for k, _ in METRICS)
             + " | obstacles hit | runs stuck | leader lost |",
             "|---|---|" + "---|" * (len(METRICS) + 3)]
    for terrain in terrains:
        for position in positions:
            sel = [r for r in rows if r["terrain"] == terrain and r["position"]
                   and int(r["position"]) == position]
            cells = []
            for key, _ in METRICS:
                values = [float(r[key]) for r in sel if r[key]]
                cells.append(f"{np.median(values):.3f}" if values else "-")
            hits = sum(int(r["obstacles_hit"]) for r in sel)
            # Columns of ensemble.csv since stuck was measured; "-" for older folders.
            stuck = (str(sum(int(r["stuck"]) for r in sel if r["stuck"]))
                     if sel and "stuck" in sel[0] else "-")
            lost = (str(sum(int(r["leader_lost_events"]) for r in sel if r["leader_lost_events"]))
                    if sel and "leader_lost_events" in sel[0] else "-")
            lines.append(f"| {terrain} | {position} | " + " | ".join(cells)
                         + f" | {hits} | {stuck} | {lost} |")
    lines += ["", "Leaders (median over the courses; target: the scenario's target speed):", "",
              "| terrain | runs | max speed (m/s) | mean speed while moving (m/s) | target (m/s) |",
              "|---|---|---|---|---|"]
    heads = leader_runs(rows)
    for terrain in terrains:
        sel = [r for r in heads if r["terrain"] == terrain]
        if not sel:
            continue
        targets = sorted({target_speed(out, r["seed"], terrain) for r in sel} - {None})
        lines.append(f"| {terrain} | {len(sel)} | "
                     f"{np.median([float(r['leader_max_speed_mps']) for r in sel]):.2f} | "
                     f"{np.median([float(r['leader_mean_speed_mps']) for r in sel]):.2f} | "
                     f"{', '.join(f'{t:g}' for t in targets) or '-'} |")
    if failed:
        lines += ["", "Runs that did not complete: " + ", ".join(failed)]
    shown = shown_course(runs)
    for name, caption in [("trajectories", f"Trajectories on course {shown}"),
                          ("along_path", f"Deviation and speed along the leader's path, course {shown}"),
                          ("metrics_boxplots", "The six metrics per terrain and follower"),
                          ("obstacles_hit", "Obstacles hit"),
                          ("leader_speed", "Leader speeds"),
                          ("real_time_factor", "Real-time factor of each run")]:
        lines += ["", f"## {caption}", "", f"![{caption}](figures/{name}.png)"]
    for name, caption in [("planned_paths", "The planned leader paths of all courses "
                           "(the paper's Fig. 12; faint: the obstacles every course has)"),
                          ("driven_paths", "The driven paths of every vehicle, per terrain "
                           "(the paper's Fig. 18)"),
                          ("leader_gears", "The leaders' highest gear and time in each gear "
                           "(the paper's Sec. 4.2 on gear shifting on deformable soil)")]:
        lines += ["", f"## {caption}", "", f"![{caption}](figures/{name}.png)"]
    if stills:
        lines += ["", "## Chase camera behind the last follower (the paper's Fig. 10)", ""]
        for terrain, name, run_id, time in stills:
            when = f"t = {time:.2f} s" if time is not None else "middle frame"
            kept = ("the recorded JPEG frame, unchanged" if name.endswith(".jpg")
                    else "the recorded JPEG frame as PNG")
            lines += [f"![chase camera, {terrain}](figures/{name})", "",
                      f"{terrain}: run {run_id}, {when} ({kept}).", ""]
    if (out / "paper_comparison.md").exists():
        lines += ["", "## Comparison with the paper", "",
                  "[paper_comparison.md](paper_comparison.md): the paper's statements about this "
                  "study, checked against this ensemble."]
    (out / "report.md").write_text("\n".join(lines) + "\n")


def main():
    if len(sys.argv) != 2:
        sys.exit("usage: tools/ensemble_figures.py ENSEMBLE_DIR")
    out = pathlib.Path(sys.argv[1])
    try:
        rows = [r for r in read_csv(out / "ensemble.csv") if r["status"] == "completed"]
        runs = read_csv(out / "runs.csv")
    except OSError as e:
        sys.exit(f"ensemble_figures: {e}")
    if not runs:
        sys.exit(f"ensemble_figures: {out / 'runs.csv'} lists no runs")
    figures = out / "figures"
    figures.mkdir(exist_ok=True)
    trajectories(out, runs, figures)
    along_path(out, runs, figures)
    boxplots(rows, figures)
    obstacles_hit(rows, figures)
    leader_speed(out, rows, figures)
    real_time_factor(runs, figures)
    tracks = read_tracks(out, rows, runs)
    planned_paths(out, runs, figures)
    driven_paths(tracks, rows, figures)
    leader_gears(tracks, rows, figures)
    stills = chase_stills(out, runs, figures)
    sys.dont_write_bytecode = True  # no __pycache__ in tools/
    import paper_comparison  # tools/ beside this file; imports this module's helpers
    try:
        paper_comparison.write(out, rows, runs, tracks)
    except Exception:  # the figures and report.md still count: say why, report without it
        traceback.print_exc()
        print("ensemble_figures: no paper_comparison.md (tools/paper_comparison.py failed)",
              file=sys.stderr)
        (out / "paper_comparison.md").unlink(missing_ok=True)
    report(out, rows, runs, stills)
    print(f"ensemble_figures: {out / 'report.md'} and {figures}/")


if __name__ == "__main__":
    main()
