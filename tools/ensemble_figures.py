#!/usr/bin/python3
"""Figures and report.md of an ensemble directory written by launch_scripts/run_ensemble.sh.

    tools/ensemble_figures.py DIR

Reads DIR/ensemble.csv, DIR/runs.csv, the runs' vehicles.csv and metrics_samples.csv and the
courses' scenarios; writes DIR/figures/{trajectories,along_path,metrics_boxplots,obstacles_hit,
leader_speed,real_time_factor}.png and DIR/report.md.
Needs Debian's python3-matplotlib and python3-numpy (launch_scripts/setup.sh installs them).
"""
import csv
import pathlib
import re
import sys
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


def report(out, rows, runs):
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
             "| terrain | follower | " + " | ".join(k for k, _ in METRICS) + " | obstacles hit |",
             "|---|---|" + "---|" * (len(METRICS) + 1)]
    for terrain in terrains:
        for position in positions:
            sel = [r for r in rows if r["terrain"] == terrain and r["position"]
                   and int(r["position"]) == position]
            cells = []
            for key, _ in METRICS:
                values = [float(r[key]) for r in sel if r[key]]
                cells.append(f"{np.median(values):.3f}" if values else "-")
            hits = sum(int(r["obstacles_hit"]) for r in sel)
            lines.append(f"| {terrain} | {position} | " + " | ".join(cells) + f" | {hits} |")
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
    report(out, rows, runs)
    print(f"ensemble_figures: {out / 'report.md'} and {figures}/")


if __name__ == "__main__":
    main()
