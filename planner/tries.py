"""What auto mode's direct tries found (:class:`_Direct`), two of its tries
(the lattice and the door stage), how the stats name the try that made the plan
(see :func:`planner.planning._direct`), and the obstacle-respecting and
narrow-passage bounds of :func:`planner.plan`'s plans."""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from .bounds import lower_bounds
from .cutbound import cut_lower_bound
from .freespace import free_roadmap_waypoints
from .geobound import geo_lower_bound
from .lattice import lattice_candidates
from .passages import passage_points
from .plan import PlanStats
from .problem import Problem
from .schedule import merge_steps, shortcut
from .timing import _drop_idle, _makespan
from .upump import _GOOD_ENOUGH

__all__ = []

_CUT_MIN_ROBOTS = 10  # fewer robots queue briefly: the bound adds little and would slow small plans by a quarter
_GEO_MIN_S = 0.1  # the least time left for the obstacle-respecting bound to start [s]
_GEO_BUDGET_S = 0.5  # its least budget [s] (it takes 0.2 to 0.6 s on den312d, room-64-64-8, lak303d)
#: Above this many obstacles the geo and cut bounds are not tried within the planner's budget:
#: on the third-party maps measured (docs/benchmarks.md), each of the three maps over it
#: (2282 to 2973 rectangles) ran out of it at 100, 200 and 400 robots, after 1 to 4 s.
_BOUND_MAX_OBSTACLES = 2000


def _name_direct(stats: PlanStats, label: str) -> None:
    """Record which direct try made the plan; the start-target connections are route ``[0, 1]``."""
    stats.extra["direct"] = label
    if label in ("one step", "sequenced"):
        stats.extra["route"] = [0, 1]


@dataclass
class _Direct:
    """What auto mode's direct tries found.

    ``best`` is ``(waypoints, sequential steps, makespan, label)`` of the
    shortest plan found (or ``None``); ``accepted`` when it is good enough
    to end the search; ``covered`` names the roadmap's structured stages
    whose whole route was tried here (the roadmap skips them); ``legs``
    the connections (straight or sequenced legs) of each try.
    """

    best: tuple | None = None
    accepted: bool = False
    covered: set = field(default_factory=set)
    legs: dict = field(default_factory=dict)

    def offer(self, label: str, legs: int, timed: tuple) -> None:
        self.legs[label] = legs
        if self.best is None or timed[2] < self.best[2]:
            self.best = (*timed, label)

    def final(self, problem: Problem) -> bool:
        """Whether the roadmap has nothing left to add.

        With a plan in hand, the roadmap's own versions of the stages whose
        chains failed here rarely beat it (over 20 seeds of every paper
        scenario they changed one median makespan, Table III row 4's, from
        1.45x to 1.40x the bound), and its last
        stage, one graph holding both placements, only pays where robots
        must file through a narrow passage and the plan is far from the
        bound (``_GOOD_ENOUGH[-1]``).
        """
        if self.accepted:
            return True
        if self.best is None:
            return False
        return not len(passage_points(problem)) or self.best[2] <= _GOOD_ENOUGH[-1] * lower_bounds(problem)[0]


#: Lower estimates of what the two bounds take per obstacle [s], to start neither where it
#: cannot finish in its budget: on the twelve MovingAI maps of 134 to 2282 rectangles measured
#: (docs/benchmarks.md), the geo bound took 0.9 to 5 ms per rectangle (its set-up alone 0.4 to
#: 0.5 ms), the cut bound 0.2 to 1.5 ms.
_GEO_S_PER_OBSTACLE = 9e-4
_CUT_S_PER_OBSTACLE = 2e-4


def _bounds_end(t0: float, limit: float, least: float = _GEO_BUDGET_S) -> float:
    """When the in-plan bounds must be done: a quarter of the time used so far after now (at
    least ``least``), and the time limit.  The geo and cut bounds share it where both run;
    the cut bound alone gets at least 0.05 s."""
    now = time.perf_counter()
    return min(limit, now + max(least, 0.25 * (now - t0)))


def _too_slow(problem: Problem, per_obstacle: float, end: float, limit: float) -> str | None:
    """Why a bound is not started (``None``: it is): its obstacles, or too little time left."""
    now = time.perf_counter()
    if len(problem.obstacles) > _BOUND_MAX_OBSTACLES:
        return (f"not computed: {len(problem.obstacles)} obstacles, over the "
                f"{_BOUND_MAX_OBSTACLES} its time budget covers")
    if limit - now < _GEO_MIN_S:
        return f"not computed: {max(limit - now, 0.0):.2g} s of the time limit was left, under {_GEO_MIN_S:g} s"
    need = per_obstacle * len(problem.obstacles)
    if now + need > end:
        return (f"not computed: it takes at least about {need:.2g} s with {len(problem.obstacles)} "
                f"obstacles, and {max(end - now, 0.0):.2g} s of its time budget was left")
    return None


