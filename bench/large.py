"""Thousands of robots: random to random at a given coverage, planned in auto mode.

Run ``python -m bench.large [--robots 5000 10000] [--coverage 0.1] [--time-limit 60]``.
For each count ``m`` the workspace is the square whose area makes the robots' discs
cover ``coverage`` of it (radius 1, margin 0.1, no obstacles); start and target are
scattered independently (Poisson-disc, every robot checked exactly), and
:func:`planner.plan` runs in auto mode with one seeded generator. Each size runs in a
fresh process, so its peak resident memory (``ru_maxrss``) is its own. Put it under
``prlimit --as=4000000000`` to hold it to 4 GB.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys

_CHILD = r"""
import json, resource, sys, time
import numpy as np
from planner import NoPlanFound, PlannerParams, Problem, plan
from planner.bounds import lower_bounds
from planner.scatter import scatter
m, cover, limit, seed = int(sys.argv[1]), float(sys.argv[2]), float(sys.argv[3]), int(sys.argv[4])
r, margin = 1.0, 0.1
side = float(np.sqrt(m * np.pi * r * r / cover))
shell = Problem(side, side, (), r, margin, np.zeros((0, 2)), np.zeros((0, 2)))
rng = np.random.default_rng(seed)
s = scatter(shell.env, m, 2 * r + margin, r + margin, rng, field="start")
t = scatter(shell.env, m, 2 * r + margin, r + margin, rng, field="target")
problem = Problem(side, side, (), r, margin, s, t)
t0 = time.perf_counter()
try:
    result, stats = plan(problem, PlannerParams(time_limit=limit), rng)
    found, makespan, steps = True, stats.makespan_s, stats.steps
except NoPlanFound:
    found, makespan, steps = False, float("nan"), 0
elapsed = time.perf_counter() - t0
bound = lower_bounds(problem)[0]
print(json.dumps({"m": m, "side": side, "found": found, "time_s": elapsed, "steps": steps,
                  "ratio": makespan / bound if found else None,
                  "peak_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}))
"""


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench.large", description=__doc__.split("\n")[0])
    ap.add_argument("--robots", type=int, nargs="+", default=[5000])
    ap.add_argument("--coverage", type=float, default=0.1, help="share of the workspace the discs cover (default 0.1)")
    ap.add_argument("--time-limit", type=float, default=60.0)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)
    print("| robots | side | coverage | found | planning [s] | steps | makespan / bound | peak memory [MB] |")
    print("| ---: | ---: | ---: | --- | ---: | ---: | ---: | ---: |")
    for m in args.robots:
        p = subprocess.run([sys.executable, "-c", _CHILD, str(m), str(args.coverage), str(args.time_limit),
                            str(args.seed)], capture_output=True, text=True, check=False)
        if p.returncode != 0:
            tail = p.stderr.strip().splitlines()[-1:] or [f"exit {p.returncode}"]
            print(f"| {m} | - | {args.coverage:g} | error: {tail[0][:80]} | - | - | - | - |", flush=True)
            continue
        row = json.loads(p.stdout.strip().splitlines()[-1])
        ratio = "-" if row["ratio"] is None else f"{row['ratio']:.2f}"
        print(f"| {m} | {row['side']:.0f} | {args.coverage:g} | {'yes' if row['found'] else 'no'} | "
              f"{row['time_s']:.1f} | {row['steps']} | {ratio} | {row['peak_mb']:.0f} |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
