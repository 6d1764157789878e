"""How swarmform's planner scales with the number of robots.

Run ``python -m bench.scaling`` (``--help`` for the options).  For each
robot count ``m`` (default 7, 11, 20, 50, 100, 200) the workspace is a
square of side ``40 sqrt(m / 11)`` (the paper's 40 x 40 with 11 robots,
grown so that the robot density stays the same), with three random convex
obstacles whose diameters are uniform in ``[4, 8] * side / 40``, and start
and target placements drawn independently, uniform, clear and separated
(robot radius 1, margin 0.1).  Seed ``s`` builds the problem with
``np.random.default_rng(s)`` and :func:`planner.plan` runs in auto mode
with that generator.

Every size runs in a fresh Python process (spawned, not forked), so that
its peak memory is its own; an untimed warm-up (the scipy modules the
planner imports lazily, and two small runs with m = 3, in auto mode and at
fixed g and q) takes lazy imports and first-call costs out of the
measurements.  The memory
column is the growth of the process's peak resident set size
(``getrusage(RUSAGE_SELF).ru_maxrss``) from just before the first
``plan()`` call to after the last: about the largest extra memory a
single run of that size needed (later runs reuse what earlier ones
freed), at the page level and without the slowdown tracing would add.
Planning times are wall-clock around ``plan()``; medians and 90th
percentiles are over the solved runs.  The fitted exponent is the
least-squares slope of log median time against log m over the sizes with
a solved run (and over m >= 20, where fixed costs no longer dominate).
"""

from __future__ import annotations

import argparse
import math
import sys
import time

import numpy as np

from planner import NoPlanFound, PlannerParams, plan
from planner.bounds import lower_bounds

from ._common import (
    in_fresh_process,
    machine_info,
    markdown_table,
    percentile,
    scaled_problem,
    side_for,
    warm_up_planner,
)

__all__ = ["COLUMNS", "fit_exponent", "format_report", "main", "run_size", "scaled_problem", "side_for"]

COLUMNS = [
    "m",
    "side",
    "runs",
    "success",
    "median time [s]",
    "p90 time [s]",
    "peak RSS growth [MiB]",
    "median makespan / LB",
    "median steps",
]
"""Columns of the scaling table (the keys of :func:`main`'s rows)."""


def _maxrss_mib() -> float:
    import resource

    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return rss / (1024.0 * 1024.0) if sys.platform == "darwin" else rss / 1024.0  # bytes vs KiB


def _run_size(m: int, seeds: int, time_limit: float) -> dict:
    """All seeds of one size in this process: per-run records and the peak RSS growth."""
    # Build every problem first, so that the memory baseline holds them all.
    rngs = [np.random.default_rng(s) for s in range(seeds)]
    problems = [scaled_problem(m, rng) for rng in rngs]
    bounds = [lower_bounds(p)[0] for p in problems]
    params = PlannerParams(time_limit=time_limit)
    # Warm-up, so that lazy imports and first-call costs land before the
    # baseline instead of in the first measured run.
    warm_up_planner(time_limit)
    base = _maxrss_mib()
    records = []
    for s, (problem, rng, lb) in enumerate(zip(problems, rngs, bounds)):
        t0 = time.perf_counter()
        try:
            result, _ = plan(problem, params, rng)
        except NoPlanFound:
            records.append({"seed": s, "solved": False, "time_s": time.perf_counter() - t0})
            continue
        records.append({"seed": s, "solved": True, "time_s": time.perf_counter() - t0,
                        "ratio": result.makespan / lb, "steps": result.steps})
    return {"records": records, "rss_mib": _maxrss_mib() - base}


def run_size(m: int, seeds: int, time_limit: float) -> dict:
    """One table row: ``m`` robots, seeds ``0..seeds-1``, in a fresh spawned process."""
    result = in_fresh_process(_run_size, (m, seeds, time_limit), seeds * (time_limit + 60.0) + 120.0)
    if "error" in result:
        raise RuntimeError(f"scaling run for m = {m} failed: {result['error']}")
    rec = result["records"]
    ok = [r for r in rec if r["solved"]]
    times = [r["time_s"] for r in ok]
    return {
        "m": m,
        "side": side_for(m),
        "runs": len(rec),
        "success": len(ok) / len(rec) if rec else math.nan,
        "median time [s]": percentile(times, 50),
        "p90 time [s]": percentile(times, 90),
        "peak RSS growth [MiB]": result["rss_mib"],
        "median makespan / LB": percentile([r["ratio"] for r in ok], 50),
        "median steps": percentile([r["steps"] for r in ok], 50),
    }


def fit_exponent(rows: list[dict], min_m: int = 0) -> float:
    """Least-squares slope of log median time against log m (sizes >= ``min_m`` with a time)."""
    pts = [(r["m"], r["median time [s]"]) for r in rows
           if r["m"] >= min_m and math.isfinite(r["median time [s]"]) and r["median time [s]"] > 0]
    if len(pts) < 2:
        return math.nan
    x, y = np.log([p[0] for p in pts]), np.log([p[1] for p in pts])
    return float(np.polyfit(x, y, 1)[0])


def format_report(rows: list[dict], settings: str = "") -> str:
    """Machine, settings, the table and the fitted exponents."""
    parts = ["# swarmform scaling", "", machine_info()]
    if settings:
        parts.append(settings)
    parts += ["", markdown_table(COLUMNS, rows), "",
              f"Fitted exponent of median planning time in m: {fit_exponent(rows):.2f} (all sizes), "
              f"{fit_exponent(rows, 20):.2f} (m >= 20)."]
    return "\n".join(parts)


def _parse(argv):
    ap = argparse.ArgumentParser(prog="python -m bench.scaling", description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", type=int, default=10, help="seeds 0..N-1 per size (default 10)")
    ap.add_argument("--sizes", type=int, nargs="+", default=[7, 11, 20, 50, 100, 200],
                    help="robot counts (default 7 11 20 50 100 200)")
    ap.add_argument("--time-limit", type=float, default=60.0, help="planning time limit per run [s] (default 60)")
    args = ap.parse_args(argv)
    if args.seeds < 1:
        ap.error(f"--seeds must be an int >= 1, got {args.seeds}")
    if min(args.sizes) < 2:
        ap.error(f"--sizes must be ints >= 2, got {min(args.sizes)}")
    if not args.time_limit > 0:
        ap.error(f"--time-limit must be > 0, got {args.time_limit}")
    return args


def main(argv: list[str] | None = None) -> list[dict]:
    """Run the benchmark, print the report, return one row per size (see :data:`COLUMNS`)."""
    args = _parse(argv)
    rows = [run_size(m, args.seeds, args.time_limit) for m in args.sizes]
    settings = (
        f"- settings: seeds 0..{args.seeds - 1} per size, time limit {args.time_limit:g} s, auto mode; "
        f"side = 40 sqrt(m / 11), 3 random convex obstacles, uniform random start and target, "
        f"radius 1, margin 0.1\n"
        f"- times: wall-clock around plan() (medians, p90 over solved runs); memory: peak RSS growth "
        f"during the size's plan() calls in a fresh process (ru_maxrss)"
    )
    print(format_report(rows, settings), flush=True)
    return rows


if __name__ == "__main__":
    main()
