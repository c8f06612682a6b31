#!/usr/bin/env python3
"""Context switches and CPU time per thread of every running syndds process, over a window.

    tools/thread_profile.py [--after S] [--window S] [--frames-per-s F] [-- COMMAND ...]

Starts COMMAND (if given; e.g. tests/benchmarks/bench_scaling.sh ...), waits --after seconds,
reads /proc for every thread of every process whose name starts with "syndds_", waits
--window seconds, reads again and prints, per process kind and thread index (threads ordered
by id: 0 is the main thread, the others are created in a fixed order by Fast DDS and syndds),
the context switches (waits: the thread blocked; preempted: the scheduler took the CPU) and the CPU milliseconds per process, per
second of wall time, or per frame with --frames-per-s (frames per wall second, e.g. 100 / RTF
for a 0.01 s heartbeat). Which thread is which was read with gdb (`thread apply all bt`) on
Fast DDS 2.9.1: see docs/performance.md, "Where the wake-ups are".
"""
import argparse
import collections
import os
import re
import subprocess
import sys
import time


def snapshot():
    out = {}
    for pid in os.listdir('/proc'):
        if not pid.isdigit():
            continue
        try:
            kind = open(f'/proc/{pid}/comm').read().strip()
            if not kind.startswith('syndds_'):
                continue
            tids = os.listdir(f'/proc/{pid}/task')
        except OSError:
            continue
        for tid in tids:
            try:
                status = open(f'/proc/{pid}/task/{tid}/status').read()
                stat = open(f'/proc/{pid}/task/{tid}/stat').read().rsplit(')', 1)[1].split()
            except OSError:
                continue
            voluntary = int(re.search(r'^voluntary_ctxt_switches:\s+(\d+)', status, re.M)[1])
            forced = int(re.search(r'^nonvoluntary_ctxt_switches:\s+(\d+)', status, re.M)[1])
            ticks = int(stat[11]) + int(stat[12])  # utime + stime
            out[(int(pid), int(tid))] = (kind, voluntary, forced, ticks)
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    ap.add_argument('--after', type=float, default=15.0, help='seconds before the first reading')
    ap.add_argument('--window', type=float, default=5.0, help='seconds between the readings')
    ap.add_argument('--frames-per-s', type=float, default=0.0,
                    help='frames per wall second: report per frame instead of per second')
    ap.add_argument('command', nargs=argparse.REMAINDER)
    args = ap.parse_args()
    cmd = args.command[1:] if args.command[:1] == ['--'] else args.command
    child = subprocess.Popen(cmd) if cmd else None
    time.sleep(args.after)
    a = snapshot()
    t0 = time.monotonic()
    time.sleep(args.window)
    b = snapshot()
    elapsed = time.monotonic() - t0
    per = args.frames_per_s * elapsed if args.frames_per_s > 0 else elapsed
    unit = 'frame' if args.frames_per_s > 0 else 's'
    hz = os.sysconf('SC_CLK_TCK')

    threads = collections.defaultdict(list)
    for pid, tid in b:
        threads[pid].append(tid)
    rows = collections.defaultdict(lambda: [0, 0, 0, 0])  # voluntary, forced, ticks, processes
    for pid, tids in threads.items():
        for index, tid in enumerate(sorted(tids)):
            key = (pid, tid)
            if key not in a:
                continue
            kind = b[key][0]
            row = rows[(kind, index)]
            for i in range(3):
                row[i] += b[key][i + 1] - a[key][i + 1]
            row[3] += 1
    print(f'{"process":18s} {"thread":>6s} {"procs":>5s} {"waits/" + unit:>12s} '
          f'{"preempted/" + unit:>16s} {"CPU ms/" + unit:>14s}')
    for (kind, index), (voluntary, forced, ticks, n) in sorted(rows.items()):
        if voluntary + forced == 0 and ticks == 0:
            continue
        print(f'{kind:18s} {index:6d} {n:5d} {voluntary / per / n:12.2f} {forced / per / n:16.2f} '
              f'{ticks * 1000.0 / hz / per / n:14.3f}')
    if child:
        return child.wait()
    return 0


if __name__ == '__main__':
    sys.exit(main())
