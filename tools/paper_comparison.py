#!/usr/bin/python3
"""The paper's statements about its statistical study, checked against an ensemble directory
written by launch_scripts/run_ensemble.sh.

    tools/paper_comparison.py DIR

Reads DIR/ensemble.csv, DIR/runs.csv, DIR/ensemble.setup, DIR/courses/<seed>_<terrain>.yaml and
the runs' vehicles.csv, metrics_samples.csv and summary.json; writes DIR/paper_comparison.md: a
header (ensemble, protocol, follower, courses) and one table row per statement of the paper
("Enabling Artificial Intelligence Studies in Off-Road Mobility Through Physics-Based Simulation
of Multiagent Scenarios", J. Comput. Inf. Sci. Eng. 22 (2022), DOI 10.1115/1.4053321, Sec. 4.2
and 5): the statement, the paper's value, this ensemble's value, a verdict computed here
(`holds`, `differs`, `partly (k of n)` or `not measured`) and the rule that gave it.
tools/ensemble_figures.py calls write() after its figures, passing the vehicles.csv tracks it has
already read (one pass per file); run alone, this reads them itself.
Needs Debian's python3-numpy (and python3-matplotlib, through tools/ensemble_figures.py).
"""
import json
import pathlib
import re
import sys
from collections import defaultdict

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
sys.dont_write_bytecode = True  # no __pycache__ in tools/
import ensemble_figures as ef  # noqa: E402

PAPER = ("\"Enabling Artificial Intelligence Studies in Off-Road Mobility Through Physics-Based "
         "Simulation of Multiagent Scenarios\", J. Comput. Inf. Sci. Eng. 22 (2022), "
         "DOI 10.1115/1.4053321")
RIGID, HARD, SOFT = "rigid", "scm_hard", "scm_soft"
POSITIONS = (1, 2, 3)
# The paper's example course (rigid terrain, follower 3; Figs. 13, 14 and 19).
EXAMPLE = [("m_p_avg", 0.473, 1, "m", "Fig. 13"), ("m_p_max", 2.484, 1, "m", "Fig. 13"),
           ("m_as_avg", 0.505, 1, "m/s", "Fig. 14"), ("m_as_max", 2.154, 1, "m/s", "Fig. 14"),
           ("m_rs_avg", 12.2, 100, "%", "Fig. 14"), ("m_rs_max", 69.2, 100, "%", "Fig. 14"),
           ("segment_length_m", 158.2, 1, "m", "Fig. 19")]
PAPER_COURSES = 128
PAPER_RAMP_MPS2 = 0.47  # the leader's target speed ramp (Sec. 4.2)
OCCASIONALLY = 0.20  # "occasionally": at most this share of follower runs hit an obstacle
ALWAYS = 0.90  # "always": in at least this share of the runs
TIGHT_PERCENTILE = 75  # a "tight turn": the path's curvature at or above this percentile
CURVATURE_STEP_M, CURVATURE_WINDOW_M = 0.5, 5.0
TURN_REACH_M = 5.0  # a deviation is "at" a turn within this distance along the path
SPEED_SKIP_M = 10.0  # the paper's start from rest, left out of the speed metrics
RAMP_TOLERANCE = 0.10
CLEARANCE_M = 2.0  # the paper: 2 m between the path's centreline and every obstacle
SPEED_LINE = re.compile(r"speed: \{[^}]*\}")


class NotMeasured(Exception):
    """A statement this ensemble's data cannot check (the reason)."""


def verdict(k, n):
    if n == 0:
        raise NotMeasured("nothing to compare")
    return "holds" if k == n else "differs" if k == 0 else f"partly ({k} of {n})"


def number(value):
    return f"{value:#.3g}".rstrip(".") if abs(value) < 100 else f"{value:.1f}"


def metric_values(rows, terrain, position, key, scale=1.0):
    return [scale * float(r[key]) for r in rows if r["terrain"] == terrain and r["position"]
            and int(r["position"]) == position and r.get(key) not in (None, "", "nan", "null")]


def median(rows, terrain, position, key):
    values = metric_values(rows, terrain, position, key)
    if not values:
        raise NotMeasured(f"no {key} on {terrain} for follower {position}")
    return float(np.median(values))


def need_terrains(rows, *terrains):
    missing = [t for t in terrains if t not in {r["terrain"] for r in rows}]
    if missing:
        raise NotMeasured(f"no completed run on {', '.join(missing)}")


