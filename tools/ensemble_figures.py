#!/usr/bin/python3
"""Figures and report.md of an ensemble directory written by launch_scripts/run_ensemble.sh.

    tools/ensemble_figures.py DIR

Reads DIR/ensemble.csv, DIR/runs.csv, the runs' vehicles.csv and the courses' scenarios; writes
DIR/figures/{trajectories,metrics_boxplots,obstacles_hit,real_time_factor}.png and DIR/report.md.
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


def read_csv(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def terrains_of(rows):
    seen = {r["terrain"] for r in rows}
    return [t for t in TERRAIN_ORDER if t in seen] + sorted(seen - set(TERRAIN_ORDER))


def trajectories(out, runs, figures):
    """Top-down view of the first course on each terrain: obstacles and every vehicle's track."""
    seed = runs[0]["seed"]
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
    lines = [f"# Ensemble report: {len(seeds)} courses x {len(terrains)} terrains",
             "", f"Courses (seeds) {seeds[0]}..{seeds[-1]}; {len(runs)} runs, "
             f"{len(runs) - len(failed)} completed. Definitions: docs/ensemble.md, docs/convoy.md.",
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
    if failed:
        lines += ["", "Runs that did not complete: " + ", ".join(failed)]
    for name, caption in [("trajectories", "Trajectories on the first course"),
                          ("metrics_boxplots", "The six metrics per terrain and follower"),
                          ("obstacles_hit", "Obstacles hit"),
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
    boxplots(rows, figures)
    obstacles_hit(rows, figures)
    real_time_factor(runs, figures)
    report(out, rows, runs)
    print(f"ensemble_figures: {out / 'report.md'} and {figures}/")


if __name__ == "__main__":
    main()
