"""Dense packings: 50 robots in an empty square box at 50 % and 55 % coverage.

Run ``python -m bench.packing`` (``--coverage 0.5 0.55``, ``--seeds 10``,
``--time-limit 10``, ``--method plan dense``).  One Markdown table: per
coverage, method and seed, the outcome (``found``: a plan that passed the
exact validator; ``proven``: a proof that no plan exists; ``none``), the
wall time, the makespan and the makespan over
``stats.makespan_lower_bound_s`` (the straight-line bound of
:func:`planner.bounds.lower_bounds`).

The case (``packing_problem(m, coverage, seed)``):

* a square workspace without obstacles whose area ``A`` satisfies
  ``m * pi * r^2 / A = coverage``: side ``sqrt(m pi r^2 / coverage)``
  (17.72 at 50 %, 16.90 at 55 % for ``m = 50``);
* robots of radius ``r = 1``, margin 0.1: centres at least
  ``separation = 2.2 - 0.1 = 2.1`` apart and ``clearance = 1.1`` from the
  walls (:class:`planner.Problem`);
* start and target drawn independently from one
  ``numpy.random.default_rng(seed)`` (start first).  Random sequential
  addition jams near these densities (the separation discs of radius 1.05
  cover about 56 % and 61 % of the box their centres can use), so each
  placement is ``m`` sites drawn at random from a hexagonal lattice of
  spacing ``separation`` (shifted at random), then relaxed by
  :data:`SWEEPS` sweeps of Metropolis moves of hard discs: each robot in
  turn tries a displacement uniform in a disc, kept when it leaves the
  placement separated and clear; the step size adapts towards an
  acceptance of about 40 %.  Every placement passes
  :meth:`planner.Problem.validate`.

``--method plan`` is :func:`planner.plan` in auto mode with the time limit
and ``rng = np.random.default_rng(seed)``; ``--method dense`` is the
dense-packing stage (:func:`planner.dense.dense_plan`) called directly on
the same problem with the same time limit, its plan checked by
:func:`planner.check_plan`.

``--halls N`` runs instead ``N`` halls with pillars (``hall_problem(seed)``, seeds 0 to
N - 1, ``--method plan``): a workspace of 6 to 16 by 6 to 16, robots of radius 0.15,
0.2, 0.3 or 0.5 (margin 0.05), 1 to 8 obstacles (discs of radius 0.1 to 0.8 or
rectangles of sides 0.1 to 2, anywhere), and as many robots as cover 18 % to 38 % of the
workspace, start and target scattered (:func:`planner.scatter.scatter`), all drawn
from ``default_rng([5, seed])``; a hall whose robots do not fit is skipped.
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np

from planner import Problem

from ._common import MARGIN, RADIUS, markdown_table

__all__ = ["SWEEPS", "packing_problem", "placement", "main"]

#: Metropolis sweeps (each robot one trial move per sweep) relaxing a lattice subset.
SWEEPS = 300


def _lattice_sites(inner: float, sep: float, rng: np.random.Generator) -> np.ndarray:
    """Hexagonal lattice sites of spacing ``sep`` in ``[0, inner]^2``, shifted at random."""
    dy = sep * math.sqrt(3.0) / 2.0
    sx, sy = rng.uniform(0.0, 1.0, 2) * (sep, dy)
    pts = []
    for j in range(int((inner - sy) // dy) + 1):
        off = (sx + (j % 2) * sep / 2.0) % sep
        for i in range(int((inner - off) // sep) + 1):
            pts.append((off + i * sep, sy + j * dy))
    return np.asarray(pts, float).reshape(-1, 2)


def placement(side: float, m: int, rng: np.random.Generator, sweeps: int = SWEEPS) -> np.ndarray:
    """``m`` separated, clear centres in a ``side`` square: a random lattice subset, relaxed."""
    clear = RADIUS + MARGIN
    sep = 2.0 * RADIUS + MARGIN
    inner = side - 2.0 * clear
    for _ in range(100):
        sites = _lattice_sites(inner, sep * (1 + 1e-9), rng)
        if len(sites) >= m:
            break
    else:
        raise ValueError(f"{m} robots do not fit a lattice in a {side:g} box")
    p = sites[rng.choice(len(sites), m, replace=False)] + clear
    lo, hi = clear, side - clear
    step = 0.3
    for _ in range(sweeps):
        kept = 0
        for i in rng.permutation(m):
            q = p[i] + step * math.sqrt(rng.random()) * np.array(
                [math.cos(a := rng.uniform(0.0, 2 * math.pi)), math.sin(a)])
            if not (lo <= q[0] <= hi and lo <= q[1] <= hi):
                continue
            d2 = ((p - q) ** 2).sum(axis=1)
            d2[i] = np.inf
            if d2.min() >= sep * sep * (1 + 1e-9):
                p[i] = q
                kept += 1
        step *= 1.1 if kept > 0.4 * m else 0.9
    return p


def packing_problem(m: int = 50, coverage: float = 0.5, seed: int = 0) -> Problem:
    """The case of the module docstring: ``m`` robots at ``coverage`` in an empty square."""
    side = math.sqrt(m * math.pi * RADIUS**2 / coverage)
    rng = np.random.default_rng(seed)
    start = placement(side, m, rng)
    target = placement(side, m, rng)
    return Problem(side, side, (), RADIUS, MARGIN, start, target).validate()


def hall_problem(seed: int) -> Problem | None:
    """A hall with pillars, crowded (see the module docstring), or ``None`` when its robots
    do not fit."""
    from planner import Circle, Polygon
    from planner.scatter import scatter

    rng = np.random.default_rng([5, seed])
    w, h = rng.uniform(6, 16), rng.uniform(6, 16)
    r = float(rng.choice([0.15, 0.2, 0.3, 0.5]))
    obs: list = []
    for _ in range(rng.integers(1, 9)):
        if rng.random() < 0.5:
            obs.append(Circle((rng.uniform(0, w), rng.uniform(0, h)), rng.uniform(0.1, 0.8)))
        else:
            x, y, a, b = rng.uniform(0, w), rng.uniform(0, h), rng.uniform(0.1, 2), rng.uniform(0.1, 2)
            obs.append(Polygon(np.array([[x, y], [x + a, y], [x + a, y + b], [x, y + b]])))
    shell = Problem(w, h, tuple(obs), r, 0.05, [[w / 2, h / 2]], [[w / 2, h / 2]])
    m = int(rng.uniform(0.18, 0.38) * w * h / (math.pi * r * r))
    try:
        start = scatter(shell.env, m, shell.separation, shell.clearance, rng)
        target = scatter(shell.env, m, shell.separation, shell.clearance, rng)
    except ValueError:
        return None
    return Problem(w, h, tuple(obs), r, 0.05, start, target).validate()


def run(problem: Problem, method: str, seed: int, time_limit: float) -> dict:
    """One row: outcome, time, makespan and makespan over the straight-line bound."""
    from planner import NoPlanFound, PlannerParams, check_plan, feasibility, plan
    from planner.bounds import lower_bounds

    t0 = time.perf_counter()
    if method == "plan":
        try:
            result, stats = plan(problem, PlannerParams(time_limit=time_limit), np.random.default_rng(seed))
        except NoPlanFound as exc:
            proven = exc.stats.extra.get("feasible") is False
            return {"outcome": "proven" if proven else "none", "time_s": time.perf_counter() - t0}
        bound = stats.makespan_lower_bound_s
    else:
        from planner.dense import dense_plan

        proof = feasibility(problem)
        result = None if proof else dense_plan(problem, time_limit, np.random.default_rng(seed))
        if result is None:
            return {"outcome": "proven" if proof else "none", "time_s": time.perf_counter() - t0}
        check_plan(problem, result)
        bound = lower_bounds(problem)[0]
    return {"outcome": "found", "time_s": time.perf_counter() - t0, "makespan_s": result.makespan,
            "ratio": result.makespan / bound, "steps": result.steps,
            "stage": stats.extra.get("direct", "roadmap") if method == "plan" else "dense"}


def main(argv: list[str] | None = None) -> list[dict]:
    ap = argparse.ArgumentParser(prog="python -m bench.packing", description=__doc__.split("\n")[0])
    ap.add_argument("--coverage", type=float, nargs="+", default=[0.5, 0.55])
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--robots", type=int, default=50)
    ap.add_argument("--time-limit", type=float, default=10.0)
    ap.add_argument("--method", nargs="+", choices=("plan", "dense"), default=["plan", "dense"])
    ap.add_argument("--halls", type=int, default=0, metavar="N", help="N crowded halls with pillars instead (plan)")
    args = ap.parse_args(argv)
    from ._common import warm_up_planner

    warm_up_planner(args.time_limit)
    rows = []
    if args.halls:
        for seed in range(args.halls):
            problem = hall_problem(seed)
            if problem is None:
                continue
            row = {"seed": seed, "world": f"{problem.width:.1f} x {problem.height:.1f}", "radius": problem.radius,
                   "robots": problem.m, "obstacles": len(problem.obstacles)}
            row.update(run(problem, "plan", seed, args.time_limit))
            rows.append(row)
            print(f"# {row}", flush=True)
        print(markdown_table(["seed", "world", "radius", "robots", "obstacles", "outcome", "time_s", "makespan_s",
                              "ratio", "stage"], rows))
        return rows
    for cov in args.coverage:
        for seed in range(args.seeds):
            problem = packing_problem(args.robots, cov, seed)
            for method in args.method:
                row = {"coverage": cov, "method": method, "seed": seed}
                row.update(run(problem, method, seed, args.time_limit))
                rows.append(row)
                print(f"# {row}", flush=True)
    print(markdown_table(["coverage", "method", "seed", "outcome", "time_s", "makespan_s", "ratio", "steps"], rows))
    return rows


if __name__ == "__main__":
    main()
