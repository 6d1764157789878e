"""swarmform's planner against the planners a user would otherwise reach for.

Run ``python -m bench.peers`` (``--help`` for the options).  On each case
and seed the same problem goes to:

* **swarmform**: :func:`planner.plan` in auto mode (``g = q = None``) with
  the time limit, timed by wall clock around the call, after an untimed
  warm-up (:func:`bench._common.warm_up_planner`: lazy imports and
  first-call costs, as OMPL's time starts after its imports);
* **RRTConnect** and **PRM** from OMPL 2.x (PyPI ``ompl``): one
  ``2m``-dimensional ``RealVectorStateSpace`` (robot ``i`` is coordinates
  ``2i, 2i + 1``) bounded per robot by the workspace shrunk by the wall
  clearance (states outside are invalid anyway, so this only saves OMPL
  wasted samples); the goal state is the start's minimum-sum assignment
  to the targets.  The state validity checker is a Python function: every
  pair of robots separated and every robot clear
  (``problem.env.point_clearance``).  The motion validator is a Python
  ``MotionValidator`` subclass that checks the straight composite motion
  *exactly* (pairs by :func:`planner.geometry.closest_approach`, obstacles
  and walls by ``problem.env.segment_clearance``), so nothing is sampled
  along an edge; OMPL calls back into Python for every check, as any
  Python user's setup would.  Each solve runs in a forked child process with OMPL's own
  time limit and a hard deadline (time limit + simplification budget +
  grace) after which the child is killed; a found path is shortened with
  ``PathSimplifier.simplify`` within a small budget.  OMPL's time is the
  child's wall time from building the space to the simplified path.
* **straight lines**: every robot straight to its minimum-sum assigned
  target in one step, obstacles ignored (CAPT-style).

Every returned path (swarmform's plan too) is timed as a
:class:`planner.Plan` (path states as waypoints, shared minimum-jerk
scaling) and checked by :func:`planner.check_plan`; a path the exact
validator rejects counts as a failure and is reported in its own column.

Default cases: the paper family is the five figure scenarios plus Table
II rows 1, 4, 7 and 10 and Table III row 2 (every formation type appears
as a start or a target, m = 7 to 11); all 23 paper scenarios at 10 seeds
would take well over an hour, mostly OMPL running into the time limit.
The dense family is random start and target placements (uniform, clear,
separated) for m = 20 and 30 robots in a 40 x 40 workspace with three
random convex obstacles of diameter 4 to 8.
Seed ``s`` builds the problem with ``np.random.default_rng(s)`` (random
obstacles, formation rotations and centres), swarmform continues with that
generator, OMPL's generator is seeded with ``s + 1``.
"""

from __future__ import annotations

import argparse
import glob
import math
import multiprocessing as mp
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from planner import NoPlanFound, Plan, PlannerParams, Problem, plan
from planner.bounds import lower_bounds
from planner.geometry import closest_approach

from ._common import (
    assigned_targets,
    machine_info,
    markdown_table,
    percentile,
    random_problem,
    straight_line_waypoints,
    timed_plan,
    verify,
    warm_up_planner,
)

__all__ = [
    "COLUMNS",
    "Case",
    "DEFAULT_PAPER",
    "OMPL_PLANNERS",
    "PLANNERS",
    "Outcome",
    "Run",
    "LACAM",
    "STRAIGHT",
    "SWARMFORM",
    "dense_cases",
    "format_report",
    "main",
    "ompl_available",
    "lacam_available",
    "run_case",
    "run_lacam",
    "run_ompl",
    "run_straight",
    "run_swarmform",
    "scenario_cases",
    "summarize",
]

_ROOT = Path(__file__).resolve().parents[1]

DEFAULT_PAPER = (
    "fig1-line-to-phi",
    "fig2-random-to-C",
    "fig3-random-to-line",
    "fig4-line-to-N",
    "fig5-N-to-A",
    "tableII-row01-random-to-random-m8",
    "tableII-row04-line-to-phi-m11",
    "tableII-row07-line-to-line-m10",
    "tableII-row10-random-to-M-m11",
    "tableIII-row02-C-to-lambda-m7",
)
"""The default paper scenarios (file stems under ``scenarios/paper``)."""