def need_positions(rows):
    present = {int(r["position"]) for r in rows if r["position"]}
    if not set(POSITIONS) <= present:
        raise NotMeasured(f"follower positions {sorted(present)}: needs 1, 2 and 3")


def grows_with_position(rows, key):
    need_positions(rows)
    terrains = [t for t in ef.terrains_of(rows)]
    if not terrains:
        raise NotMeasured("no completed run")
    parts, k = [], 0
    for terrain in terrains:
        m = [median(rows, terrain, p, key) for p in POSITIONS]
        ok = all(a < b for a, b in zip(m, m[1:]))
        k += ok
        parts.append(f"{terrain} {' / '.join(number(v) for v in m)} ({'yes' if ok else 'no'})")
    return "; ".join(parts), verdict(k, len(terrains))


def below(rows, key, lower, upper):
    """Per follower position: median on terrain `lower` < median on terrain `upper`."""
    need_terrains(rows, lower, upper)
    need_positions(rows)
    parts, k = [], 0
    for p in POSITIONS:
        a, b = median(rows, lower, p, key), median(rows, upper, p, key)
        k += a < b
        parts.append(f"{p}: {number(a)} vs {number(b)} ({'yes' if a < b else 'no'})")
    return "; ".join(parts), verdict(k, len(POSITIONS))


def leader_order(rows, key):
    need_terrains(rows, RIGID, HARD, SOFT)
    heads = ef.leader_runs(rows)
    m = {t: float(np.median([float(r[key]) for r in heads if r["terrain"] == t]))
         for t in (RIGID, HARD, SOFT)}
    k = (m[RIGID] > m[HARD]) + (m[HARD] > m[SOFT])
    return (f"rigid {m[RIGID]:.2f}, SCM hard {m[HARD]:.2f}, SCM soft {m[SOFT]:.2f} m/s "
            f"(median of {len(heads)} leader runs)"), verdict(k, 2)


def gear_medians(highest):
    need = [t for t in (RIGID, HARD, SOFT) if not highest.get(t)]
    if need:
        raise NotMeasured(f"no leader track (vehicles.csv) on {', '.join(need)}")
    m = {t: float(np.median(highest[t])) for t in (RIGID, HARD, SOFT)}
    k = (m[HARD] < m[RIGID]) + (m[SOFT] < m[RIGID]) + (m[SOFT] <= m[HARD])
    return f"rigid {m[RIGID]:g}, SCM hard {m[HARD]:g}, SCM soft {m[SOFT]:g}", verdict(k, 3)


def gear_distributions(highest):
    need = [t for t in (RIGID, HARD, SOFT) if not highest.get(t)]
    if need:
        raise NotMeasured(f"no leader track (vehicles.csv) on {', '.join(need)}")
    gears = sorted({g for t in (RIGID, HARD, SOFT) for g in highest[t]})
    reach = {t: np.array([np.mean(np.array(highest[t]) >= g) for g in gears])
             for t in (RIGID, HARD, SOFT)}

    def below(a, b):  # a's highest gears lower: P(a >= g) <= P(b >= g) for all g, once strictly
        return bool(np.all(reach[a] <= reach[b]) and np.any(reach[a] < reach[b]))
    k = below(HARD, RIGID) + below(SOFT, HARD)
    shares = "; ".join(f"{t}: " + ", ".join(f"gear {g} {100 * highest[t].count(g) / len(highest[t]):.0f} %"
                                             for g in gears if g in highest[t])
                       for t in (RIGID, HARD, SOFT))
    return shares, verdict(k, 2)


def hit_cells(rows):
    need_terrains(rows, RIGID, HARD, SOFT)
    need_positions(rows)
    return {(t, p): sum(int(r["obstacles_hit"]) for r in rows if r["terrain"] == t
                        and r["position"] and int(r["position"]) == p)
            for t in (RIGID, HARD, SOFT) for p in POSITIONS}


def hits_text(cells):
    return "; ".join(f"{t} " + " / ".join(str(cells[(t, p)]) for p in POSITIONS)
                     for t in (RIGID, HARD, SOFT))


def worst_cell(rows):
    cells = hit_cells(rows)
    worst = max(cells.values())
    top = [c for c, v in cells.items() if v == worst]
    ok = top == [(HARD, 3)]
    return (f"{hits_text(cells)} (followers 1 / 2 / 3); most: "
            f"{', '.join(f'{t} {p}' for t, p in top)} ({worst})"), "holds" if ok else "differs"


