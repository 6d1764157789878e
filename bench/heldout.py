"""Held-out benchmark: the planner on worlds that neither bench.frontier nor bench.maps makes.

    python -m bench.heldout [--quick] [--seeds N] [--time-limit S] [--cases PREFIX ...] [--list]

Four families, drawn by :mod:`bench.heldout_worlds` (its own seeded generator):
``letter-mM`` (a line at a drawn angle and position into a drawn glyph, drawn aspect),
``random-mM`` (drawn aspect, coverage and obstacles), ``door-W-mM`` (drawn wall
position, thickness and door height; W = 2.2 is the narrowest door a robot fits
through) and ``map-NAME-mM`` (the maps of bench.maps and five more, cells drawn
here).  Each case and seed runs in a fresh spawned process after an untimed
warm-up: :func:`planner.feasibility`, then :func:`planner.plan` in auto mode.

Columns: ``time_s`` the planner's own time, ``peak_mb`` the process's peak
resident memory, ``x_straight`` / ``x_geo`` / ``x_cut`` the makespan over the
straight-line bound, the obstacle-respecting bound (:mod:`planner.geobound`,
computed after the plan when the planner left it out, within ``--geo-budget``)
and the cut bound (when the planner's stats have one).  ``target`` is what the row
is judged against: on maps, solved with ``x_geo <= 2`` and within 3 s (m <= 100),
10 s (m <= 200) or, on room and warehouse maps, 30 s (m <= 400); a door at the limit
(2.2) with 200 robots, solved with ``x_cut <= 3``; elsewhere, solved within the time
limit.  ``meets`` is ``yes``, ``no`` or ``?`` (a bound it needs was
not computed).
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from dataclasses import dataclass

import numpy as np

from ._common import in_fresh_process, machine_info, markdown_table

DOOR_LIMIT = 2.2  # the narrowest door a robot fits through (2 (radius + margin))
DOOR_X = 3.0  # its target: makespan within this factor of the cut bound, at 200 robots

__all__ = ["CASES", "COLUMNS", "Case", "build", "judge", "main", "run_one", "summary"]

OLD_MAPS = ("room-32-32-4", "maze-32-32-4", "random-32-32-20", "warehouse-10-20-10-2-1", "den312d",
            "warehouse-20-40-10-2-2")
NEW_MAPS = ("random-64-64-10", "room-64-64-8", "maze-32-32-2", "empty-32-32", "warehouse-10-20-10-2-2")
COLUMNS = ["case", "m", "seed", "ok", "time_s", "peak_mb", "makespan_s", "x_straight", "x_geo", "x_cut",
           "target", "meets", "note", "planner"]
GEO_LIMIT = 2.0


@dataclass(frozen=True)
class Case:
    """One table row per seed: ``family`` names the generator, ``param`` its width or map."""

    name: str
    family: str
    m: int
    param: str = ""
    quick: bool = False


def _cases() -> tuple[Case, ...]:
    out = [Case(f"letter-m{m}", "letter", m, quick=m in (137, 350)) for m in (137, 263, 350, 720)]
    out += [Case(f"random-m{m}", "random", m, quick=m in (150, 350)) for m in (150, 350, 750)]
    out += [Case(f"door-{w}-m{m}", "door", m, w, quick=m != 130) for w in ("2.2", "2.3", "2.6") for m in (60, 130, 200)]
    for name in OLD_MAPS + NEW_MAPS:
        small = "-32-32" in name or "room" in name or "warehouse" in name
        for m in (75, 150, 300) + ((400,) if small else ()):
            out.append(Case(f"map-{name}-m{m}", "map", m, name, quick=m in (75, 150)))
    return tuple(out)


CASES = _cases()


def build(case: Case, seed: int):
    """``(problem, note)`` of ``case`` for ``seed``."""
    from . import heldout_worlds as hw

    if case.family == "letter":
        return hw.letter_world(case.m, seed)
    if case.family == "random":
        problem = hw.random_problem(case.m, seed)
        return problem, f"{len(problem.obstacles)} obstacles"
    if case.family == "door":
        return hw.door_problem(float(case.param), case.m, seed), ""
    if case.family == "map":
        return hw.map_problem(case.param, case.m, seed), ""
    raise ValueError(f"unknown family {case.family!r}")


def time_target(case: Case) -> float:
    """The planning-time target [s] of a map row (``inf``: none)."""
    if case.family != "map":
        return math.inf
    if case.m <= 100:
        return 3.0
    if case.m <= 200:
        return 10.0
    if case.m <= 400 and ("room" in case.param or "warehouse" in case.param):
        return 30.0
    return math.inf


def judge(case: Case, row: dict, time_limit: float) -> tuple[str, str]:
    """``(target, meets)`` of a row."""
    if case.family == "door" and float(case.param) == DOOR_LIMIT and case.m >= 200:
        target = f"ok, x_cut<={DOOR_X:g}"
        x = row.get("x_cut", math.nan)
        if row.get("ok") is not True:
            return target, "no"
        return target, "?" if math.isnan(x) else ("yes" if x <= DOOR_X else "no")
    if case.family != "map":
        return f"ok, t<={time_limit:g}s", "yes" if row.get("ok") is True else "no"
    limit = time_target(case)
    target = f"ok, x_geo<={GEO_LIMIT:g}" + (f", t<={limit:g}s" if math.isfinite(limit) else "")
    if row.get("ok") is not True or row.get("time_s", math.inf) > limit:
        return target, "no"
    x = row.get("x_geo", math.nan)
    if math.isnan(x):
        return target, "?"
    return target, "yes" if x <= GEO_LIMIT else "no"


def _maxrss_mb() -> float:
    import resource

    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return rss / (1024.0 * 1024.0) if sys.platform == "darwin" else rss / 1024.0


def planner_digest() -> str:
    """A short digest of the planner's source as this process sees it (runs may span edits)."""
    import zlib
    from pathlib import Path

    files = sorted((Path(__file__).resolve().parents[1] / "planner").glob("*.py"))
    return f"{zlib.crc32(b''.join(f.read_bytes() for f in files)):08x}"


