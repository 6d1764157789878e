"""Helpers shared by the planner benchmarks: random problems, exact checks of peer paths, tables.

Everything here uses the planner's public API only (``Problem``, ``Plan``,
``check_plan``, the environment's exact clearance kernels and the lower
bounds), so the benchmarks keep measuring whatever the planner currently is.
"""

from __future__ import annotations

import datetime
import math
import os
import platform
import sys
from dataclasses import dataclass
from importlib.metadata import PackageNotFoundError, version

import numpy as np
from scipy.optimize import linear_sum_assignment

from planner import Plan, PlanInvalid, Polygon, Problem, check_plan

__all__ = [
    "MARGIN",
    "PathCheck",
    "RADIUS",
    "assigned_targets",
    "timed_plan",
    "verify",
    "machine_info",
    "markdown_table",
    "percentile",
    "random_problem",
    "scaled_problem",
    "side_for",
    "straight_line_waypoints",
    "warm_up_planner",
]

RADIUS = 1.0  # robot radius of the paper's scenarios [workspace units]
MARGIN = 0.1  # safety margin of the paper's scenarios [workspace units]


# ----------------------------------------------------------------------------
# warm-up


def warm_up_planner(time_limit: float = 10.0) -> None:
    """Untimed runs, so that lazy imports and first-call costs stay out of the measurements.

    The scipy modules the planner imports where it first needs them, then
    a small random problem in auto mode (often solved by the direct tries
    alone) and at fixed g and q (which always samples pebble graphs and
    connects them).  Seeded apart from every measured run.
    """
    import scipy.optimize  # noqa: F401
    import scipy.sparse.csgraph  # noqa: F401
    import scipy.spatial  # noqa: F401

    from planner import NoPlanFound, PlannerParams, plan

    warm = np.random.default_rng(10**6)
    for params in (PlannerParams(time_limit=time_limit), PlannerParams(g=1, q=16, time_limit=time_limit)):
        try:
            plan(scaled_problem(3, warm), params, warm)
        except NoPlanFound:
            pass


# ----------------------------------------------------------------------------
# random problems


def _random_polygon(rng: np.random.Generator, diameter: float, width: float, height: float) -> Polygon:
    """A convex polygon: 3 to 8 vertices at sorted random angles on a circle of ``diameter``."""
    while True:
        k = int(rng.integers(3, 9))
        ang = np.sort(rng.uniform(0.0, 2.0 * np.pi, size=k))
        rad = diameter / 2.0
        c = rng.uniform([rad, rad], [width - rad, height - rad])
        v = c + rad * np.stack([np.cos(ang), np.sin(ang)], axis=1)
        x, y = v[:, 0], v[:, 1]
        area = 0.5 * abs(float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y)))
        if area >= 0.05 * diameter**2:  # not a sliver
            return Polygon(v)


def _free_points(shell: Problem, m: int, rng: np.random.Generator, max_batches: int = 500) -> np.ndarray:
    """``m`` points uniform in the workspace, clear of walls and obstacles, pairwise separated.

    Candidates are drawn in batches and accepted in order when clear and at
    least ``shell.separation`` from every point accepted so far.
    """
    clr, sep = shell.clearance, shell.separation
    lo = np.array([clr, clr])
    hi = np.array([shell.width - clr, shell.height - clr])
    pts = np.zeros((0, 2))
    for _ in range(max_batches):
        cand = rng.uniform(lo, hi, size=(max(64, 4 * m), 2))
        for p in cand[shell.env.point_clearance(cand) >= clr]:
            if len(pts) == 0 or np.min(np.hypot(*(pts - p).T)) >= sep:
                pts = np.vstack([pts, p])
                if len(pts) == m:
                    return pts
    raise ValueError(f"cannot place {m} separated robots in a {shell.width:g} x {shell.height:g} workspace")


def random_problem(
    m: int,
    side: float,
    rng: np.random.Generator,
    *,
    obstacles: int = 3,
    size: tuple[float, float] = (4.0, 8.0),
    radius: float = RADIUS,
    margin: float = MARGIN,
) -> Problem:
    """A random ``side`` x ``side`` problem for ``m`` robots.

    ``obstacles`` random convex polygons with diameters uniform in ``size``
    (workspace units), then start and target placements drawn independently,
    each uniform, clear and separated (a start may overlap a target: the
    problem is unlabeled).  All draws come from ``rng``.
    """
    obs = tuple(_random_polygon(rng, rng.uniform(*size), side, side) for _ in range(obstacles))
    shell = Problem(side, side, obs, radius, margin, np.zeros((0, 2)), np.zeros((0, 2)))
    start = _free_points(shell, m, rng)
    target = _free_points(shell, m, rng)
    return Problem(side, side, obs, radius, margin, start, target).validate()


# ----------------------------------------------------------------------------
# peer paths


def side_for(m: int) -> float:
    """Workspace side for ``m`` robots: 40 at m = 11, growing with sqrt(m)."""
    return 40.0 * math.sqrt(m / 11.0)