def hits_grow(rows):
    cells = hit_cells(rows)
    k = sum(cells[(t, 1)] <= cells[(t, 2)] <= cells[(t, 3)] and cells[(t, 1)] < cells[(t, 3)]
            for t in (RIGID, HARD, SOFT))
    return hits_text(cells) + " (followers 1 / 2 / 3)", verdict(k, 3)


def occasional_hits(rows):
    if not rows:
        raise NotMeasured("no completed run")
    hit = sum(int(r["obstacles_hit"]) > 0 for r in rows)
    share = hit / len(rows)
    by_position = ", ".join(
        f"{p}: {sum(int(r['obstacles_hit']) > 0 for r in rows if int(r['position']) == p)}"
        for p in sorted({int(r["position"]) for r in rows if r["position"]}))
    return (f"{hit} of {len(rows)} follower runs ({100 * share:.1f} %; by position {by_position})",
            "holds" if 0 < share <= OCCASIONALLY else "differs")


def leader_collisions(out, runs):
    done = [r for r in runs if r["status"] == "completed"]
    counted, hit = 0, []
    for run in done:
        run_id = f"{run['seed']}_{run['terrain']}"
        try:
            summary = json.loads((out / "runs" / run_id / "summary.json").read_text())
        except (OSError, ValueError):
            continue
        followers = {c.get("follower") for c in summary.get("convoy", [])}
        leaders = [v for v in summary.get("vehicles", []) if v.get("id") not in followers]
        if not leaders:
            continue
        counted += 1
        if any(v.get("collisions", 0) for v in leaders):
            hit.append(run_id)
    if not counted:
        raise NotMeasured("no summary.json")
    return (f"{len(hit)} of {counted} runs with a leader collision"
            + (f" ({', '.join(hit[:5])}{', ...' if len(hit) > 5 else ''})" if hit else "")), \
        verdict(counted - len(hit), counted)


def curvature_along(x, y):
    """A driven track's turns every CURVATURE_STEP_M of its arc length from its first point:
    (arc, the largest |curvature| (1/m) within TURN_REACH_M either side), the curvature being the
    heading's rate averaged over CURVATURE_WINDOW_M."""
    step = np.hypot(np.diff(x), np.diff(y))
    moving = np.concatenate([[True], step > 1e-6])
    arc = np.concatenate([[0.0], np.cumsum(step)])[moving]
    x, y = x[moving], y[moving]
    if len(arc) < 3 or arc[-1] < 2 * CURVATURE_WINDOW_M:
        return None
    grid = np.arange(0.0, arc[-1], CURVATURE_STEP_M)
    gx, gy = np.interp(grid, arc, x), np.interp(grid, arc, y)
    heading = np.unwrap(np.arctan2(np.gradient(gy), np.gradient(gx)))
    rate = np.gradient(heading, CURVATURE_STEP_M)
    width = max(1, int(round(CURVATURE_WINDOW_M / CURVATURE_STEP_M)))
    kernel = np.ones(width)
    smooth = np.abs(np.convolve(rate, kernel, "same") /
                    np.convolve(np.ones_like(rate), kernel, "same"))
    # A turn's curvature at each point: the largest within TURN_REACH_M either side.
    reach = int(round(TURN_REACH_M / CURVATURE_STEP_M))
    padded = np.pad(smooth, reach, mode="edge")
    turn = np.max(np.lib.stride_tricks.sliding_window_view(padded, 2 * reach + 1), axis=1)
    return grid, turn


def metrics_samples(out, runs, cache):
    """{run_id: rows of metrics_samples.csv} of the completed runs (read once into cache)."""
    key = "metrics_samples"
    if key not in cache:
        found = {}
        for run in runs:
            run_id = f"{run['seed']}_{run['terrain']}"
            if run["status"] == "completed":
                try:
                    found[run_id] = ef.read_csv(out / "runs" / run_id / "metrics_samples.csv")
                except OSError:
                    pass
        cache[key] = found
    return cache[key]