def run_one(case: Case, seed: int, time_limit: float, geo_budget: float) -> dict:
    """One case and seed (meant for a fresh process): feasibility, plan, bounds."""
    from planner import NoPlanFound, PlannerParams, feasibility, plan
    from planner.bounds import lower_bounds
    from planner.geobound import geo_lower_bound

    from ._common import warm_up_planner

    warm_up_planner(min(time_limit, 10.0))
    problem, note = build(case, seed)
    row = {"case": case.name, "m": case.m, "seed": seed, "note": note, "planner": planner_digest()}
    proof = feasibility(problem)
    if proof is not None:
        row.update(ok="unsolvable", note=f"proven unsolvable: {proof.reason}"[:60])
        return row
    t0 = time.perf_counter()
    try:
        result, stats = plan(problem, PlannerParams(time_limit=time_limit), np.random.default_rng([7919, seed]))
    except NoPlanFound as exc:
        row.update(ok=False, time_s=time.perf_counter() - t0, peak_mb=_maxrss_mb(),
                   note=(note + " " + str(exc)[:50]).strip())
        return row
    row.update(ok=True, time_s=stats.planning_time_s, peak_mb=_maxrss_mb(), makespan_s=result.makespan)
    stage = stats.extra.get("direct", stats.extra.get("method", "roadmap"))
    row["note"] = f"{note} {stage}".strip()
    straight = stats.makespan_lower_bound_s
    if not math.isfinite(straight):
        straight = lower_bounds(problem)[0]
    geo = stats.makespan_lower_bound_geo_s
    if math.isnan(geo):
        try:
            geo = geo_lower_bound(problem, deadline=time.perf_counter() + geo_budget)
        except TimeoutError:
            geo = math.nan
            row["note"] += ", geo bound timed out"
    cut = float(getattr(stats, "makespan_lower_bound_cut_s", math.nan))
    for key, bound in (("x_straight", straight), ("x_geo", geo), ("x_cut", cut)):
        row[key] = result.makespan / bound if bound > 0 and math.isfinite(bound) else math.nan
    return row


