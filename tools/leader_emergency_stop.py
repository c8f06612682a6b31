#!/usr/bin/env python3
"""The leader emergency-stop study: on each terrain, the leader_emergency_stop scenario
(tools/make_convoy_scenarios.py) with N stop times drawn at random (seeded: the same draw every
time), each run in one process (syndds_sim, byte-identical to a distributed run); then a table
of the follower's smallest bumper gap, when it happened, the time it spent below its standstill
gap and the contacts, per run and per terrain.

    tools/leader_emergency_stop.py --output DIR [--runs 20] [--terrains rigid,scm_hard,scm_soft]
        [--jobs 2] [--gap 'time_s: 1.0, standstill_bumper_m: 5'] [--build-dir build]
        [--radar] [--v2v 'rate_hz: 10, latency_s: 0.0, drop_probability: 0.5']

--radar gives the follower the convoy_radar rig and takes its gap from its forward radar
(controller radar: {sensor: front_radar}; docs/convoy.md "Radar gap"); --v2v replaces the
leader's V2V block (e.g. to drop messages).

Stop times: uniform in [3, 20] s (the ramp ends at 8 s), drawn by Python's random.Random with the
terrain's seed (201, 202, 203), rounded to whole frames (0.01 s). Runs go to
DIR/runs/<terrain>_<k>/, their scenarios to DIR/scenarios/; the table to DIR/table.md (and
stdout), one row per run in DIR/results.csv. A run passes when it completed, no collision event
was recorded (there are no obstacles: a collision is a vehicle contact) and the smallest
bumper gap is >= 1.0 m. Exit status 0 when every run passes, 2 otherwise, 1 bad command line.
"""
import argparse
import csv
import json
import pathlib
import random
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor

ROOT = pathlib.Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tools"))
import make_convoy_scenarios as gen  # noqa: E402

STOP_RANGE_S = (3.0, 20.0)
MIN_GAP_M = 1.0


def stop_times(terrain, runs):
    rng = random.Random(gen.STOP_SEEDS[terrain])
    return [round(rng.uniform(*STOP_RANGE_S), 2) for _ in range(runs)]


def leader_speed_at(run, time_s):
    """The leader's recorded speed in the frame of the stop (vehicles.csv)."""
    with open(run / "vehicles.csv") as f:
        for r in csv.DictReader(f):
            if r["vehicle"] == "l1" and float(r["time_s"]) >= time_s - 1e-9:
                return float(r["speed_mps"])
    return float("nan")