def scaled_problem(m: int, rng: np.random.Generator) -> Problem:
    """The scaling benchmark's random problem for ``m`` robots (see :mod:`bench.scaling`)."""
    side = side_for(m)
    return random_problem(m, side, rng, size=(4.0 * side / 40.0, 8.0 * side / 40.0))


def assigned_targets(problem: Problem) -> np.ndarray:
    """Targets reordered so that robot ``i`` goes to row ``i``: the minimum-sum assignment."""
    d = np.linalg.norm(problem.start[:, None] - problem.target[None], axis=2)
    rows, cols = linear_sum_assignment(d)
    return problem.target[cols[np.argsort(rows)]]


def straight_line_waypoints(problem: Problem) -> np.ndarray:
    """One step from the start straight to the assigned targets, obstacles ignored ``(2, m, 2)``."""
    return np.stack([np.asarray(problem.start, float), assigned_targets(problem)])


@dataclass(frozen=True)
class PathCheck:
    """The exact validator's verdict on a plan.

    valid: whether :func:`planner.check_plan` accepted the plan.
    makespan_s: the plan's makespan [s].
    clearance: the exact minimum gap [workspace units] (``-inf`` when the
    path does not even start or end where it should).
    reason: why it was rejected (empty when valid).
    """

    valid: bool
    makespan_s: float
    clearance: float
    reason: str = ""


def timed_plan(problem: Problem, waypoints) -> Plan:
    """A waypoint path ``(K+1, m, 2)`` timed with the shared minimum-jerk scaling and the problem's limits.

    Between consecutive waypoints every robot moves on a straight segment
    and all move together, which is exactly the linear interpolation of the
    composite (``2m``-dimensional) configuration that sampling-based
    planners assume between two states.
    """
    w = np.asarray(waypoints, float)
    return Plan.from_waypoints(w, problem.radius, problem.margin, problem.max_speed, problem.max_accel)


def verify(problem: Problem, plan: Plan) -> PathCheck:
    """The exact validator's verdict on ``plan`` (:func:`planner.check_plan`), as a record."""
    try:
        c = check_plan(problem, plan)
    except PlanInvalid as exc:
        gap = exc.clearance.value if exc.clearance is not None else -math.inf
        return PathCheck(False, plan.makespan, gap, str(exc))
    return PathCheck(True, plan.makespan, c.value)


# ----------------------------------------------------------------------------
# reporting


def percentile(values, q: float) -> float:
    """The ``q``-th percentile of ``values``; NaN when there are none."""
    v = np.asarray(list(values), float)
    return float(np.percentile(v, q)) if len(v) else math.nan


def _cpu_model() -> str:
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown CPU"


def _version(dist: str) -> str:
    try:
        return version(dist)
    except PackageNotFoundError:
        return "not installed"


def machine_info() -> str:
    """Markdown bullet lines: date, platform, CPU, Python and library versions."""
    now = datetime.datetime.now().astimezone().strftime("%Y-%m-%d %H:%M %Z")
    return (
        f"- date: {now}\n"
        f"- platform: {platform.platform()}\n"
        f"- cpu: {_cpu_model()} ({os.cpu_count()} logical cores)\n"
        f"- python: {sys.version.split()[0]} ({platform.python_implementation()})\n"
        f"- numpy: {np.__version__}, scipy: {_version('scipy')}, networkx: {_version('networkx')}, "
        f"ompl: {_version('ompl')}"
    )


def _cell(v) -> str:
    if isinstance(v, float):
        if math.isnan(v):
            return "-"
        if math.isinf(v):
            return "inf"
        return f"{v:.3g}" if abs(v) < 1000 else f"{v:.0f}"
    return str(v)


def markdown_table(columns: list[str], rows: list[dict]) -> str:
    """A Markdown table of ``rows`` (dicts keyed by ``columns``); floats get 3 significant digits."""
    out = ["| " + " | ".join(columns) + " |", "|" + "|".join(" --- " for _ in columns) + "|"]
    for r in rows:
        out.append("| " + " | ".join(_cell(r.get(c, "")) for c in columns) + " |")
    return "\n".join(out)


def _child(conn, fn, args) -> None:
    try:
        conn.send(fn(*args))
    except Exception as exc:  # reported to the parent
        conn.send({"error": repr(exc)})
    conn.close()


def in_fresh_process(fn, args: tuple, timeout_s: float) -> dict:
    """``fn(*args)`` (a module-level function returning a dict) in a fresh spawned process.

    Each case gets its own interpreter, so its peak memory is its own.  The
    result, or ``{"error": reason}`` when ``fn`` raised, the process died
    (out of memory?) or it did not answer within ``timeout_s`` (then it is
    killed).
    """
    import multiprocessing as mp

    ctx = mp.get_context("spawn")
    recv, send = ctx.Pipe(duplex=False)
    proc = ctx.Process(target=_child, args=(send, fn, args), daemon=True)
    proc.start()
    send.close()
    result = None
    try:
        if recv.poll(timeout_s):
            result = recv.recv()
    except EOFError:
        result = {"error": "the worker process died (out of memory?)"}
    finally:
        if proc.is_alive():
            proc.kill()
        proc.join()
        recv.close()
    if result is None:
        result = {"error": "the worker process did not answer in time"}
    return result