SWARMFORM = "swarmform"
STRAIGHT = "straight lines"
LACAM = "LaCAM (grid)"
OMPL_PLANNERS = ("RRTConnect", "PRM")
PLANNERS = (SWARMFORM, *OMPL_PLANNERS, LACAM, STRAIGHT)
_PLANNER_KEYS = {"swarmform": SWARMFORM, "rrtconnect": "RRTConnect", "prm": "PRM", "lacam": LACAM,
                 "straight": STRAIGHT}

_GRACE_S = 5.0  # extra wall time before a silent OMPL child is killed [s]


# ----------------------------------------------------------------------------
# cases and records


@dataclass(frozen=True)
class Case:
    """A problem family member: ``build(rng)`` makes the problem for one seed."""

    family: str
    name: str
    m: int
    build: Callable[[np.random.Generator], Problem]


@dataclass
class Outcome:
    """What one planner returned on one problem.

    plan: the timed path, or ``None`` when the planner returned none.
    time_s: wall time the planner took [s].
    status: the planner's own word (``found``, ``no plan``, ``Timeout``, ...).
    """

    plan: Plan | None
    time_s: float
    status: str


@dataclass
class Run:
    """One planner on one case and seed, after the exact check.

    solved: a path was returned and the exact validator accepted it.
    invalid: a path was returned and the exact validator rejected it.
    time_s: planner wall time [s]; makespan_s: the plan's makespan [s]
    (NaN unless solved); lower_bound_s: the problem's makespan lower bound [s].
    """

    family: str
    case: str
    m: int
    seed: int
    planner: str
    solved: bool
    invalid: bool
    time_s: float
    makespan_s: float
    lower_bound_s: float
    status: str
    detail: str = ""


# ----------------------------------------------------------------------------
# the planners


def run_swarmform(problem: Problem, time_limit: float, rng: np.random.Generator) -> Outcome:
    """swarmform's planner in auto mode."""
    t0 = time.perf_counter()
    try:
        result, _ = plan(problem, PlannerParams(time_limit=time_limit), rng)
    except NoPlanFound:
        return Outcome(None, time.perf_counter() - t0, "no plan")
    return Outcome(result, time.perf_counter() - t0, "found")


def run_straight(problem: Problem) -> Outcome:
    """Straight lines to the minimum-sum assigned targets, in one step (obstacles ignored)."""
    t0 = time.perf_counter()
    waypoints = straight_line_waypoints(problem)
    elapsed = time.perf_counter() - t0
    return Outcome(timed_plan(problem, waypoints), elapsed, "found")


def lacam_available() -> bool:
    """Whether pymapf's LaCAM imports."""
    try:
        from pymapf.algorithms.lacam import LaCAM  # noqa: F401
    except ImportError:
        return False
    return True