def deviation_at_turns(out, runs, tracks, cache, inner=False):
    """For each follower run: is the leader's path curvature where the follower's path deviation
    is largest (metrics_samples.csv) above the TIGHT_PERCENTILE of the curvature over the
    common segment? inner: both only over the segment less SPEED_SKIP_M at either end."""
    k = n = at_ends = 0
    at_max, overall = [], []
    for run_id, samples in metrics_samples(out, runs, cache).items():
        if run_id not in tracks:
            continue
        by_follower = defaultdict(list)
        for s in samples:
            by_follower[(s["follower"], s["leader"])].append((float(s["arc_m"]), float(s["path_m"])))
        for (follower, leader), pairs in by_follower.items():
            lead = tracks[run_id]["leaders"].get(leader)
            curve = curvature_along(lead["x"], lead["y"]) if lead is not None else None
            if curve is None or len(pairs) < 2:
                continue
            arcs, devs = np.array(pairs).T
            lo, hi = arcs.min(), arcs.max()
            if inner:
                lo, hi = lo + SPEED_SKIP_M, hi - SPEED_SKIP_M
                keep = (arcs >= lo) & (arcs <= hi)
                if not keep.any():
                    continue
                arcs, devs = arcs[keep], devs[keep]
            where = arcs[int(np.argmax(devs))]
            grid, kappa = curve
            inside = kappa[(grid >= lo) & (grid <= hi)]
            if not len(inside):
                continue
            here = float(np.interp(where, grid, kappa))
            n += 1
            k += here > np.percentile(inside, TIGHT_PERCENTILE)
            at_ends += where - arcs.min() < SPEED_SKIP_M or arcs.max() - where < SPEED_SKIP_M
            at_max.append(here)
            overall.append(float(np.median(inside)))
    if not n:
        raise NotMeasured("no metrics_samples.csv with a leader track")
    share = k / n
    text = (f"{k} of {n} follower runs ({100 * share:.0f} %); curvature at the largest deviation "
            f"median {np.median(at_max):.3f} 1/m (radius {1 / max(np.median(at_max), 1e-9):.0f} m) "
            f"vs the paths' median {np.median(overall):.3f} 1/m (radius "
            f"{1 / max(np.median(overall), 1e-9):.0f} m)")
    if not inner:
        text += f"; {at_ends} of the maxima within {SPEED_SKIP_M:g} m of the segment's ends"
    result = ("holds" if share >= ALWAYS else "differs" if share <= 1 - TIGHT_PERCENTILE / 100
              else f"partly ({k} of {n})")
    return text, result


def example_value(rows, key, paper, scale, unit):
    need_terrains(rows, RIGID)
    values = metric_values(rows, RIGID, 3, key, scale)
    if not values:
        raise NotMeasured(f"no {key} for follower 3 on rigid")
    lo, mid, hi = np.percentile(values, [5, 50, 95])
    return (f"median {number(mid)} {unit}, 5-95 % {number(lo)}..{number(hi)} {unit} "
            f"({len(values)} runs)"), "holds" if lo <= paper <= hi else "differs"


def study_design(rows, runs):
    terrains = sorted({r["terrain"] for r in runs})
    seeds = {t: {r["seed"] for r in runs if r["terrain"] == t} for t in terrains}
    completed = sum(r["status"] == "completed" for r in runs)
    convoys = sorted({r["convoy"] for r in rows})
    counts = {len(s) for s in seeds.values()}
    checks = [set(terrains) == {RIGID, HARD, SOFT},
              len({frozenset(s) for s in seeds.values()}) == 1,
              counts == {PAPER_COURSES},
              completed == len(runs),
              convoys == ["1L3F"]]
    text = (f"{', '.join(f'{t} {len(seeds[t])}' for t in terrains)} courses; "
            f"{completed} of {len(runs)} runs completed; same seeds on every terrain: "
            f"{'yes' if checks[1] else 'no'}; convoy {', '.join(convoys) or '-'}")
    return text, verdict(sum(checks), len(checks))


def course_texts(out, runs):
    texts = {}
    for run in runs:
        text = ef.course_scenario(out, run["seed"], run["terrain"])
        if text:
            texts[(run["seed"], run["terrain"])] = text
    if not texts:
        raise NotMeasured("no courses/*.yaml")
    return texts


def one_per_seed(texts):
    by_seed = {}
    for (seed, terrain), text in sorted(texts.items()):
        by_seed.setdefault(seed, text)
    return by_seed


def fixed_obstacles(out, runs):
    courses = one_per_seed(course_texts(out, runs))
    fields = [ef.obstacles_of(t) for t in courses.values()]
    common = set.intersection(*[{(x, y) for x, y, _ in f} for f in fields])
    sizes = sorted({len(f) for f in fields})
    random_r = [r for f in fields for x, y, r in f if (x, y) not in common]
    fixed = sorted(common)
    along = [(x + y) / np.sqrt(2) for x, y in fixed]
    checks = [sizes == [34], len(fixed) == 4,
              bool(fixed) and all(abs(x - y) < 1e-6 for x, y in fixed),
              len(fixed) > 2 and float(np.ptp(np.diff(along))) < 1e-6]
    fixed_r = sorted({r for f in fields for x, y, r in f if (x, y) in common})
    text = (f"{', '.join(map(str, sizes))} obstacles per course ({len(courses)} courses); "
            f"{len(fixed)} in every course at {', '.join(f'({x:g}, {y:g})' for x, y in fixed)}, "
            f"radius {', '.join(f'{r:g}' for r in fixed_r[:4])}{'...' if len(fixed_r) > 4 else ''} m; "
            f"the others' radius {min(random_r, default=0):.2f}..{max(random_r, default=0):.2f} m")
    return text, verdict(sum(checks), len(checks))