def contacts(run):
    with open(run / "events.csv") as f:
        return sum(1 for r in csv.DictReader(f) if r["kind"] == "collision")


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--output", required=True)
    p.add_argument("--runs", type=int, default=20)
    p.add_argument("--terrains", default="rigid,scm_hard,scm_soft")
    p.add_argument("--jobs", type=int, default=2)
    p.add_argument("--gap", default=None,
                   help="the follower's gap block instead of the generator's (YAML flow map)")
    p.add_argument("--build-dir", default=str(ROOT / "build"))
    p.add_argument("--radar", action="store_true",
                   help="the follower keeps its gap with its forward radar (convoy_radar rig)")
    p.add_argument("--v2v", default=None,
                   help="the leader's v2v block instead of the generator's (YAML flow map)")
    a = p.parse_args()
    terrains = a.terrains.split(",")
    for t in terrains:
        if t not in gen.STOP_TERRAINS:
            p.error(f"--terrains: unknown terrain '{t}' ({', '.join(gen.STOP_TERRAINS)})")
    if not 1 <= a.runs <= 1000:
        p.error("--runs must be 1..1000")
    sim = pathlib.Path(a.build_dir) / "bin" / "syndds_sim"
    if not sim.exists():
        p.error(f"{sim} is missing: build first")
    out = pathlib.Path(a.output)
    (out / "scenarios").mkdir(parents=True, exist_ok=True)
    (out / "runs").mkdir(parents=True, exist_ok=True)

    jobs = []
    for t in terrains:
        for k, stop in enumerate(stop_times(t, a.runs)):
            text = gen.emergency_stop(t, stop)
            if a.gap is not None:
                default = f"gap: {{time_s: 1.0, standstill_bumper_m: {gen.STANDSTILL_BUMPER_M:g}}}"
                text = text.replace(default, f"gap: {{{a.gap}}}")
            if a.v2v is not None:
                default = "v2v: {rate_hz: 10, latency_s: 0.0, drop_probability: 0.0}"
                assert default in text
                text = text.replace(default, f"v2v: {{{a.v2v}}}")
            if a.radar:
                head, follower = text.split("  - id: f1\n")
                follower = follower.replace("    sensors: convoy\n", "    sensors: convoy_radar\n")
                text = head + "  - id: f1\n" + follower + "      radar: {sensor: front_radar}\n"
            scenario = out / "scenarios" / f"{t}_{k}.yaml"
            scenario.write_text(text)
            jobs.append((t, k, stop, scenario, out / "runs" / f"{t}_{k}"))

    def run(job):
        t, k, stop, scenario, run_dir = job
        with open(str(run_dir) + ".log", "w") as log:
            code = subprocess.call([str(sim), str(scenario), "--output", str(run_dir),
                                    "--run-id", f"stop-{t}-{k}", "--quiet",
                                    "--config-dir", str(ROOT / "config")],
                                   stdout=log, stderr=subprocess.STDOUT)
        return job, code

    rows = []
    with ThreadPoolExecutor(max_workers=a.jobs) as pool:
        for (t, k, stop, scenario, run_dir), code in pool.map(run, jobs):
            row = {"terrain": t, "run": k, "stop_at_s": stop, "status": f"exit {code}"}
            try:
                s = json.loads((run_dir / "summary.json").read_text())
                f = s["convoy"][0]
                row.update(status=s["status"],
                           leader_speed_mps=leader_speed_at(run_dir, stop),
                           min_bumper_gap_m=f["bumper_gap_m"]["min"],
                           min_gap_time_s=f["min_bumper_gap_time_s"],
                           time_below_standstill_s=f["time_below_standstill_s"],
                           contacts=contacts(run_dir))
            except (OSError, ValueError, KeyError, IndexError):
                pass
            row["pass"] = (row["status"] == "completed" and row.get("contacts") == 0
                           and row.get("min_bumper_gap_m", 0.0) >= MIN_GAP_M)
            rows.append(row)
            print(f"leader_emergency_stop: {t} #{k} stop {stop:.2f} s: {row['status']}, "
                  f"smallest bumper gap {row.get('min_bumper_gap_m', float('nan')):.2f} m",
                  flush=True)

    columns = ["terrain", "run", "stop_at_s", "status", "leader_speed_mps", "min_bumper_gap_m",
               "min_gap_time_s", "time_below_standstill_s", "contacts", "pass"]
    with open(out / "results.csv", "w", newline="") as f:
        w = csv.DictWriter(f, columns, lineterminator="\n", extrasaction="ignore")
        w.writeheader()
        for r in rows:
            w.writerow({c: (f"{r[c]:.4g}" if isinstance(r.get(c), float) else r.get(c, ""))
                        for c in columns})

    num = lambda r, c, d: f"{r[c]:.{d}f}" if c in r else "-"  # noqa: E731
    lines = ["| terrain | run | stop at (s) | leader speed then (m/s) | smallest bumper gap (m) "
             "| at (s) | below standstill (s) | contacts | pass |",
             "|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['terrain']} | {r['run']} | {r['stop_at_s']:.2f} | "
                     f"{num(r, 'leader_speed_mps', 2)} | {num(r, 'min_bumper_gap_m', 2)} | "
                     f"{num(r, 'min_gap_time_s', 2)} | {num(r, 'time_below_standstill_s', 2)} | "
                     f"{r.get('contacts', '-')} | {'yes' if r['pass'] else 'NO'} |")
    lines += ["", "| terrain | runs | passed | smallest bumper gap (m) | median (m) | contacts |",
              "|---|---|---|---|---|---|"]
    for t in terrains:
        mine = [r for r in rows if r["terrain"] == t]
        gaps = sorted(r["min_bumper_gap_m"] for r in mine if "min_bumper_gap_m" in r)
        median = gaps[len(gaps) // 2] if len(gaps) % 2 else (
            (gaps[len(gaps) // 2 - 1] + gaps[len(gaps) // 2]) / 2 if gaps else float("nan"))
        lines.append(f"| {t} | {len(mine)} | {sum(r['pass'] for r in mine)} | "
                     f"{gaps[0] if gaps else float('nan'):.2f} | {median:.2f} | "
                     f"{sum(r.get('contacts', 0) for r in mine)} |")
    table = "\n".join(lines) + "\n"
    (out / "table.md").write_text(table)
    print(table)
    return 0 if all(r["pass"] for r in rows) else 2


if __name__ == "__main__":
    sys.exit(main())
