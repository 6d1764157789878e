"""Planner benchmark: every paper scenario over many seeds, paper (g, q) and auto.

    python -m bench.planner [--seeds 50] [--scenarios GLOB ...] [--time-limit S]

For each scenario and mode it prints the success rate, the median and 90th
percentile planning time (measured inside ``plan()``, after an untimed
warm-up run that takes lazy imports out) and the median makespan over its
lower bound.  One run is
``rng = default_rng(seed); problem = build_problem(scenario, rng);
plan(problem, params, rng)``, as the command line does.
"""

from __future__ import annotations

import argparse
import glob
import platform
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

__all__ = ["main", "run"]

DEFAULT = ["scenarios/paper/*.yaml", "scenarios/harder/*.yaml"]


def run(paths: list[str], seeds: int, time_limit: float, modes=("paper", "auto"), progress=None) -> list[dict]:
    """One row per (scenario, mode): success, times and makespan ratio."""
    from planner import NoPlanFound, PlannerParams, plan
    from sim.scenario import build_problem, read_scenario

    from ._common import warm_up_planner

    warm_up_planner(time_limit)
    rows = []
    for path in paths:
        sc = read_scenario(path)
        for mode in modes:
            if mode == "paper":
                if sc.planner.auto:
                    continue
                params = replace(sc.planner, time_limit=time_limit)
            else:
                params = PlannerParams(time_limit=time_limit)
            times, ratios, found = [], [], 0
            for seed in range(seeds):
                rng = np.random.default_rng(seed)
                problem = build_problem(sc, rng)
                try:
                    _, stats = plan(problem, params, rng)
                except NoPlanFound as exc:
                    times.append(exc.stats.planning_time_s)
                    continue
                found += 1
                times.append(stats.planning_time_s)
                ratios.append(stats.makespan_s / stats.makespan_lower_bound_s)
            ok = np.asarray(times)
            rows.append({
                "scenario": sc.name,
                "m": sc.count,
                "mode": "auto" if mode == "auto" else f"g={params.g} q={params.q}",
                "success": found / seeds,
                "median_s": float(np.median(ok)),
                "p90_s": float(np.percentile(ok, 90)),
                "ratio": float(np.median(ratios)) if ratios else float("nan"),
            })
            if progress:
                progress(rows[-1])
    return rows


def table(rows: list[dict]) -> str:
    out = ["| scenario | m | mode | success | median time [s] | p90 time [s] | makespan / bound (median) |",
           "| --- | ---: | --- | ---: | ---: | ---: | ---: |"]
    for r in rows:
        out.append(f"| {r['scenario']} | {r['m']} | {r['mode']} | {100 * r['success']:.0f} % | "
                   f"{r['median_s']:.3f} | {r['p90_s']:.3f} | {r['ratio']:.2f} |")
    return "\n".join(out)


def main(argv=None) -> list[dict]:
    ap = argparse.ArgumentParser(prog="python -m bench.planner", description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=50)
    ap.add_argument("--scenarios", nargs="+", default=DEFAULT, help="globs of scenario files")
    ap.add_argument("--time-limit", type=float, default=60.0)
    ap.add_argument("--modes", nargs="+", default=["paper", "auto"], choices=["paper", "auto"])
    args = ap.parse_args(argv)
    root = Path(__file__).resolve().parents[1]
    paths = sorted({p for g in args.scenarios for p in glob.glob(str(root / g) if not Path(g).is_absolute() else g)})
    print(f"# planner benchmark, {time.strftime('%Y-%m-%d')}, {platform.platform()}, "
          f"{platform.processor() or platform.machine()}, python {platform.python_version()}, "
          f"{args.seeds} seeds, time limit {args.time_limit:g} s", flush=True)
    t0 = time.perf_counter()
    rows = run(paths, args.seeds, args.time_limit, tuple(args.modes),
               progress=lambda r: print(f"  {r['scenario']} {r['mode']}: {100 * r['success']:.0f} %, "
                                        f"median {r['median_s']:.3f} s", file=sys.stderr, flush=True))
    print(table(rows))
    auto = [r for r in rows if r["mode"] == "auto"]
    small = [r["median_s"] for r in auto if r["m"] <= 11]
    big = [r["median_s"] for r in auto if r["m"] >= 20]
    if auto:  # (none with --modes paper)
        print(f"\nauto mode: success {min(r['success'] for r in auto) * 100:.0f} % at worst; "
              f"largest median time {max(small, default=float('nan')):.3f} s for m <= 11, "
              f"{max(big, default=float('nan')):.3f} s for m >= 20; "
              f"largest median makespan / bound {max(r['ratio'] for r in auto):.2f}; "
              f"total {time.perf_counter() - t0:.0f} s")
    else:
        print(f"\ntotal {time.perf_counter() - t0:.0f} s")
    return rows


if __name__ == "__main__":
    main()