def segment_distance(points, cx, cy):
    p = np.asarray(points, float)
    a, b = p[:-1], p[1:]
    d = b - a
    length2 = np.maximum((d ** 2).sum(axis=1), 1e-12)
    t = np.clip(((cx - a[:, 0]) * d[:, 0] + (cy - a[:, 1]) * d[:, 1]) / length2, 0, 1)
    return float(np.min(np.hypot(a[:, 0] + t * d[:, 0] - cx, a[:, 1] + t * d[:, 1] - cy)))


def path_clearance(out, runs):
    texts = course_texts(out, runs)
    clearances = []
    for text in texts.values():
        path = ef.planned_path(text)
        if path and len(path) > 1:
            clearances.append(min((segment_distance(path, x, y) - r
                                   for x, y, r in ef.obstacles_of(text)), default=np.inf))
    if not clearances:
        raise NotMeasured("no planned path in the courses")
    k = sum(c >= CLEARANCE_M - 1e-3 for c in clearances)
    return (f"smallest clearance {min(clearances):.2f} m, median {np.median(clearances):.2f} m "
            f"({len(clearances)} scenarios)"), verdict(k, len(clearances))


def path_in_domain(out, runs):
    courses = one_per_seed(course_texts(out, runs))
    paths = [ef.planned_path(t) for t in courses.values()]
    paths = [p for p in paths if p]
    if not paths:
        raise NotMeasured("no planned path in the courses")
    k = sum(all(0 <= x <= 100 and 0 <= y <= 100 for x, y in p) for p in paths)
    ends = sorted({(p[0], p[-1]) for p in paths})
    return (f"{k} of {len(paths)} paths inside [0, 100] m x [0, 100] m; from "
            f"{', '.join(f'{a} to {b}' for a, b in ends[:2])}"), verdict(k, len(paths))


def same_speed_profile(out, runs):
    texts = course_texts(out, runs)
    by_seed = defaultdict(set)
    for (seed, terrain), text in texts.items():
        found = SPEED_LINE.search(text)
        by_seed[seed].add(found.group(0) if found else None)
    k = sum(len(v) == 1 for v in by_seed.values())
    profiles = sorted({p for v in by_seed.values() for p in v if p})
    return (f"{k} of {len(by_seed)} courses with one leader speed setting on all their terrains: "
            f"{'; '.join(f'`{p}`' for p in profiles[:2])}"), verdict(k, len(by_seed))


def ramp_acceleration(tracks):
    rates = []
    for run_id, track in tracks.items():
        if run_id.split("_", 1)[1] != RIGID:
            continue
        for lead in track["leaders"].values():
            top = lead["speed"].max()
            lo, hi = 0.2 * top, 0.8 * top
            i_lo, i_hi = np.argmax(lead["speed"] >= lo), np.argmax(lead["speed"] >= hi)
            if top > 1 and lead["t"][i_hi] > lead["t"][i_lo]:
                rates.append((hi - lo) / (lead["t"][i_hi] - lead["t"][i_lo]))
    if not rates:
        raise NotMeasured("no leader track (vehicles.csv) on rigid")
    m = float(np.median(rates))
    return (f"median {m:.3f} m/s2 over {len(rates)} rigid runs (5-95 % "
            f"{np.percentile(rates, 5):.3f}..{np.percentile(rates, 95):.3f})"), \
        "holds" if abs(m - PAPER_RAMP_MPS2) <= RAMP_TOLERANCE * PAPER_RAMP_MPS2 else "differs"


