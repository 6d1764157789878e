"""Lower bounds on a plan's makespan and path length.

Whatever the plan, robot ``i`` must travel at least from ``s_i`` to the
target it ends on, and the targets form a permutation.  The makespan is at
least the duration of one straight step over the *bottleneck* assignment
distance ``min_sigma max_i |s_i - t_sigma(i)|`` under the plan's own time
scaling and limits (what the swarm would need if no robot were in
another's way); the path length is at least the *minimum-sum* assignment
distance.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import linear_sum_assignment

from .plan import step_duration
from .problem import Problem

__all__ = ["bottleneck_distance", "lower_bounds", "min_sum_distance"]


def _distances(start, target) -> np.ndarray:
    return np.linalg.norm(np.asarray(start)[:, None] - np.asarray(target)[None], axis=2)


def min_sum_distance(start, target) -> float:
    """Minimum over assignments of the summed straight-line distances."""
    d = _distances(start, target)
    r, c = linear_sum_assignment(d)
    return float(d[r, c].sum())


def bottleneck_distance(start, target) -> float:
    """Minimum over assignments of the longest straight-line distance.

    Binary search over the sorted distinct distances, each tested for a
    perfect matching on the pairs no longer than the candidate.
    The search is confined to ``[L, U]``: every robot must reach some
    target and every target be reached, so the answer is at least the
    largest row or column minimum ``L``; the minimum-sum assignment is one
    assignment, so its longest distance ``U`` bounds it from above.
    """
    d = _distances(start, target)
    if len(d) == 0:
        return 0.0
    r, c = linear_sum_assignment(d)
    return _bottleneck(d, float(d[r, c].max()))


def _bottleneck(d: np.ndarray, high: float) -> float:
    """:func:`bottleneck_distance` of the distance matrix ``d``, given an assignment's
    longest distance ``high`` (the graphs near ``d.max()`` are dense and their matchings
    slow: at 1000 robots the search from ``d.max()`` took 1.7 s)."""
    low = max(float(d.min(axis=1).max()), float(d.min(axis=0).max()))
    values = np.unique(d[(d >= low) & (d <= high)])
    lo, hi = 0, len(values) - 1
    while lo < hi:
        mid = (lo + hi) // 2
        if _perfect(d <= values[mid]):
            hi = mid
        else:
            lo = mid + 1
    return float(values[lo])


def _perfect(allowed: np.ndarray) -> bool:
    """Whether the bipartite graph of ``allowed`` pairs has a perfect matching.

    A zero-cost assignment of the 0/1 costs ``~allowed`` (scipy's LAP
    solver).  Not Hopcroft-Karp (scipy's ``maximum_bipartite_matching``):
    on graphs without a perfect matching it can take seconds to minutes
    (1000 robots in one half of the workspace, targets in the other: 20 s a
    test, 470 s a bound), where the LAP solver takes 0.1 s; on graphs with
    one both take well under a second.
    """
    r, c = linear_sum_assignment(~allowed)
    return bool(allowed[r, c].all())


def lower_bounds(problem: Problem) -> tuple[float, float]:
    """``(makespan lower bound [s], path length lower bound)`` of ``problem`` (cached)."""
    cached = problem.__dict__.get("_lower_bounds")
    if cached is None:
        d = _distances(problem.start, problem.target)
        if len(d) == 0:
            d_star, total = 0.0, 0.0
        else:  # one minimum-sum assignment: the path length bound and the search's top
            r, c = linear_sum_assignment(d)
            d_star, total = _bottleneck(d, float(d[r, c].max())), float(d[r, c].sum())
        makespan = float(step_duration(d_star, problem.max_speed, problem.max_accel))
        cached = (makespan, total)
        problem.__dict__["_lower_bounds"] = cached
    return cached