def run_lacam(problem: Problem, time_limit: float, seed: int) -> Outcome:
    """LaCAM (pymapf) on a grid of the workspace, after the assignment.

    The grid's cells are ``sqrt(2)`` separations wide: the smallest cell for
    which every grid MAPF step (distinct cells, no swaps, following allowed)
    keeps two robots the separation apart.  A cell is free when its centre
    is clear and so is its segment to every free 4-neighbour (found by
    dropping cells until that holds), so that grid moves never clip an
    obstacle.  Starts and targets go to distinct free cells (minimum sum of
    squared distances), starts are assigned targets (minimum sum of grid
    cell distances), and LaCAM solves the labeled grid problem.  The plan:
    every robot straight to its start cell, the grid paths one time step
    per step, every robot straight to its target; checked exactly like the
    others (a robot's first or last straight move may clip another's).
    """
    from pymapf.algorithms.lacam import LaCAM
    from pymapf.core.grid import GridMap
    from pymapf.core.solver import Agent, MAPFProblem
    from scipy.optimize import linear_sum_assignment
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import min_weight_full_bipartite_matching
    from scipy.spatial import cKDTree

    t0 = time.perf_counter()
    c = problem.clearance
    a = math.sqrt(2.0) * problem.separation * (1 + 1e-6)
    nx = int((problem.width - 2 * c) // a) + 1
    ny = int((problem.height - 2 * c) // a) + 1
    xs, ys = c + a * np.arange(nx), c + a * np.arange(ny)
    centres = np.stack(np.meshgrid(xs, ys, indexing="ij"), axis=-1)  # (nx, ny, 2)
    free = problem.env.points_clear(centres.reshape(-1, 2), c).reshape(nx, ny)
    for _ in range(nx + ny):  # drop cells with a blocked edge to a free neighbour
        bad = np.zeros_like(free)
        for dx, dy in ((1, 0), (0, 1)):
            u = free[: nx - dx, : ny - dy] & free[dx:, dy:]
            pa = centres[: nx - dx, : ny - dy][u]
            pb = centres[dx:, dy:][u]
            clear = problem.env.segments_clear(pa, pb, c)
            blocked = np.zeros_like(u)
            blocked[u] = ~clear
            bad[: nx - dx, : ny - dy] |= blocked
        if not bad.any():
            break
        free &= ~bad
    cells = np.argwhere(free)
    pts = centres[free]
    if len(pts) < problem.m:
        return Outcome(None, time.perf_counter() - t0, "grid too small")

    def snap(placement):
        k = min(16, len(pts))
        d, j = cKDTree(pts).query(placement, k=k)
        w = np.asarray(d).ravel() ** 2 + 1e-9
        mat = csr_matrix((w, (np.repeat(np.arange(len(placement)), k), np.asarray(j).ravel())),
                         shape=(len(placement), len(pts)))
        return min_weight_full_bipartite_matching(mat)[1]

    try:
        sc, tc = snap(problem.start), snap(problem.target)
    except ValueError:
        return Outcome(None, time.perf_counter() - t0, "no cells")
    manhattan = np.abs(cells[sc][:, None] - cells[tc][None]).sum(axis=2)
    _, goal = linear_sum_assignment(manhattan)
    grid = GridMap((~free).T.astype(int).tolist())  # rows = y, columns = x
    agents = [Agent(f"r{i}", (int(cells[sc[i], 1]), int(cells[sc[i], 0])),
                    (int(cells[tc[goal[i]], 1]), int(cells[tc[goal[i]], 0]))) for i in range(problem.m)]
    remaining = time_limit - (time.perf_counter() - t0)
    if remaining <= 0:
        return Outcome(None, time.perf_counter() - t0, "Timeout")
    sol = LaCAM(time_limit=remaining, seed=seed).solve(MAPFProblem(grid, agents))
    if sol is None:
        return Outcome(None, time.perf_counter() - t0, "no plan")
    paths = [sol.paths[f"r{i}"] for i in range(problem.m)]
    steps = max(len(p) for p in paths)
    w = [problem.start]
    for t in range(steps):
        w.append(np.array([centres[p[min(t, len(p) - 1)][1], p[min(t, len(p) - 1)][0]] for p in paths]))
    w.append(problem.target[goal])
    elapsed = time.perf_counter() - t0
    return Outcome(timed_plan(problem, _drop_repeats(np.asarray(w))), elapsed, "found")


def _drop_repeats(w: np.ndarray) -> np.ndarray:
    keep = [0] + [k for k in range(1, len(w)) if not np.array_equal(w[k], w[k - 1])]
    return w[keep]


def ompl_available() -> bool:
    """Whether OMPL's Python bindings import."""
    try:
        import ompl.base  # noqa: F401
        import ompl.geometric  # noqa: F401
    except ImportError:
        return False
    return True


def _checkers(problem: Problem):
    """``(state_valid(points), motion_valid(a, b))`` on ``(m, 2)`` arrays, both exact."""
    m = problem.m
    env = problem.env
    clr, sep = problem.clearance, problem.separation
    i, j = np.triu_indices(m, 1)

    def state_valid(p: np.ndarray) -> bool:
        if m > 1:
            d = p[i] - p[j]
            if np.min(np.hypot(d[:, 0], d[:, 1])) < sep:
                return False
        return bool(np.min(env.point_clearance(p)) >= clr)

    def motion_valid(a: np.ndarray, b: np.ndarray) -> bool:
        # All robots move together on straight segments: the closest
        # approach of each pair and each segment's clearance are exact.
        if m > 1 and np.min(closest_approach(a[i], b[i], a[j], b[j])) < sep:
            return False
        return bool(np.min(env.segment_clearance(a, b)) >= clr)

    return state_valid, motion_valid


def _ompl_solve(problem: Problem, goal: np.ndarray, name: str, time_limit: float,
                simplify_s: float, seed: int) -> dict:
    """Solve with OMPL's ``name`` planner in this process; the result as plain data."""
    from ompl import base as ob
    from ompl import geometric as og
    from ompl import util as ou

    ou.setLogLevel(ou.LogLevel.LOG_NONE)
    ou.RNG.setSeed(seed)
    t0 = time.perf_counter()
    m, n = problem.m, 2 * problem.m
    state_valid, motion_valid = _checkers(problem)
    counts = {"states": 0, "motions": 0}

    def is_valid(state) -> bool:
        counts["states"] += 1
        return state_valid(np.array(state[0:n]).reshape(m, 2))

    class ExactMotionValidator(ob.MotionValidator):
        def checkMotion(self, s1, s2):  # noqa: N802 (OMPL's name)
            counts["motions"] += 1
            return motion_valid(np.array(s1[0:n]).reshape(m, 2), np.array(s2[0:n]).reshape(m, 2))

    space = ob.RealVectorStateSpace(n)
    bounds = ob.RealVectorBounds(n)
    clr = problem.clearance
    for k in range(m):
        bounds.setLow(2 * k, clr)
        bounds.setHigh(2 * k, problem.width - clr)
        bounds.setLow(2 * k + 1, clr)
        bounds.setHigh(2 * k + 1, problem.height - clr)
    space.setBounds(bounds)
    si = ob.SpaceInformation(space)
    si.setStateValidityChecker(is_valid)
    validator = ExactMotionValidator(si)
    si.setMotionValidator(validator)
    si.setup()
    start, target = space.allocState(), space.allocState()
    for k, v in enumerate(np.asarray(problem.start, float).ravel()):
        start[k] = float(v)
    for k, v in enumerate(np.asarray(goal, float).ravel()):
        target[k] = float(v)
    pdef = ob.ProblemDefinition(si)
    pdef.setStartAndGoalStates(start, target)
    planner = {"RRTConnect": og.RRTConnect, "PRM": og.PRM}[name](si)
    planner.setProblemDefinition(pdef)
    planner.setup()
    status = planner.solve(time_limit)
    solve_s = time.perf_counter() - t0
    out = {"status": status.asString(), "exact": bool(pdef.hasExactSolution()), "waypoints": None,
           "solve_s": solve_s, "states_before": 0, "states_after": 0}
    if out["exact"]:
        path = pdef.getSolutionPath()
        out["states_before"] = path.getStateCount()
        if simplify_s > 0:
            og.PathSimplifier(si).simplify(path, simplify_s)
        out["states_after"] = path.getStateCount()
        out["waypoints"] = np.array([s[0:n] for s in path.getStates()], float).reshape(-1, m, 2)
    out["time_s"] = time.perf_counter() - t0
    out.update(state_checks=counts["states"], motion_checks=counts["motions"])
    return out


def _ompl_child(conn, problem, goal, name, time_limit, simplify_s, seed):
    try:
        result = _ompl_solve(problem, goal, name, time_limit, simplify_s, seed)
    except Exception as exc:  # reported to the parent, which records the failure
        result = {"status": f"error: {exc!r}", "exact": False, "waypoints": None}
    conn.send(result)
    conn.close()


def _context():
    methods = mp.get_all_start_methods()
    return mp.get_context("fork" if "fork" in methods else "spawn")


def run_ompl(problem: Problem, name: str, time_limit: float, seed: int,
             simplify_s: float | None = None) -> Outcome:
    """OMPL's ``name`` (``RRTConnect`` or ``PRM``) in a child process with a hard deadline.

    ``simplify_s`` is the path simplification budget [s] (default: a tenth
    of the time limit, at most 1 s).  A child that has not answered by the
    time limit plus the budget plus a grace period is killed and the run
    counts as a failure (``hung``).
    """
    if simplify_s is None:
        simplify_s = min(1.0, 0.1 * time_limit)
    goal = assigned_targets(problem)
    ctx = _context()
    recv, send = ctx.Pipe(duplex=False)
    proc = ctx.Process(target=_ompl_child, args=(send, problem, goal, name, time_limit, simplify_s, seed),
                       daemon=True)
    t0 = time.perf_counter()
    proc.start()
    send.close()
    result = None
    try:
        if recv.poll(time_limit + simplify_s + _GRACE_S):
            result = recv.recv()
    except EOFError:
        result = {"status": "crashed", "exact": False, "waypoints": None}
    finally:
        wall = time.perf_counter() - t0
        if proc.is_alive():
            proc.kill()
        proc.join()
        recv.close()
    if result is None:
        return Outcome(None, wall, "hung (killed)")
    elapsed = result.get("time_s", wall)
    if result.get("waypoints") is None:
        return Outcome(None, elapsed, result["status"])
    return Outcome(timed_plan(problem, result["waypoints"]), elapsed, result["status"])


# ----------------------------------------------------------------------------
# cases


def _resolve(pattern: str) -> list[Path]:
    hits = sorted(glob.glob(pattern))
    if not hits and not Path(pattern).is_absolute():
        hits = sorted(glob.glob(str(_ROOT / pattern)))
    return [Path(h) for h in hits]


def scenario_cases(patterns: list[str] | None = None) -> list[Case]:
    """Cases from scenario files (globs); the family is the file's folder name.

    Without patterns: the default paper subset (:data:`DEFAULT_PAPER`).
    """
    from sim.scenario import build_problem, read_scenario

    if patterns is None:
        paths = [_ROOT / "scenarios" / "paper" / f"{stem}.yaml" for stem in DEFAULT_PAPER]
    else:
        paths = []
        for pat in patterns:
            found = _resolve(pat)
            if not found:
                raise SystemExit(f"--scenarios: no file matches {pat!r}")
            paths.extend(p for p in found if p not in paths)
    cases = []
    for path in paths:
        sc = read_scenario(path)
        cases.append(Case(path.parent.name, sc.name, sc.count, lambda rng, sc=sc: build_problem(sc, rng)))
    return cases


def dense_cases(sizes: list[int], side: float = 40.0) -> list[Case]:
    """Random start and target placements for each ``m`` in a ``side`` x ``side`` workspace, 3 obstacles."""
    return [
        Case("dense", f"random-to-random-m{m}", m, lambda rng, m=m: random_problem(m, side, rng))
        for m in sizes
    ]


# ----------------------------------------------------------------------------
# running


def _record(case: Case, seed: int, name: str, problem: Problem, lb: float, out: Outcome) -> Run:
    if out.plan is None:
        return Run(case.family, case.name, case.m, seed, name, False, False, out.time_s, math.nan, lb, out.status)
    check = verify(problem, out.plan)
    return Run(case.family, case.name, case.m, seed, name, check.valid, not check.valid, out.time_s,
               check.makespan_s if check.valid else math.nan, lb, out.status, check.reason)


def run_case(case: Case, seed: int, time_limit: float, planners=PLANNERS,
             simplify_s: float | None = None) -> list[Run]:
    """Every planner in ``planners`` on one case and seed (the same problem for all)."""
    rng = np.random.default_rng(seed)
    problem = case.build(rng)
    lb = lower_bounds(problem)[0]
    runs = []
    for name in planners:
        if name == SWARMFORM:
            out = run_swarmform(problem, time_limit, rng)
        elif name == STRAIGHT:
            out = run_straight(problem)
        elif name == LACAM:
            out = run_lacam(problem, time_limit, seed)
        else:
            out = run_ompl(problem, name, time_limit, seed + 1, simplify_s)
        runs.append(_record(case, seed, name, problem, lb, out))
    return runs


# ----------------------------------------------------------------------------
# summaries

COLUMNS = [
    "planner",
    "runs",
    "success",
    "invalid paths",
    "median time [s]",
    "median makespan / LB",
    "time / swarmform (median)",
    "time / swarmform (min)",
    "under 10x swarmform",
    "solved where swarmform failed",
    "swarmform success where it failed",
]
"""Columns of a family table (the keys of :func:`summarize`'s rows besides ``family``)."""

_FAST = 10.0  # the speed-up over a peer that the "under 10x" column counts against


def summarize(runs: list[Run]) -> list[dict]:
    """One row per family and planner.

    ``success`` is the share of runs whose path passed the exact check;
    ``invalid paths`` counts returned paths it rejected.  Times and
    makespan ratios are medians over the planner's solved runs.  The time
    ratio to swarmform is taken per run (same case and seed) over the runs
    both solved: the median and the minimum of those ratios (above 1:
    swarmform was faster), and how many of them are below 10.  The last two
    columns compare success: runs this planner solved and swarmform did
    not, and swarmform's success rate on the runs this planner failed.
    """
    rows = []
    families = list(dict.fromkeys(r.family for r in runs))
    for fam in families:
        fr = [r for r in runs if r.family == fam]
        ref = {(r.case, r.seed): r for r in fr if r.planner == SWARMFORM}
        for name in dict.fromkeys(r.planner for r in fr):
            pr = [r for r in fr if r.planner == name]
            ok = [r for r in pr if r.solved]
            row = {
                "family": fam,
                "planner": name,
                "runs": len(pr),
                "success": len(ok) / len(pr),
                "invalid paths": sum(r.invalid for r in pr),
                "median time [s]": percentile([r.time_s for r in ok], 50),
                "median makespan / LB": percentile([r.makespan_s / r.lower_bound_s for r in ok], 50),
            }
            if name == SWARMFORM or not ref:
                row.update({c: "-" for c in COLUMNS[6:]})
                row["time / swarmform (median)"] = row["time / swarmform (min)"] = math.nan
            else:
                paired = [(r, ref[(r.case, r.seed)]) for r in pr if (r.case, r.seed) in ref]
                ratios = [r.time_s / s.time_s for r, s in paired if r.solved and s.solved]
                lost = [s for r, s in paired if not r.solved]
                row["time / swarmform (median)"] = percentile(ratios, 50)
                row["time / swarmform (min)"] = min(ratios) if ratios else math.nan
                row["under 10x swarmform"] = sum(q < _FAST for q in ratios)
                row["solved where swarmform failed"] = sum(r.solved and not s.solved for r, s in paired)
                row["swarmform success where it failed"] = (
                    sum(s.solved for s in lost) / len(lost) if lost else math.nan)
            rows.append(row)
    return rows


def _case_table(runs: list[Run], family: str) -> str:
    fr = [r for r in runs if r.family == family]
    names = list(dict.fromkeys(r.planner for r in fr))
    rows = []
    for case in dict.fromkeys(r.case for r in fr):
        cr = [r for r in fr if r.case == case]
        row = {"case": case, "m": cr[0].m}
        for name in names:
            pr = [r for r in cr if r.planner == name]
            ok = [r.time_s for r in pr if r.solved]
            t = f", {percentile(ok, 50):.3g} s" if ok else ""
            bad = sum(r.invalid for r in pr)
            row[name] = f"{len(ok)}/{len(pr)}{t}" + (f" ({bad} invalid)" if bad else "")
        rows.append(row)
    return markdown_table(["case", "m", *names], rows)


def format_report(runs: list[Run], settings: str = "") -> str:
    """Machine, settings, then per family: the summary table and the per-case table."""
    parts = ["# swarmform vs peers", "", machine_info()]
    if settings:
        parts.append(settings)
    rows = summarize(runs)
    for fam in dict.fromkeys(r.family for r in runs):
        parts += ["", f"## {fam}", "", markdown_table(COLUMNS, [r for r in rows if r["family"] == fam]), "",
                  "Per case: solved/seeds, median planning time of the solved runs.", "",
                  _case_table(runs, fam)]
    bad = [r for r in runs if r.invalid and r.planner != STRAIGHT]
    if bad:
        parts += ["", "Paths rejected by the exact validator (besides straight lines):", ""]
        parts += [f"- {r.planner} on {r.case} seed {r.seed}: {r.detail}" for r in bad]
    return "\n".join(parts)


# ----------------------------------------------------------------------------
# entry point


def _parse(argv):
    ap = argparse.ArgumentParser(prog="python -m bench.peers", description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", type=int, default=None, help="seeds 0..N-1 per case (default 10; --quick: 2)")
    ap.add_argument("--time-limit", type=float, default=None,
                    help="planning time limit per run [s] (default 10; --quick: 2)")
    ap.add_argument("--scenarios", nargs="+", metavar="GLOB",
                    help="scenario files instead of the default paper subset (family = folder name)")
    ap.add_argument("--dense", type=int, nargs="*", default=None, metavar="M",
                    help="robot counts of the dense random family (default 20 30; none: skip it)")
    ap.add_argument("--planners", nargs="+", choices=sorted(_PLANNER_KEYS), default=sorted(_PLANNER_KEYS),
                    help="which planners to run (default all)")
    ap.add_argument("--simplify", type=float, default=None,
                    help="OMPL path simplification budget [s] (default min(1, time limit / 10))")
    ap.add_argument("--json", metavar="PATH", help="also write every run as JSON (one record per planner run)")
    ap.add_argument("--quick", action="store_true",
                    help="a few minutes' run: 2 seeds, 2 s limit, 3 paper scenarios, dense m = 20")
    args = ap.parse_args(argv)
    if args.seeds is not None and args.seeds < 1:
        ap.error(f"--seeds must be an int >= 1, got {args.seeds}")
    if args.time_limit is not None and not args.time_limit > 0:
        ap.error(f"--time-limit must be > 0, got {args.time_limit}")
    if args.dense and min(args.dense) < 2:
        ap.error(f"--dense robot counts must be ints >= 2, got {min(args.dense)}")
    return args


def main(argv: list[str] | None = None) -> list[dict]:
    """Run the benchmark, print the report, return the summary rows (see :data:`COLUMNS`)."""
    args = _parse(argv)
    seeds = args.seeds if args.seeds is not None else (2 if args.quick else 10)
    limit = args.time_limit if args.time_limit is not None else (2.0 if args.quick else 10.0)
    dense = args.dense if args.dense is not None else ([20] if args.quick else [20, 30])
    if args.scenarios is not None:
        cases = scenario_cases(args.scenarios)
    elif args.quick:
        cases = [c for c in scenario_cases() if c.name in DEFAULT_PAPER[1:2] + DEFAULT_PAPER[4:6]]
    else:
        cases = scenario_cases()
    cases += dense_cases(dense)
    planners = [p for p in PLANNERS if p in {_PLANNER_KEYS[k] for k in args.planners}]
    note = ""
    if any(p in OMPL_PLANNERS for p in planners) and not ompl_available():
        planners = [p for p in planners if p not in OMPL_PLANNERS]
        note = " (ompl is not importable: OMPL planners skipped)"
    if LACAM in planners and not lacam_available():
        planners = [p for p in planners if p != LACAM]
        note += " (pymapf is not importable: LaCAM skipped)"
    simplify_s = args.simplify if args.simplify is not None else min(1.0, 0.1 * limit)
    if SWARMFORM in planners:
        warm_up_planner(limit)  # OMPL's time starts after its imports too
    runs = []
    for case in cases:
        for seed in range(seeds):
            done = run_case(case, seed, limit, planners, simplify_s)
            runs += done
            # Progress on stderr, so that stdout stays the Markdown report.
            print(f"{case.name} seed {seed}: " + ", ".join(
                f"{r.planner} {'ok' if r.solved else ('invalid' if r.invalid else 'failed')} {r.time_s:.3g} s"
                for r in done), file=sys.stderr, flush=True)
    settings = (
        f"- settings: seeds 0..{seeds - 1}, time limit {limit:g} s, OMPL simplification budget "
        f"{simplify_s:g} s, planners: {', '.join(planners)}{note}\n"
        f"- times are wall-clock per run (swarmform: the plan() call including its own exact check; "
        f"OMPL: space setup + solve + simplification in the child process; straight lines: the "
        f"assignment); LB = makespan lower bound (planner.bounds.lower_bounds)"
    )
    print(format_report(runs, settings), flush=True)
    if args.json:
        _write_json(args.json, runs)
    return summarize(runs)


def _write_json(path: str, runs: list[Run]) -> None:
    import json
    from dataclasses import asdict

    def clean(v):
        return None if isinstance(v, float) and not math.isfinite(v) else v

    records = [{k: clean(v) for k, v in asdict(r).items()} for r in runs]
    Path(path).write_text(json.dumps(records, indent=1) + "\n", encoding="utf-8")


if __name__ == "__main__":
    main()