def speed_noise(out, runs, cache):
    """Per terrain and position: the median over runs of the RMS of the follower's speed about
    its own 5 m moving average (metrics_samples.csv, from 10 m on)."""
    noise = defaultdict(list)
    for run_id, samples in metrics_samples(out, runs, cache).items():
        terrain = run_id.split("_", 1)[1]
        if terrain not in (HARD, SOFT):
            continue
        by_follower = defaultdict(list)
        for s in samples:
            if float(s["arc_m"]) >= SPEED_SKIP_M:
                by_follower[int(s["position"])].append(float(s["follower_speed_mps"]))
        kernel = np.ones(int(round(CURVATURE_WINDOW_M / CURVATURE_STEP_M)))
        for position, v in by_follower.items():
            v = np.array(v)
            if len(v) < 2 * len(kernel):
                continue
            mean = np.convolve(v, kernel, "same") / np.convolve(np.ones_like(v), kernel, "same")
            noise[(terrain, position)].append(float(np.sqrt(np.mean((v - mean) ** 2))))
    missing = [f"{t} {p}" for t in (HARD, SOFT) for p in POSITIONS if not noise[(t, p)]]
    if missing:
        raise NotMeasured(f"no metrics_samples.csv for {', '.join(missing)}")
    parts, k = [], 0
    for p in POSITIONS:
        s, h = np.median(noise[(SOFT, p)]), np.median(noise[(HARD, p)])
        k += s < h
        parts.append(f"{p}: {s:.3f} vs {h:.3f} m/s ({'yes' if s < h else 'no'})")
    return "; ".join(parts), verdict(k, len(POSITIONS))


