"""The planner's frontier: many robots, clutter, dense obstacles, doors and unsolvable worlds.

Run ``python -m bench.frontier`` (``--help`` for the options; ``--quick``
for a small version).  One table: per case, the seeds run, how many were
proven unsolvable before planning (and the slowest proof), how many of the
rest were solved, the median and largest planning time, the peak memory of
the case's process and the median makespan over its lower bound.  A second
table (the full run, or ``--time-limits`` alone) checks that ``plan``
returns within ``1.1 time_limit + 0.5 s``: 200 and 1000 random robots,
lines of 200 and 500 into letters, 60 obstacles and 40 % density with 50
robots, and 200 robots on the maps room-32-32-4, warehouse-20-40-10-2-2 and
Berlin_1_256 (:func:`bench.maps.map_problem`, built outside the timed call),
at time limits of 0.5, 2 and 5 s, three seeds each, wall time around the
call whether or not a plan was found.

Cases (robot radius 1, margin 0.1, max speed and acceleration 2):

* ``random-mM``: ``M`` robots, start and target drawn independently,
  uniform, clear and separated, in a square workspace whose area the
  robots' discs cover at 10 % (side ``sqrt(M pi / 0.1)``), with three
  random convex obstacles of diameter ``[4, 8] * side / 40``.
* ``line-letter-mM``: ``M`` robots from a straight line (rotation 0, at
  the formation's spacing of 1.02 separations) into a letter (A, M, N, C,
  phi, lambda by seed; random rotation and centre); the square workspace
  is the line's length plus 8 % (coverage far below 10 %: the line must
  fit), three random convex obstacles as above.
* ``clutter-K-mM``: ``K`` random convex obstacles of diameter 2 to 4 in a
  40 x 40 workspace, random start and target in the largest component of
  the free space (grown obstacles, shapely).
* ``density-P-mM``: random convex obstacles of diameter 5 to 10 added to a
  40 x 40 workspace, two at a time, until their union covers ``P`` % of
  it; random start and target in the largest component of the free space
  (a world whose main room cannot hold them is drawn again, from the
  generator seeded ``[seed, attempt]``).
* ``door-W``: a wall 2 thick across the middle of a 40 x 40 workspace with
  one door ``W`` wide; 10 robots start left of it and end right of it.
  ``door-W-m200``: the same in a 60 x 60 workspace with 200 robots.
* ``unsolvable-*``: a door 0.01 and one 1e-6 narrower than a robot needs
  (2.2), a pocket holding 5 starts and 3 targets, and 1000 robots in two
  halves joined by a door too narrow.

Generated problems pass :meth:`planner.Problem.validate`; the planner's
feasibility test (:func:`planner.feasibility`) runs first on each, and
only problems it cannot prove unsolvable are planned (with the time
limit, auto mode); the proven ones are counted in their own columns with
their proof time.  Every plan found has passed the exact validator inside
:func:`planner.plan`.  Each case runs in a fresh spawned process after an
untimed warm-up; its memory is that process's peak resident set size
(``ru_maxrss``, everything included: the interpreter, numpy, scipy,
shapely and the problems).
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from dataclasses import dataclass, field

import numpy as np

from planner import Polygon, Problem

from ._common import MARGIN, RADIUS, in_fresh_process, machine_info, markdown_table, percentile

__all__ = ["CASES", "COLUMNS", "LIMIT_COLUMNS", "Case", "case_problem", "limit_rows", "main", "run_case"]

LETTERS = ("A", "M", "N", "C", "phi", "lambda")
COVERAGE = 0.10  # share of the workspace the robots' discs cover in random-mM


@dataclass(frozen=True)
class Case:
    """One row: ``kind`` names the generator, ``m`` robots, ``param`` its knob."""

    name: str
    kind: str
    m: int
    param: float = 0.0
    seeds: int = 5
    quick_seeds: int = 1
    tags: tuple = field(default=())


def _cases() -> tuple[Case, ...]:
    out = []
    for m, seeds in ((200, 5), (500, 3), (1000, 3)):
        out.append(Case(f"random-m{m}", "random", m, seeds=seeds))
    for m, seeds in ((200, 5), (500, 3), (1000, 2)):
        out.append(Case(f"line-letter-m{m}", "line-letter", m, seeds=seeds))
    for k in (10, 30, 60):
        for m in (20, 50):
            out.append(Case(f"clutter-{k}-m{m}", "clutter", m, k, seeds=10, quick_seeds=2))
    for p in (10, 20, 30, 40):
        for m in (20, 50):
            out.append(Case(f"density-{p}-m{m}", "density", m, p, seeds=20 if p == 40 else 10, quick_seeds=3))
    for w in (2.2, 2.6, 3.3, 4.4):
        out.append(Case(f"door-{w:g}", "door", 10, w, seeds=5, quick_seeds=1))
    for w in (2.2, 2.3, 2.6):  # a crowd through one door: a 60 x 60 workspace
        out.append(Case(f"door-{w:g}-m200", "door", 200, w, seeds=3, quick_seeds=1))
    out.append(Case("unsolvable-door-2.19", "door", 10, 2.19, seeds=5, quick_seeds=1))
    out.append(Case("unsolvable-door-2.2-1e-6", "door", 10, 2.2 - 1e-6, seeds=5, quick_seeds=1))
    out.append(Case("unsolvable-pocket", "pocket", 20, seeds=5, quick_seeds=1))
    out.append(Case("unsolvable-halves-m1000", "halves", 1000, 2.19, seeds=2, quick_seeds=1))
    return tuple(out)


CASES = _cases()

COLUMNS = ["case", "m", "seeds", "proven unsolvable", "proof max [s]", "planned", "solved",
           "median time [s]", "max time [s]", "peak RSS [MiB]", "makespan / bound (median)",
           "makespan / bound (max)"]


# ----------------------------------------------------------------------------
# generators


def _convex(rng, diameter: float, lo, hi) -> Polygon:
    """A convex polygon of 3 to 8 corners on a circle of ``diameter`` centred in ``[lo, hi]``."""
    while True:
        k = int(rng.integers(3, 9))
        ang = np.sort(rng.uniform(0.0, 2 * np.pi, size=k))
        c = rng.uniform(lo, hi)
        v = c + diameter / 2 * np.stack([np.cos(ang), np.sin(ang)], axis=1)
        x, y = v[:, 0], v[:, 1]
        if 0.5 * abs(float(x @ np.roll(y, -1) - np.roll(x, -1) @ y)) >= 0.05 * diameter**2:
            return Polygon(v)


def _obstacles(rng, count: int, side_w: float, side_h: float, size) -> tuple:
    out = []
    for _ in range(count):
        d = rng.uniform(*size)
        out.append(_convex(rng, d, [d / 2, d / 2], [side_w - d / 2, side_h - d / 2]))
    return tuple(out)


def _free(shell: Problem, m: int, rng, lo=None, hi=None, avoid=None, batches: int = 400) -> np.ndarray:
    """``m`` uniform, clear, separated points in the box ``[lo, hi]`` (default: the workspace)."""
    from planner.geometry import greedy_separated

    clr, sep = shell.clearance, shell.separation
    lo = np.array([clr, clr]) if lo is None else np.maximum(lo, clr)
    hi = np.array([shell.width - clr, shell.height - clr]) if hi is None else np.minimum(
        hi, [shell.width - clr, shell.height - clr])
    pts = np.zeros((0, 2))
    for _ in range(batches):
        cand = rng.uniform(lo, hi, size=(max(256, 4 * m), 2))
        cand = cand[shell.env.points_clear(cand, clr)]
        if avoid is not None:
            cand = cand[~avoid(cand)]
        pts = np.vstack([pts, cand[greedy_separated(cand, sep, pts, m - len(pts))]])
        if len(pts) == m:
            return pts
    raise ValueError(f"cannot place {m} robots")


def _outside_main_room(shell: Problem):
    """A test of points that are not in the largest component of the free space
    (shapely, obstacles grown by the clearance): robots drawn in the main room only."""
    import shapely
    from shapely.geometry import box

    c = shell.clearance
    grown = shapely.union_all([shapely.Polygon(o.vertices).buffer(c) for o in shell.obstacles])
    free = box(c, c, shell.width - c, shell.height - c).difference(grown)
    main = max(getattr(free, "geoms", [free]), key=lambda g: g.area)
    shapely.prepare(main)
    return lambda p: ~shapely.contains_xy(main, p[:, 0], p[:, 1])


def _shell(w, h, obs) -> Problem:
    return Problem(w, h, obs, RADIUS, MARGIN, np.zeros((0, 2)), np.zeros((0, 2)))


def _union_share(obs, w: float, h: float) -> float:
    import shapely
    from shapely.geometry import box

    u = shapely.union_all([shapely.Polygon(o.vertices) for o in obs])
    return float(u.intersection(box(0, 0, w, h)).area / (w * h))


def case_problem(case: Case, seed: int) -> Problem:
    """The problem of ``case`` for ``seed`` (all draws from ``default_rng(seed)``)."""
    rng = np.random.default_rng(seed)
    m = case.m
    if case.kind == "random":
        side = math.sqrt(m * math.pi * RADIUS**2 / COVERAGE)
        obs = _obstacles(rng, 3, side, side, (4 * side / 40, 8 * side / 40))
        sh = _shell(side, side, obs)
        return Problem(side, side, obs, RADIUS, MARGIN, _free(sh, m, rng), _free(sh, m, rng)).validate()
    if case.kind == "line-letter":
        from planner.formations import formation_shape, place_formation

        sep = 2 * RADIUS + MARGIN
        line = formation_shape("line", m, 0.0, sep, rng)
        side = float(np.ptp(line[:, 0])) * 1.08 + 2 * (RADIUS + MARGIN)
        obs = _obstacles(rng, 3, side, side, (4 * side / 40, 8 * side / 40))
        sh = _shell(side, side, obs)
        start = place_formation(line, sh.env, sh.clearance, rotation=0.0, center=None, rng=rng,
                                field="start")
        letter = formation_shape(LETTERS[seed % len(LETTERS)], m, 0.3 * side, sep, rng)
        for _ in range(50):
            target = place_formation(letter, sh.env, sh.clearance, rotation=None, center=None, rng=rng,
                                     field="target")
            p = Problem(side, side, obs, RADIUS, MARGIN, start, target)
            try:
                return p.validate()
            except ValueError:
                continue
        raise ValueError("no target placement")
    if case.kind == "clutter":
        obs = _obstacles(rng, int(case.param), 40.0, 40.0, (2.0, 4.0))
        sh = _shell(40.0, 40.0, obs)
        out = _outside_main_room(sh)
        return Problem(40.0, 40.0, obs, RADIUS, MARGIN, _free(sh, m, rng, avoid=out),
                       _free(sh, m, rng, avoid=out)).validate()
    if case.kind == "density":
        for attempt in range(50):  # a world whose main room holds the robots
            rng = np.random.default_rng([seed, attempt])
            obs = []
            while _union_share(obs, 40.0, 40.0) < case.param / 100.0 if obs else True:
                obs += list(_obstacles(rng, 2, 40.0, 40.0, (5.0, 10.0)))
            sh = _shell(40.0, 40.0, tuple(obs))
            out = _outside_main_room(sh)
            try:
                start, target = _free(sh, m, rng, avoid=out, batches=40), _free(sh, m, rng, avoid=out, batches=40)
            except ValueError:
                continue
            return Problem(40.0, 40.0, tuple(obs), RADIUS, MARGIN, start, target).validate()
        raise ValueError(f"no {case.param:g} % world holds {m} robots")
    if case.kind in ("door", "halves"):
        w = case.param
        side = (40.0 if m <= 10 else 60.0) if case.kind == "door" else math.sqrt(m * math.pi / COVERAGE)
        mid = side / 2
        lo, hi = mid - w / 2, mid + w / 2
        obs = (Polygon([[mid - 1, 0], [mid + 1, 0], [mid + 1, lo], [mid - 1, lo]]),
               Polygon([[mid - 1, hi], [mid + 1, hi], [mid + 1, side], [mid - 1, side]]))
        sh = _shell(side, side, obs)
        if case.kind == "door":
            start = _free(sh, m, rng, hi=[mid - 1, side])
            target = _free(sh, m, rng, lo=[mid + 1, 0])
        else:  # more starts than targets on the left
            left = m // 2 + 3
            start = np.vstack([_free(sh, left, rng, hi=[mid - 1, side]),
                               _free(sh, m - left, rng, lo=[mid + 1, 0])])
            target = np.vstack([_free(sh, m // 2, rng, hi=[mid - 1, side]),
                                _free(sh, m - m // 2, rng, lo=[mid + 1, 0])])
        return Problem(side, side, obs, RADIUS, MARGIN, start, target).validate()
    if case.kind == "pocket":
        # A 10 x 10 room in the corner of a 40 x 40 workspace, its opening 2.0 wide.
        obs = (Polygon([[12, 0], [14, 0], [14, 12], [12, 12]]),
               Polygon([[0, 12], [5, 12], [5, 14], [0, 14]]),
               Polygon([[7, 12], [14, 12], [14, 14], [7, 14]]))
        sh = _shell(40.0, 40.0, obs)
        inside = dict(hi=[12, 12])

        def in_room(p):
            return (p[:, 0] < 14 + 1.1) & (p[:, 1] < 14 + 1.1)

        start = np.vstack([_free(sh, 5, rng, **inside), _free(sh, m - 5, rng, avoid=in_room)])
        target = np.vstack([_free(sh, 3, rng, **inside), _free(sh, m - 3, rng, avoid=in_room)])
        return Problem(40.0, 40.0, obs, RADIUS, MARGIN, start, target).validate()
    raise ValueError(f"unknown case kind {case.kind!r}")


# ----------------------------------------------------------------------------
# running


def _maxrss_mib() -> float:
    import resource

    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return rss / (1024.0 * 1024.0) if sys.platform == "darwin" else rss / 1024.0


def _run_case(case: Case, seeds: list[int], time_limit: float) -> dict:
    from planner import NoPlanFound, PlannerParams, feasibility, plan
    from planner.bounds import lower_bounds

    from ._common import warm_up_planner

    warm_up_planner(time_limit)
    records = []
    wanted, seed = len(seeds), seeds[0]
    # Draw seeds in turn until ``wanted`` problems pass the feasibility test
    # (designed-unsolvable cases: until ``wanted`` proofs), at most 20 per wanted.
    while seed < seeds[0] + 20 * wanted:
        done = [r for r in records if r["proven"] == case.name.startswith("unsolvable")]
        if len(done) >= wanted:
            break
        problem = case_problem(case, seed)
        seed += 1
        t0 = time.perf_counter()
        proof = feasibility(problem)
        if proof is not None:
            records.append({"seed": seed - 1, "proven": True, "proof_s": time.perf_counter() - t0,
                            "reason": proof.reason})
            continue
        rng = np.random.default_rng(seed - 1)
        t0 = time.perf_counter()
        try:
            result, stats = plan(problem, PlannerParams(time_limit=time_limit), rng)
        except NoPlanFound as exc:
            records.append({"seed": seed - 1, "proven": False, "solved": False,
                            "time_s": time.perf_counter() - t0, "reason": str(exc)})
            continue
        records.append({"seed": seed - 1, "proven": False, "solved": True, "time_s": time.perf_counter() - t0,
                        "ratio": result.makespan / lower_bounds(problem)[0], "steps": result.steps,
                        "method": stats.extra.get("direct", stats.extra.get("method", "roadmap"))})
    return {"records": records, "rss_mib": _maxrss_mib()}


def _run_limits(case: Case, seeds: list[int], limits: tuple) -> dict:
    """Wall time of each ``plan`` call (found or not) per time limit."""
    from planner import NoPlanFound, PlannerParams, plan

    from ._common import warm_up_planner

    warm_up_planner(min(limits))
    out = []
    for limit in limits:
        for seed in seeds:
            problem = _limit_problem(case, seed)
            t0 = time.perf_counter()
            try:
                plan(problem, PlannerParams(time_limit=limit), np.random.default_rng(seed))
                found = True
            except NoPlanFound:
                found = False
            out.append({"limit": limit, "seed": seed, "found": found, "wall_s": time.perf_counter() - t0})
    return {"records": out, "rss_mib": _maxrss_mib()}


def _in_child(case: Case, seeds: list[int], time_limit: float, limits=None) -> dict:
    """``_run_case`` (or ``_run_limits``) in a fresh spawned process."""
    timeout = len(seeds) * (time_limit * 1.5 + 60.0) + 120.0
    if limits is None:
        return in_fresh_process(_run_case, (case, seeds, time_limit), timeout)
    return in_fresh_process(_run_limits, (case, seeds, limits), timeout)


#: The time-limit table: cases, limits [s], seeds per case and limit.  ``map-NAME-mM``: the
#: MovingAI map ``NAME`` with ``M`` robots (:func:`bench.maps.map_problem`; seed 0 the map's
#: ``.scen`` agents, others random cells); ``scatter-NAME-mM``: the same map with the robots
#: scattered over its free space (:func:`bench.maps.scatter_problem`); in this table only.
LIMIT_CASES = ("random-m200", "line-letter-m200", "random-m1000", "line-letter-m500", "clutter-60-m50", "density-40-m50",
               "map-room-32-32-4-m200", "map-warehouse-20-40-10-2-2-m200", "map-Berlin_1_256-m200",
               "scatter-room-32-32-4-m400", "scatter-Berlin_1_256-m200")
LIMITS = (0.5, 2.0, 5.0)
LIMIT_SEEDS = 3
LIMIT_COLUMNS = ["case", "m", "time limit [s]", "runs", "found", "median wall [s]", "max wall [s]",
                 "bar [s]", "within bar"]


def limit_rows(names=LIMIT_CASES, limits=LIMITS, seeds: int = LIMIT_SEEDS) -> list[dict]:
    """Whether ``plan`` returns within ``1.1 time_limit + 0.5 s``: one row per case and
    limit, each case in a fresh process, wall time around the ``plan`` call."""
    rows = []
    for name in names:
        case = _limit_case(name)
        result = _in_child(case, list(range(seeds)), max(limits), limits)
        if "error" in result:
            rows.append({"case": name, "m": case.m, "within bar": f"error: {result['error'][:60]}"})
            continue
        for limit in limits:
            rec = [r for r in result["records"] if r["limit"] == limit]
            walls = [r["wall_s"] for r in rec]
            bar = 1.1 * limit + 0.5
            rows.append({"case": name, "m": case.m, "time limit [s]": limit, "runs": len(rec),
                         "found": sum(r["found"] for r in rec), "median wall [s]": percentile(walls, 50),
                         "max wall [s]": max(walls), "bar [s]": bar,
                         "within bar": "yes" if max(walls) <= bar else "no"})
        print(f"  time limits, {name}: " + ", ".join(f"{r['time limit [s]']:g} s -> max {r['max wall [s]']:.2f} s"
                                                    for r in rows if r["case"] == name), file=sys.stderr, flush=True)
    return rows


def _limit_case(name: str) -> Case:
    """The case of a time-limit row: one of :data:`CASES` or a map case (``map-NAME-mM``)."""
    if name.startswith(("map-", "scatter-")):
        return Case(name, "map", int(name.rsplit("-m", 1)[1]))
    return next(c for c in CASES if c.name == name)


def _limit_problem(case: Case, seed: int) -> Problem:
    """The problem of a time-limit run (a map case's built by :func:`bench.maps.map_problem`)."""
    if case.kind == "map":
        from .maps import map_problem, scatter_problem

        kind, rest = case.name.split("-", 1)
        make = scatter_problem if kind == "scatter" else map_problem
        return make(rest.rsplit("-m", 1)[0], case.m, seed)
    return case_problem(case, seed)


def run_case(case: Case, seeds: list[int], time_limit: float) -> dict:
    """One table row, measured in a fresh spawned process."""
    result = _in_child(case, seeds, time_limit)
    row = {"case": case.name, "m": case.m}
    if "error" in result:
        row["solved"] = f"error: {result['error'][:60]}"
        return row
    rec = result["records"]
    proven = [r for r in rec if r["proven"]]
    planned = [r for r in rec if not r["proven"]]
    ok = [r for r in planned if r["solved"]]
    times = [r["time_s"] for r in planned]
    ratios = [r["ratio"] for r in ok]
    row.update({
        "seeds": len(rec),
        "proven unsolvable": len(proven),
        "proof max [s]": max((r["proof_s"] for r in proven), default=math.nan),
        "planned": len(planned),
        "solved": f"{len(ok)}/{len(planned)}" if planned else "-",
        "median time [s]": percentile(times, 50),
        "max time [s]": max(times, default=math.nan),
        "peak RSS [MiB]": result["rss_mib"],
        "makespan / bound (median)": percentile(ratios, 50),
        "makespan / bound (max)": max(ratios, default=math.nan),
        "records": rec,
    })
    return row


def _parse(argv):
    ap = argparse.ArgumentParser(prog="python -m bench.frontier", description=__doc__.split("\n")[0])
    ap.add_argument("--cases", nargs="+", default=None, help="case names or prefixes (default: all)")
    ap.add_argument("--seeds", type=int, default=None, help="seeds per case (default: the case's own)")
    ap.add_argument("--quick", action="store_true", help="each case's small seed count")
    ap.add_argument("--time-limit", type=float, default=60.0, help="planning time limit per run [s] (default 60)")
    ap.add_argument("--list", action="store_true", help="list the cases and exit")
    ap.add_argument("--time-limits", action="store_true",
                    help="only the time-limit table (the full run, without --cases, prints both)")
    args = ap.parse_args(argv)
    if args.seeds is not None and args.seeds < 1:
        ap.error(f"--seeds must be an int >= 1, got {args.seeds}")
    if not args.time_limit > 0:
        ap.error(f"--time-limit must be > 0, got {args.time_limit}")
    return args


def main(argv: list[str] | None = None) -> list[dict]:
    """Run the benchmark, print the report, return one row per case (see :data:`COLUMNS`)."""
    args = _parse(argv)
    cases = [c for c in CASES if args.cases is None or any(c.name == p or c.name.startswith(p) for p in args.cases)]
    if args.list:
        for c in cases:
            print(c.name)
        return []
    rows = []
    if args.time_limits:
        cases = []
    for case in cases:
        n = args.seeds or (case.quick_seeds if args.quick else case.seeds)
        row = run_case(case, list(range(n)), args.time_limit)
        rows.append(row)
        print(f"  {case.name}: {row.get('solved')} solved, {row.get('proven unsolvable', 0)} proven, "
              f"median {row.get('median time [s]', math.nan):.3g} s, {row.get('peak RSS [MiB]', math.nan):.0f} MiB",
              file=sys.stderr, flush=True)
    print("# swarmform frontier\n\n" + machine_info())
    print(f"- settings: time limit {args.time_limit:g} s, auto mode, seeds 0..N-1 per case\n")
    if rows:
        print(markdown_table(COLUMNS, rows))
    if args.time_limits or args.cases is None:
        limits = limit_rows(seeds=1 if args.quick else LIMIT_SEEDS)
        print("\n## time_limit honoured (returns within 1.1 time_limit + 0.5 s; seeds 0..N-1, "
              "wall time around plan())\n")
        print(markdown_table(LIMIT_COLUMNS, limits))
        rows = rows + limits
    return rows


if __name__ == "__main__":
    main()
