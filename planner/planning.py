"""The planner's entry point: :func:`plan` (UPUMP, then timing and exact validation)."""

from __future__ import annotations

import time

import numpy as np

from .params import PlannerParams
from .plan import Plan, PlanStats
from .problem import Problem
from .upump import NoPlanFound, plan_sequential
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
    waypoints, stats = plan_sequential(problem, params, rng, deadline)
    result = Plan.from_waypoints(
        _drop_idle(waypoints), problem.radius, problem.margin, problem.max_speed, problem.max_accel
    )
    try:
        clearance = check_plan(problem, result)
    except PlanInvalid as exc:  # a bug, never an expected outcome
        raise AssertionError(f"planner produced an invalid plan: {exc}") from exc
    _fill_stats(stats, result, clearance.value)
    stats.planning_time_s = time.perf_counter() - t0
    result = Plan(result.radius, result.margin, result.durations, result.waypoints,
                  result.max_speed, result.max_accel, stats)
    return result, stats


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