def statements(out, rows, runs, tracks):
    """[(id, statement, paper's value, rule, function returning (ours, verdict))]."""
    labels = dict(ef.METRICS)
    highest, _ = ef.leader_gear_stats(tracks)
    cache = {}  # files more than one statement reads
    s = []
    for key in ("m_p_avg", "m_p_max", "m_as_avg", "m_rs_avg"):
        s.append((f"a.{key}", "\"worse performance for the trailing follower vehicles\" "
                  f"(Sec. 5; Figs. 15-17): {labels[key]}",
                  "worse from follower 1 to 3 on each terrain",
                  "median over the courses strictly increasing with position 1 < 2 < 3; "
                  "k of the terrains run",
                  lambda key=key: grows_with_position(rows, key)))
    for key in ("m_p_avg", "m_as_avg", "m_rs_avg"):
        s.append((f"b.{key}", "\"better performance on harder surfaces\" (Sec. 5; Figs. 15-17): "
                  f"{labels[key]}, rigid vs SCM hard",
                  "rigid lower than SCM hard",
                  "median on rigid < median on SCM hard, per follower position (k of 3)",
                  lambda key=key: below(rows, key, RIGID, HARD)))
    for key in ("m_p_avg", "m_p_max", "m_as_avg", "m_rs_avg"):
        s.append((f"c.{key}", "\"SCM-Soft showing consistent lower metrics values\" than SCM-Hard "
                  f"(Sec. 4.2; Figs. 15-17): {labels[key]}",
                  "SCM soft lower than SCM hard",
                  "median on SCM soft < median on SCM hard, per follower position (k of 3)",
                  lambda key=key: below(rows, key, SOFT, HARD)))
    s.append(("d.max_speed", "On deformable soil the leader was \"unable to continuously increase "
              "its speed to the specified value\", more so on SCM-Soft (Sec. 4.2)",
              "leader speed rigid > SCM hard > SCM soft",
              "median of the leaders' fastest frame: rigid > SCM hard and SCM hard > SCM soft "
              "(k of 2)", lambda: leader_order(rows, "leader_max_speed_mps")))
    s.append(("d.mean_speed", "\"The ensuing overall lower convoy speed\" on deformable soil "
              "(Sec. 4.2)", "convoy slower on SCM hard, slowest on SCM soft",
              "median of the leaders' mean speed while moving: rigid > SCM hard and SCM hard > "
              "SCM soft (k of 2)", lambda: leader_order(rows, "leader_mean_speed_mps")))
    s.append(("e.gear_median", "\"On both deformable terrain types, the vehicles were unable to "
              "shift in the higher gears ... more pronounced on SCM-Soft\" (Sec. 4.2)",
              "highest gear lower on SCM hard and SCM soft than on rigid, lowest on soft",
              "median over the runs of the leader's highest gear (vehicles.csv): hard < rigid, "
              "soft < rigid, soft <= hard (k of 3)", lambda: gear_medians(highest)))
    s.append(("e.gear_share", "The same, as the distribution of the leader's highest gear "
              "(Sec. 4.2)", "fewer runs reach the higher gears on hard, fewer still on soft",
              "share of runs reaching gear g or higher, for every g: SCM hard <= rigid and "
              "SCM soft <= SCM hard, each lower for some g (k of 2)",
              lambda: gear_distributions(highest)))
    s.append(("f.worst_cell", "\"the trailing follower on SCM-Hard terrain exhibiting worst "
              "performance\" in obstacles hit (Fig. 20)", "most hits: SCM hard, follower 3",
              "obstacles hit summed over the courses: the (SCM hard, 3) cell strictly above the "
              "other 8", lambda: worst_cell(rows)))
    s.append(("g.hits_trend", "Obstacles hit show \"the same relative performance trends\" "
              "(Fig. 20)", "more hits further back in the convoy",
              "per terrain: hits(1) <= hits(2) <= hits(3) and hits(1) < hits(3) (k of 3)",
              lambda: hits_grow(rows)))
    s.append(("h.occasional", "Followers \"occasionally are unable to avoid an obstacle\" "
              "(Sec. 4.2)", "occasionally",
              f"share of follower runs with >= 1 obstacle hit in (0, {100 * OCCASIONALLY:.0f} %]",
              lambda: occasional_hits(rows)))
    s.append(("h.leader", "\"a leader vehicle always avoids obstacles\" (Sec. 4.2)",
              "no leader collision", "no collision of a leader in any completed run "
              "(summary.json; k of the runs without one)",
              lambda: leader_collisions(out, runs)))
    s.append(("i.tight_turns", "\"The largest deviations in a follower's path always occur at "
              "tight turns where the leader vehicle must go around an obstacle\" (Sec. 4.2, "
              "Fig. 19)", "always",
              f"per follower run: the leader's driven-path curvature ({CURVATURE_WINDOW_M:g} m "
              f"average, largest within {TURN_REACH_M:g} m; vehicles.csv) at the arc of the "
              "largest path_m (metrics_samples.csv) above the "
              f"{TIGHT_PERCENTILE}th percentile of the same over the common segment; holds if in >= "
              f"{100 * ALWAYS:.0f} % of the runs, differs if <= {100 - TIGHT_PERCENTILE} % "
              "(chance)", lambda: deviation_at_turns(out, runs, tracks, cache)))
    s.append(("i.tight_turns_inner", "The same, leaving out the first and last "
              f"{SPEED_SKIP_M:g} m of the common segment (start from rest, stop behind the "
              "leader)", "always", "as above, the largest deviation and the percentile both "
              f"over the segment less {SPEED_SKIP_M:g} m at either end",
              lambda: deviation_at_turns(out, runs, tracks, cache, inner=True)))
    s.append(("i.speed_noise", "\"spurious accelerations and decelerations are less pronounced "
              "on the SCM-Soft\" (Sec. 4.2)", "follower speed less noisy on SCM soft than hard",
              f"median RMS of the follower's speed about its {CURVATURE_WINDOW_M:g} m moving "
              f"average (metrics_samples.csv, from {SPEED_SKIP_M:g} m): soft < hard per position "
              "(k of 3)", lambda: speed_noise(out, runs, cache)))
    for key, paper, scale, unit, figure in EXAMPLE:
        s.append((f"j.{key}", f"The paper's example course, rigid, follower 3 ({figure}): {key}",
                  f"{paper:g} {unit}", "the paper's value within our rigid follower-3 5-95 % "
                  "range", lambda key=key, paper=paper, scale=scale, unit=unit:
                  example_value(rows, key, paper, scale, unit)))
    s.append(("k.design", "128 courses on each of the three terrains, \"each one of the three "
              "sets of 128 simulations used the same set of randomly generated trajectories\", "
              "all 1L+3F (Sec. 4.2)", "128 x 3, same courses, 1L+3F",
              "terrains rigid, SCM hard, SCM soft; the same seeds on each; 128 courses; every "
              "run completed; convoy 1L3F (k of 5)", lambda: study_design(rows, runs)))
    s.append(("k.obstacles", "\"30 randomly placed circular obstacles\" and \"four additional "
              "fixed obstacles with radius of 8 m placed equidistantly along the diagonal\" "
              "(Sec. 4.2, Fig. 11)", "34 per course, 4 fixed on the diagonal",
              "from courses/*.yaml: 34 obstacles per course; 4 at the same place in every "
              "course; those on the diagonal x = y; equally spaced (k of 4)",
              lambda: fixed_obstacles(out, runs)))
    s.append(("k.clearance", "The path leaves \"2 m ... of separation from the generated path "
              "centerline\" to every obstacle (Sec. 4.2)", f"{CLEARANCE_M:g} m",
              "planned waypoints' polyline to every obstacle circle >= 2 m (1 mm tolerance), "
              "per scenario", lambda: path_clearance(out, runs)))
    s.append(("k.domain", "The PSO paths run from the south-west to the north-east corner and "
              "\"remained in the domain\" (Sec. 4.2, Fig. 12)", "inside 100 m x 100 m",
              "every planned waypoint inside [0, 100] m x [0, 100] m, per course",
              lambda: path_in_domain(out, runs)))
    s.append(("k.speed_setting", "\"the target speed profile for the leader vehicle was set "
              "identically for all three terrain types\" (Sec. 4.2)", "identical",
              "the first leader's `speed:` setting the same in a course's scenarios on every "
              "terrain, per course", lambda: same_speed_profile(out, runs)))
    s.append(("k.ramp", "The leader's target speed increases linearly in time, \"a constant "
              "acceleration of 0.47 m/s²\" (Sec. 4.2)", f"{PAPER_RAMP_MPS2} m/s2",
              "rigid leaders' speed gain from 20 % to 80 % of their fastest frame over the time "
              f"it took (vehicles.csv), median within {100 * RAMP_TOLERANCE:.0f} % of 0.47",
              lambda: ramp_acceleration(tracks)))
    return s