def summary(family: str, rows: list[dict]) -> str:
    """One line: solved share, worst ratios, worst time, how many meet their target."""
    ok = [r for r in rows if r.get("ok") is True]

    def worst(key):
        v = [r[key] for r in ok if not math.isnan(r.get(key, math.nan))]
        return f"{max(v):.3g}" if v else "-"

    times = [r["time_s"] for r in rows if "time_s" in r]
    meets = sum(r.get("meets") == "yes" for r in rows)
    return (f"- **{family}**: solved {len(ok)}/{len(rows)} ({100 * len(ok) / max(1, len(rows)):.0f} %), "
            f"worst x_straight {worst('x_straight')}, worst x_geo {worst('x_geo')}, worst x_cut {worst('x_cut')}, "
            f"worst time {max(times):.3g} s, meets target {meets}/{len(rows)}" if times else
            f"- **{family}**: no runs finished ({len(rows)} rows)")


def _parse(argv):
    ap = argparse.ArgumentParser(prog="python -m bench.heldout", description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="a smaller set of cases, one seed each")
    ap.add_argument("--seeds", type=int, default=None, help="seeds 0..N-1 per case (default 2; 1 with --quick)")
    ap.add_argument("--time-limit", type=float, default=60.0, help="planning time limit per run [s] (default 60)")
    ap.add_argument("--geo-budget", type=float, default=60.0,
                    help="time for the obstacle-respecting bound when the planner left it out [s] (default 60)")
    ap.add_argument("--cases", nargs="+", default=None, help="case names or prefixes (default: all)")
    ap.add_argument("--list", action="store_true", help="list the cases and exit")
    args = ap.parse_args(argv)
    if args.seeds is not None and args.seeds < 1:
        ap.error(f"--seeds must be >= 1, got {args.seeds}")
    if not args.time_limit > 0:
        ap.error(f"--time-limit must be > 0, got {args.time_limit}")
    return args


def main(argv: list[str] | None = None) -> list[dict]:
    """Run the benchmark, print the tables, return the rows."""
    args = _parse(argv)
    cases = [c for c in CASES if (not args.quick or c.quick)
             and (args.cases is None or any(c.name == p or c.name.startswith(p) for p in args.cases))]
    if args.list:
        print("\n".join(c.name for c in cases))
        return []
    seeds = args.seeds or (1 if args.quick else 2)
    timeout = args.time_limit * 1.5 + args.geo_budget + 180.0
    rows = []
    for case in cases:
        for seed in range(seeds):
            row = in_fresh_process(run_one, (case, seed, args.time_limit, args.geo_budget), timeout)
            if "error" in row:
                row = {"case": case.name, "m": case.m, "seed": seed, "ok": "error", "note": row["error"][:80]}
            row["target"], row["meets"] = judge(case, row, args.time_limit)
            row["family"] = case.family
            rows.append(row)
            print(markdown_table(COLUMNS, [row]).split("\n")[-1], file=sys.stderr, flush=True)
    print("# swarmform held-out benchmark\n\n" + machine_info())
    print(f"- settings: time limit {args.time_limit:g} s, auto mode, seeds 0..{seeds - 1}, planner source "
          f"{planner_digest()} at the end (column planner: as each run saw it), "
          f"{'--quick' if args.quick else 'all cases'}\n")
    for family in ("letter", "random", "door", "map"):
        part = [r for r in rows if r["family"] == family]
        if part:
            print(f"## {family}\n\n{markdown_table(COLUMNS, part)}\n\n{summary(family, part)}\n")
    return rows


if __name__ == "__main__":
    main()