def _geo_bound(problem: Problem, stats: PlanStats, end: float, limit: float) -> None:
    """The obstacle-respecting makespan bound (:mod:`planner.geobound`) into the stats, by
    ``end`` (:func:`_bounds_end`); otherwise NaN and ``stats.extra["geo_lower_bound"]`` says
    why (also when it is not started: too little time left, see :func:`_too_slow`)."""
    why = _too_slow(problem, _GEO_S_PER_OBSTACLE, end, limit)
    if why is not None:
        stats.extra["geo_lower_bound"] = why
        return
    try:
        stats.makespan_lower_bound_geo_s = geo_lower_bound(problem, deadline=end)
    except TimeoutError:
        stats.extra["geo_lower_bound"] = "not computed: out of its time budget"
    except Exception as exc:  # a statistic only: never worth losing a plan over
        stats.extra["geo_lower_bound"] = f"not computed: {type(exc).__name__}: {exc}"


def _cut_bound(problem: Problem, stats: PlanStats, end: float, limit: float) -> None:
    """The narrow-passage bound (:mod:`planner.cutbound`) into the stats (from
    :data:`_CUT_MIN_ROBOTS` robots) by ``end`` (what the geo bound left of the budget, at
    least 0.05 s); skipped where the stages
    already found no passage one robot wide (:func:`planner.passages.passage_points`,
    cached; finding them afresh takes seconds on large maps)."""
    lanes = problem.__dict__.get("_lanes_4")
    if problem.m < _CUT_MIN_ROBOTS or not problem.obstacles or (lanes is not None and not len(lanes)):
        return
    end = max(end, min(limit, time.perf_counter() + 0.05))
    why = _too_slow(problem, _CUT_S_PER_OBSTACLE, end, limit)
    if why is not None:
        stats.extra["cut_lower_bound"] = why
        return
    try:
        stats.makespan_lower_bound_cut_s = cut_lower_bound(problem, deadline=end)
    except Exception as exc:  # a statistic only
        stats.extra["cut_lower_bound"] = f"not computed: {type(exc).__name__}: {exc}"


#: A lattice plan within this factor of the makespan bound ends the search over lattices.
LATTICE_GOOD = 2.5


def _lattice(problem: Problem, out: _Direct, deadline: float) -> None:
    """Offer the shortest lattice plan (:mod:`planner.lattice`): after the first that
    works, other shifts and spacings are tried while the best is over
    :data:`LATTICE_GOOD` times the bound, the lattice has used less than 4.5 times what
    the first took, and another such try would use under a quarter of the time left."""
    t0 = time.perf_counter()
    first = None
    for raw in lattice_candidates(problem, deadline):
        w = merge_steps(problem, _drop_idle(raw), deadline)
        out.offer("lattice", len(raw) - 1, (w, len(raw) - 1, _makespan(problem, w)))
        now = time.perf_counter()
        first = first if first is not None else now - t0
        # (the bound, about a second at 1000 robots, only when another try could follow)
        if (now > deadline or now - t0 > 4.5 * first or first > 0.25 * (deadline - now)
                or out.best[2] <= LATTICE_GOOD * lower_bounds(problem)[0]):
            return


def _door(problem: Problem, out: _Direct, deadline: float) -> bool:
    """Offer the door stage's plan (:mod:`planner.conveyor`); whether it found one (which
    ends the search: the other stages move one robot through at a time)."""
    from .conveyor import door_plan

    found = door_plan(problem, deadline)
    if found is None:
        return False
    w, raw = found
    out.offer("door", raw, (w, raw, _makespan(problem, w)))
    out.accepted = True
    return True


#: From this many obstacles on, a plan of the free-space roadmap ends the search.
CLUTTER = 10

#: Where the grid stage snapped the robots onto a map's cells and its plan has at most this
#: many steps (the snapping rounds and a short routing between them), or it took at least as
#: many snapping rounds as routing steps (a crowd in an open arena), with at most
#: :data:`FREE_AFTER_GRID_MAX_ROBOTS` robots and :data:`FREE_AFTER_GRID_MAX_OBSTACLES`
#: obstacles, the free-space roadmap and a lattice (from ``planning.LATTICE_MIN_ROBOTS``
#: robots) are tried after it (:func:`_after_grid`), for :data:`FREE_AFTER_GRID_MIN_S` or
#: twice the grid stage's time, whichever is longer; the shortest plan is kept (scattered
#: robots in the turtlebot3 arena of Nav2's maps: 2.45x -> 1.67x the bound at 20).
FREE_AFTER_GRID_MAX_STEPS = 5
FREE_AFTER_GRID_MAX_ROBOTS = 150
FREE_AFTER_GRID_MAX_OBSTACLES = 500
#: the roadmap's set-up alone takes 0.9 to 1.8 s in that arena, its routing up to 2 s more
FREE_AFTER_GRID_MIN_S = 4.0


