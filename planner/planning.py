"""The planner's entry point: :func:`plan` (UPUMP, then timing and exact validation)."""

from __future__ import annotations

import time

import numpy as np
from scipy.optimize import linear_sum_assignment

from .bounds import lower_bounds
from .connect import sequenced_moves
from .params import PlannerParams
from .plan import Plan, PlanStats
from .problem import Problem
from .schedule import merge_moves, merge_steps, schedule, shortcut, split_moves, step_clear
from .upump import _GOOD_ENOUGH, NoPlanFound, build_roadmap, retrieve
from .validate import PlanInvalid, check_plan

__all__ = ["NoPlanFound", "plan"]


def plan(problem: Problem, params: PlannerParams | None = None, rng: np.random.Generator | None = None):
    """Plan collision-free motions for the unlabeled problem.

    Returns ``(Plan, PlanStats)``; the plan has passed the exact validator
    (its minimum gap is at least the margin).  Raises :class:`NoPlanFound`,
    carrying the stats, when no plan is found within the limits.
    ``rng`` is the run's one generator (default: seeded with 0).
    """
    params = params or PlannerParams()
    rng = rng if rng is not None else np.random.default_rng(0)
    problem.validate()
    t0 = time.perf_counter()
    deadline = t0 + params.time_limit
    if _same_set(problem.start, problem.target):
        stats = PlanStats(found=True)
        result = Plan.from_waypoints(problem.start[None], problem.radius, problem.margin,
                                     problem.max_speed, problem.max_accel)
    elif (direct := _direct(problem, params, memo := {})) is not None:
        waypoints, sequential = direct
        if params.concurrent:
            waypoints = shortcut(problem, waypoints)
        result = Plan.from_waypoints(waypoints, problem.radius, problem.margin, problem.max_speed,
                                     problem.max_accel)
        stats = PlanStats(found=True, g=0, q=0, graphs=0, connections=1)
        stats.extra["sequential_steps"] = sequential
        stats.extra["route"] = [0, 1]
        stats.extra["attempts"] = 0
    else:
        timed: dict[tuple, tuple] = {}  # route -> (waypoints, sequential steps, makespan)

        def evaluate(roadmap, route):
            key = tuple(route)
            if key not in timed:
                timed[key] = _timed(problem, params, retrieve(problem, roadmap, route), memo)
            return timed[key]

        roadmap, source, goal, stats = build_roadmap(
            problem, params, rng, deadline, makespan=lambda rm, route: evaluate(rm, route)[2]
        )
        best = None
        for route in roadmap.routes(source, goal, _ROUTES):
            waypoints, sequential, makespan = evaluate(roadmap, route)
            if best is None or makespan < best[2]:
                best = (waypoints, sequential, makespan, route)
        waypoints, sequential, _, route = best
        if params.concurrent:
            waypoints = shortcut(problem, waypoints)
        result = Plan.from_waypoints(waypoints, problem.radius, problem.margin, problem.max_speed,
                                     problem.max_accel)
        stats.extra["sequential_steps"] = sequential
        stats.extra["route"] = [int(g) for g, _ in route]
    try:
        clearance = check_plan(problem, result)
    except PlanInvalid as exc:  # a bug, never an expected outcome
        raise AssertionError(f"planner produced an invalid plan: {exc}") from exc
    _fill_stats(stats, result, clearance.value)
    stats.makespan_lower_bound_s, stats.path_length_lower_bound = lower_bounds(problem)
    stats.planning_time_s = time.perf_counter() - t0
    result = Plan(result.radius, result.margin, result.durations, result.waypoints,
                  result.max_speed, result.max_accel, stats)
    return result, stats


_ROUTES = 3  # best routes by estimate compared by their scheduled makespan (plus one per family)


def _direct(problem: Problem, params: PlannerParams, memo: dict):
    """Auto mode's first try, before any pebble graph is sampled.

    First all robots at once, straight to their assigned targets, when
    that single step is clear.  Then the robots go from the start straight
    (or around the obstacles by shortest paths) to their assigned targets,
    one at a time in dependency order (:func:`planner.connect.sequenced_moves`), then scheduled
    concurrently.  It is the roadmap's own first stage (the sequenced
    connection between the start's and the target's graphs) run without
    pumping the two graphs; when its plan is within the first
    good-enough factor of the makespan lower bound, it is the answer;
    otherwise ``memo`` keeps its timing for the roadmap's identical route.
    Returns ``(waypoints, sequential steps)`` or ``None``.
    """
    if not params.auto or _GOOD_ENOUGH[1] is None:
        return None
    limit = _GOOD_ENOUGH[1] * lower_bounds(problem)[0]
    # Everybody at once, straight to the minimum-sum-of-squares targets: a
    # connection in the paper's sense (m pairs, no two interfering), exact.
    _, cols = linear_sum_assignment(((problem.start[:, None] - problem.target[None]) ** 2).sum(axis=2))
    one = np.stack([problem.start, problem.target[cols]])
    if step_clear(problem, one[0], one[1]) and _makespan(problem, one) <= limit:
        return one, 1
    bends = (False, True) if problem.obstacles else (False,)
    for bent in bends:
        seq = sequenced_moves(problem, problem.start, problem.target, bent)
        if seq is None:
            continue
        raw = [problem.start, *seq.waypoints(problem.start, seq.rows)]
        waypoints, sequential, makespan = _timed(problem, params, raw, memo)
        if makespan <= limit:
            return waypoints, sequential
        return None
    return None


def _timed(problem: Problem, params: PlannerParams, waypoints, memo: dict | None = None):
    """Merge, cut, schedule and merge again: ``(waypoints, sequential steps, makespan)``.

    ``memo`` maps waypoints already timed (by their bytes) to the result.

    Long moves are cut into speed-limited pieces before scheduling, which
    lets a robot waiting for another start while the other is still on its
    way; the chosen route's plan is then straightened by :func:`shortcut`.
    """
    waypoints = _drop_idle(waypoints)
    key = waypoints.tobytes()
    if memo is not None and key in memo:
        return memo[key]
    result = _timed_fresh(problem, params, waypoints)
    if memo is not None:
        memo[key] = result
    return result


def _timed_fresh(problem: Problem, params: PlannerParams, waypoints: np.ndarray):
    sequential = len(waypoints) - 1
    waypoints = merge_moves(problem, waypoints)
    if params.concurrent:
        waypoints = merge_steps(problem, schedule(problem, split_moves(problem, waypoints)))
    return waypoints, sequential, _makespan(problem, waypoints)


def _makespan(problem: Problem, waypoints) -> float:
    return Plan.from_waypoints(waypoints, problem.radius, problem.margin, problem.max_speed,
                               problem.max_accel).makespan


def _same_set(a: np.ndarray, b: np.ndarray) -> bool:
    """Whether two placements are the same set of points."""
    return bool(np.array_equal(a[np.lexsort(a.T[::-1])], b[np.lexsort(b.T[::-1])]))


def _drop_idle(waypoints: list[np.ndarray]) -> np.ndarray:
    """Remove steps in which no robot moves."""
    out = [waypoints[0]]
    for w in waypoints[1:]:
        if not np.array_equal(w, out[-1]):
            out.append(w)
    return np.asarray(out)


def _fill_stats(stats: PlanStats, plan: Plan, clearance: float):
    stats.found = True
    stats.steps = plan.steps
    stats.makespan_s = plan.makespan
    stats.path_length = plan.path_length
    stats.min_clearance = clearance
