#!/usr/bin/python3
"""Training curve of a syndds_train output directory.

    tools/training_curve.py DIR

Reads DIR/training.csv (one row per PPO update, docs/learning.md) and writes
DIR/training_curve.png: the moving average of the finished episodes' returns (last 20
episodes) and the mean return of each update's episodes, against the interactions.
Needs Debian's python3-matplotlib (launch_scripts/setup.sh installs it).
"""
import csv
import math
import pathlib
import sys

import matplotlib

matplotlib.use("Agg")  # files only, no display
import matplotlib.pyplot as plt  # noqa: E402


def main():
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    out = pathlib.Path(sys.argv[1])
    with open(out / "training.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    if not rows:
        sys.exit(f"training_curve: no updates in {out / 'training.csv'}")
    x = [int(r["interactions"]) for r in rows]
    mean = [float(r["mean_return"]) for r in rows]
    moving = [float(r["moving_average_return"]) for r in rows]
    fig, ax = plt.subplots(figsize=(7, 4))
    ax.plot(x, mean, ".", color="0.6", markersize=3, label="mean return of the update's episodes")
    ax.plot(x, moving, "-", color="C0", label="moving average, last 20 episodes")
    ax.set_xlabel("interactions")
    ax.set_ylabel("episode return")
    finite = [v for v in mean + moving if not math.isnan(v)]
    if finite and min(finite) < 0 and max(finite) < 0 and min(finite) / max(finite) > 100:
        ax.set_yscale("symlog")  # returns spanning decades: early random policies
    ax.grid(True, alpha=0.3)
    ax.legend()
    ax.set_title(f"PPO training, {len(rows)} updates")
    fig.tight_layout()
    fig.savefig(out / "training_curve.png", dpi=120)
    print(f"wrote {out / 'training_curve.png'}")


if __name__ == "__main__":
    main()