#: A grid plan of robots snapped onto a map of cells finer (or coarser) than a robot
#: (:func:`planner.mapgrid.robot_cells` false) longer than this many times the straight-line
#: bound is followed by the lattice meeting (:mod:`planner.packmeet`), which snaps robots by
#: flows instead of rounds (Nav2's depot with 200 robots of radius 0.2: 6.6 s -> 4.8 s).
MEET_AFTER_GRID_X = 2.0


def _after_grid(problem: Problem, params, out: _Direct, info: dict, t_grid: float, deadline: float, rng,
                lattice: bool) -> None:
    """After the grid stage's plan (``out.best``) of snapped robots: on a map of cells
    that are not robot-sized, when the plan is long (:data:`MEET_AFTER_GRID_X`), the
    lattice meeting; where the grid plan is short (:data:`FREE_AFTER_GRID_MAX_STEPS`) or
    took at least as many snapping rounds as routing steps (``info``,
    :func:`planner.gridstage.grid_plan`), the free-space roadmap, which moves robots from
    where they stand, and a lattice (``lattice``) may do better; each is kept when shorter
    as it will run (shortcut, which shortens grid plans more)."""
    from .mapgrid import robot_cells

    grid_best = out.best
    if ("dense" not in out.legs and not robot_cells(problem)
            and grid_best[2] > MEET_AFTER_GRID_X * lower_bounds(problem)[0]):
        _dense(problem, out, deadline, rng, meet_only=True)
    steps = len(grid_best[0]) - 1
    short = steps <= FREE_AFTER_GRID_MAX_STEPS or info.get("snap_rounds", 0) >= info.get("route_steps", 1)
    if (short and problem.m <= FREE_AFTER_GRID_MAX_ROBOTS
            and 0 < len(problem.obstacles) <= FREE_AFTER_GRID_MAX_OBSTACLES):
        now = time.perf_counter()
        end = min(deadline, now + max(FREE_AFTER_GRID_MIN_S, 2.0 * (now - t_grid)))
        _free_space(problem, out, lower_bounds(problem)[0], end, rng)
        if lattice:
            _lattice(problem, out, end)
    if out.best is not grid_best and params.concurrent:
        runs = []
        for w_c, steps_c, _, label_c in (grid_best, out.best):
            w_c = shortcut(problem, w_c, deadline=deadline)
            runs.append((w_c, steps_c, _makespan(problem, w_c), label_c))
        out.best = min(runs, key=lambda r: r[2])


#: The packing stage's share of the time left when it runs before the other tries among obstacles.
DENSE_SHARE = 0.5


def _dense(problem: Problem, out: _Direct, deadline: float, rng, meet_only: bool = False) -> None:
    """Offer the packing stage's plans within :data:`DENSE_SHARE` of the time left: both
    placements met on a roomy lattice (:mod:`planner.packmeet`), then (unless
    ``meet_only``) the flows of :mod:`planner.dense` in what is left of that share."""
    from .dense import dense_plan
    from .packmeet import meet_plan

    end = time.perf_counter() + DENSE_SHARE * max(deadline - time.perf_counter(), 0.0)
    for stage in (meet_plan,) if meet_only else (meet_plan, dense_plan):
        found = stage(problem, max(end - time.perf_counter(), 0.0), rng, deadline=deadline)
        if found is not None:
            w = np.asarray(found.waypoints)
            out.offer("dense", len(w) - 1, (w, len(w) - 1, found.makespan))
    out.legs.setdefault("dense", 0)  # tried: not again after the grid stage


def _free_space(problem: Problem, out: _Direct, bound: float, deadline: float, rng) -> None:
    """Offer the free-space roadmap's plan (:mod:`planner.freespace`), a few tries."""
    if "free-space roadmap" in out.legs:
        return
    raw = None
    # Escapes and ties are random: a stalled routing may pass on another try.  Goal
    # swapping first (shorter plans), priority inheritance where it stalls.
    for router in ("tswap", "tswap", "tswap", "pibt") * 3:
        if raw is not None or time.perf_counter() > deadline:
            break
        raw = free_roadmap_waypoints(problem, deadline, rng, router=router)
    if raw is None:
        out.legs.setdefault("free-space roadmap", 0)
        return
    w = merge_steps(problem, _drop_idle(raw), deadline)
    span = _makespan(problem, w)
    out.offer("free-space roadmap", len(raw) - 1, (w, len(raw) - 1, span))
    # Among many obstacles the pebble-graph roadmap costs much and rarely does better.
    out.accepted = len(problem.obstacles) >= CLUTTER or span <= _GOOD_ENOUGH[-1] * bound
