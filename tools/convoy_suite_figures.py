#!/usr/bin/python3
"""The paper's Table 1 for a convoy suite directory written by launch_scripts/run_convoy_suite.sh.

    tools/convoy_suite_figures.py DIR

Reads the runs DIR/<convoy>_<terrain>-<mode>/ (vehicles.csv and scene.json; convoy 1L3F, 2L2F,
3L1F, terrain rigid, scm_hard, scm_soft, mode distributed or single-process: the distributed
run where both were made); writes DIR/trajectories.png, a 3 x 3 grid (rows: convoys, columns:
terrains) of top-down trajectories, leaders solid and followers dashed, with the scenario's
obstacles, a panel saying "not run" where a run is missing; and appends a line showing the
figure to DIR/convoy_suite.md (once). Table 1 of "Enabling Artificial Intelligence Studies in
Off-Road Mobility Through Physics-Based Simulation of Multiagent Scenarios", J. Comput. Inf. Sci.
Eng. 22 (2022), DOI 10.1115/1.4053321.
Needs Debian's python3-matplotlib and python3-numpy (launch_scripts/setup.sh installs them).
"""
import json
import pathlib
import sys

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
sys.dont_write_bytecode = True  # no __pycache__ in tools/
import ensemble_figures as ef  # noqa: E402  (its matplotlib set-up and vehicles.csv reader)
import numpy as np  # noqa: E402

plt = ef.plt
CONVOYS = ["1L3F", "2L2F", "3L1F"]
TERRAINS = [("rigid", "rigid"), ("scm_hard", "SCM hard"), ("scm_soft", "SCM soft")]
MODES = ["distributed", "single-process"]
STRIDE = 20  # frames between the points drawn (0.2 s)
Y_STRETCH = 2.0  # the y axis drawn this many times the x axis' scale: the paths are long and flat
LINE = "![Trajectories of the nine runs (the paper's Table 1)](trajectories.png)"


def find_run(out, convoy, terrain):
    """(run directory, mode) of a scenario's run, None if not run."""
    for mode in MODES:
        run = out / f"{convoy}_{terrain}-{mode}"
        if (run / "vehicles.csv").exists():
            return run, mode
    return None


def obstacle_patch(obstacle):
    x, y = obstacle["position"][:2]
    size = obstacle.get("size", [0.5, 0.5])
    if obstacle.get("shape") in ("cylinder", "sphere"):
        return plt.Circle((x, y), size[0], color="0.45")
    qw, qx, qy, qz = obstacle.get("orientation", [1, 0, 0, 0])
    yaw = np.degrees(np.arctan2(2 * (qw * qz + qx * qy), 1 - 2 * (qy * qy + qz * qz)))
    corner = np.array([x, y]) - np.array([[np.cos(np.radians(yaw)), -np.sin(np.radians(yaw))],
                                          [np.sin(np.radians(yaw)), np.cos(np.radians(yaw))]]) @ size[:2]
    return plt.Rectangle(corner, 2 * size[0], 2 * size[1], angle=yaw, color="0.45")


def panel(ax, run):
    """One run's obstacles and tracks; returns the extent of both (x0, x1, y0, y1)."""
    scene = json.loads((run / "scene.json").read_text()) if (run / "scene.json").exists() else {}
    roles = {v["id"]: v.get("controller", "") for v in scene.get("vehicles", [])}
    xs, ys = [], []
    for obstacle in scene.get("obstacles", []):
        ax.add_patch(obstacle_patch(obstacle))
        reach = max(obstacle.get("size", [0.5, 0.5])[:2])
        xs += [obstacle["position"][0] - reach, obstacle["position"][0] + reach]
        ys += [obstacle["position"][1] - reach, obstacle["position"][1] + reach]
    header, by_vehicle = ef.vehicle_rows(run / "vehicles.csv", lambda v: STRIDE)
    i_x, i_y = header.index("x"), header.index("y")
    order = list(roles) + [v for v in by_vehicle if v not in roles]
    for index, vehicle in enumerate(v for v in order if v in by_vehicle):
        track = np.array([[r[i_x], r[i_y]] for r in by_vehicle[vehicle]], float)
        leader = roles.get(vehicle, "path_follower") == "path_follower"
        ax.plot(track[:, 0], track[:, 1], "-" if leader else "--", lw=1.2, color=f"C{index}",
                label=vehicle)
        xs += [track[:, 0].min(), track[:, 0].max()]
        ys += [track[:, 1].min(), track[:, 1].max()]
    ax.legend(fontsize=6, loc="upper left", ncol=2)
    return (min(xs), max(xs), min(ys), max(ys)) if xs else None


def figure(out):
    fig, axes = plt.subplots(len(CONVOYS), len(TERRAINS), figsize=(15, 6.6), squeeze=False)
    extents = []
    for row, convoy in enumerate(CONVOYS):
        for column, (terrain, label) in enumerate(TERRAINS):
            ax = axes[row][column]
            found = find_run(out, convoy, terrain)
            title = f"{convoy}, {label}"
            if found is None:
                ax.text(0.5, 0.5, "not run", transform=ax.transAxes, ha="center", va="center",
                        fontsize=12, color="0.4")
                ax.set_xticks([])
                ax.set_yticks([])
            else:
                run, mode = found
                try:
                    extent = panel(ax, run)
                except (OSError, ValueError, IndexError, KeyError) as e:
                    extent = None
                    ax.text(0.5, 0.5, f"unreadable: {e}", transform=ax.transAxes, ha="center",
                            fontsize=8)
                if extent:
                    extents.append((ax, extent))
                title += f" ({mode})"
            ax.set_title(title, fontsize=9)
    if extents:  # one scale for every panel
        x0 = min(e[0] for _, e in extents) - 2
        x1 = max(e[1] for _, e in extents) + 2
        y0 = min(e[2] for _, e in extents) - 2
        y1 = max(e[3] for _, e in extents) + 2
        for ax in axes.flat:
            ax.set_xlim(x0, x1)
            ax.set_ylim(y0, y1)
            ax.set_aspect(Y_STRETCH)
            ax.tick_params(labelsize=7)
    for ax in axes[-1]:
        ax.set_xlabel("x east (m)", fontsize=8)
    for ax in axes[:, 0]:
        ax.set_ylabel("y north (m)", fontsize=8)
    fig.suptitle("Top-down trajectories: leaders solid, followers dashed, obstacles grey "
                 f"(y axis stretched x{Y_STRETCH:g})", fontsize=10)
    fig.tight_layout()
    ef.save_small(fig, out / "trajectories.png", dpi=90)
    plt.close(fig)


def main():
    if len(sys.argv) != 2:
        sys.exit("usage: tools/convoy_suite_figures.py SUITE_DIR")
    out = pathlib.Path(sys.argv[1])
    if not out.is_dir():
        sys.exit(f"convoy_suite_figures: {out} is not a directory")
    figure(out)
    table = out / "convoy_suite.md"
    text = table.read_text() if table.exists() else ""
    if LINE not in text:
        table.write_text(text + ("\n" if text and not text.endswith("\n\n") else "") + LINE + "\n")
    print(f"convoy_suite_figures: {out / 'trajectories.png'}")


if __name__ == "__main__":
    main()
