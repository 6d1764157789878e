"""Raw waypoints made into timed plans: moves merged, long moves cut, steps
scheduled concurrently and merged again, and the makespan of the result."""

from __future__ import annotations

import numpy as np

from .params import PlannerParams
from .plan import Plan
from .problem import Problem
from .schedule import merge_moves, merge_steps, schedule, split_moves

__all__ = []


def _timed(problem: Problem, params: PlannerParams, waypoints, memo: dict | None = None,
           deadline: float | None = None):
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
    result = _timed_fresh(problem, params, waypoints, deadline)
    if memo is not None:
        memo[key] = result
    return result


def _timed_fresh(problem: Problem, params: PlannerParams, waypoints: np.ndarray, deadline: float | None = None):
    sequential = len(waypoints) - 1
    waypoints = merge_moves(problem, waypoints, deadline)
    if params.concurrent:
        waypoints = merge_steps(problem, schedule(problem, split_moves(problem, waypoints), deadline), deadline)
    return waypoints, sequential, _makespan(problem, waypoints)


def _makespan(problem: Problem, waypoints) -> float:
    return Plan.from_waypoints(waypoints, problem.radius, problem.margin, problem.max_speed,
                               problem.max_accel).makespan


def _drop_idle(waypoints: list[np.ndarray]) -> np.ndarray:
    """Remove steps in which no robot moves."""
    out = [waypoints[0]]
    for w in waypoints[1:]:
        if not np.array_equal(w, out[-1]):
            out.append(w)
    return np.asarray(out)