def read_setup(out):
    try:
        words = (out / "ensemble.setup").read_text().split()
    except OSError:
        return {}
    return dict(w.split("=", 1) for w in words if "=" in w)


def compare(out, rows=None, runs=None, tracks=None):
    """[{id, statement, paper, ours, verdict, rule}] for an ensemble directory."""
    out = pathlib.Path(out)
    if rows is None:
        rows = [r for r in ef.read_csv(out / "ensemble.csv") if r["status"] == "completed"]
    if runs is None:
        runs = ef.read_csv(out / "runs.csv")
    if tracks is None:
        tracks = ef.read_tracks(out, rows, runs)
    results = []
    for key, statement, paper, rule, measure in statements(out, rows, runs, tracks):
        try:
            ours, result = measure()
        except NotMeasured as e:
            ours, result = f"not measured: {e}", "not measured"
        results.append({"id": key, "statement": statement, "paper": paper, "ours": ours,
                        "verdict": result, "rule": rule})
    return results


def write(out, rows=None, runs=None, tracks=None):
    out = pathlib.Path(out)
    if runs is None:
        runs = ef.read_csv(out / "runs.csv")
    results = compare(out, rows, runs, tracks)
    setup = read_setup(out)
    policy = setup.get("follower_policy", "classical")
    seeds = sorted({int(r["seed"]) for r in runs})
    counts = defaultdict(int)
    for r in results:
        counts[r["verdict"].split(" (")[0]] += 1
    lines = [f"# {out.resolve().name}: the paper's statistical study, statement by statement", "",
             f"- Ensemble: `{out.resolve().name}`, protocol {setup.get('protocol', 'current')}, "
             f"convoy {setup.get('convoy', '-')}, {len(seeds)} courses, {len(runs)} runs "
             f"({sum(r['status'] == 'completed' for r in runs)} completed).",
             f"- Followers: {'the classical follower controller' if policy == 'classical' else f'the learned policy `{policy}`'}.",
             f"- Paper: {PAPER}; its followers are its learned (RL) policy."
             + (" Ours here are the classical controller: this compares trends, not a policy."
                if policy == "classical" else
                " Ours is another learned policy: this compares trends, not the same policy."),
             "- Verdicts are computed by tools/paper_comparison.py from ensemble.csv, runs.csv, "
             "the runs' vehicles.csv, metrics_samples.csv and summary.json and the courses' "
             "scenarios, by the rule in the last column: `holds`, `differs`, `partly (k of n)` "
             "(k of the n cases the rule names), or `not measured` (the reason in the value).",
             "- Tally: " + ", ".join(f"{v} {k}" for k, v in counts.items()) + ".", "",
             "| # | the paper's statement | paper | this ensemble | verdict | rule |",
             "|---|---|---|---|---|---|"]
    for r in results:
        cells = [r["id"], r["statement"], r["paper"], r["ours"], f"**{r['verdict']}**", r["rule"]]
        lines.append("| " + " | ".join(c.replace("|", "/") for c in cells) + " |")
    (out / "paper_comparison.md").write_text("\n".join(lines) + "\n")
    return results


def main():
    if len(sys.argv) != 2:
        sys.exit("usage: tools/paper_comparison.py ENSEMBLE_DIR")
    out = pathlib.Path(sys.argv[1])
    try:
        write(out)
    except OSError as e:
        sys.exit(f"paper_comparison: {e}")
    print(f"paper_comparison: {out / 'paper_comparison.md'}")


if __name__ == "__main__":
    main()
