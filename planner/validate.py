"""The exact validator: minimum clearance of a whole plan, continuous in time.

Within a step every robot moves on a straight segment and all share one
monotone time scaling, so the set of simultaneous positions is
``{(a_i + theta (b_i - a_i))_i : theta in [0, 1]}``.  The minimum over time
of a robot-robot distance is therefore the closed-form closest approach of
two linearly interpolated points, and a robot's clearance to the static
world is that of its segment.  Nothing is sampled.

Clearances are *gaps*: between two disc boundaries (centre distance minus
``2 r``) or between a disc and an obstacle or wall (centre clearance minus
``r``).  A plan is valid when its minimum gap is at least the margin.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .geometry import closest_approach
from .plan import Plan, min_jerk
from .problem import Problem, describe_obstacle

__all__ = ["Clearance", "PlanInvalid", "check_plan", "min_clearance"]

_TOL = 1e-9


@dataclass(frozen=True)
class Clearance:
    """Where a plan comes closest to a collision.

    value: the smallest gap [workspace units]; negative means overlap.
    kind: ``robot-robot``, ``robot-obstacle`` or ``robot-wall``.
    robots: the robot indices involved; obstacle: its index (or None).
    step: the step index (-1: the start placement, before any step).
    time: the plan time [s] at which the gap is smallest.
    """

    value: float
    kind: str
    robots: tuple[int, ...]
    obstacle: int | None
    step: int
    time: float

    def describe(self) -> str:
        who = (
            f"robots {self.robots[0]} and {self.robots[1]}"
            if self.kind == "robot-robot"
            else f"robot {self.robots[0]} and {describe_obstacle(self.obstacle if self.obstacle is not None else -1)}"
        )
        return f"gap {self.value:.4g} between {who} at t = {self.time:.3f} s (step {self.step})"


class PlanInvalid(ValueError):
    """A plan that comes closer than the margin, or does not solve the problem."""

    def __init__(self, message: str, clearance: Clearance | None = None):
        super().__init__(message)
        self.clearance = clearance


def _theta_to_time(plan: Plan, step: int, theta: float) -> float:
    """Plan time at which step ``step`` reaches path parameter ``theta``."""
    if step < 0:
        return 0.0
    lo, hi = 0.0, 1.0
    for _ in range(60):  # s is increasing: bisection on s(u) = theta
        mid = 0.5 * (lo + hi)
        if min_jerk(mid)[0] < theta:
            lo = mid
        else:
            hi = mid
    return float(plan.times[step] + 0.5 * (lo + hi) * plan.durations[step])


def _segment_theta(a, b, problem: Problem, who: int) -> float:
    """Parameter on ``a -> b`` where the clearance to ``who`` is smallest (exact)."""
    env = problem.env
    ab = b - a
    L2 = float(ab @ ab)
    if L2 == 0.0:
        return 0.0
    if who < 0:
        return 0.0 if env.wall_clearance(a) <= env.wall_clearance(b) else 1.0
    ob = problem.obstacles[who]
    if hasattr(ob, "center"):
        return float(np.clip((np.asarray(ob.center) - a) @ ab / L2, 0.0, 1.0))
    # The segment-to-polygon distance is attained at a segment end, at the
    # projection of a polygon vertex onto the segment, or at a crossing.
    v = ob.vertices
    cand = np.concatenate([[0.0, 1.0], np.clip((v - a) @ ab / L2, 0.0, 1.0)])
    w = np.roll(v, -1, axis=0)
    e = w - v
    den = ab[0] * e[:, 1] - ab[1] * e[:, 0]
    ok = np.abs(den) > 0
    t = ((v[:, 0] - a[0]) * e[:, 1] - (v[:, 1] - a[1]) * e[:, 0]) / np.where(ok, den, 1.0)
    cand = np.concatenate([cand, np.clip(t[ok], 0.0, 1.0)])
    pts = a + cand[:, None] * ab
    d = env.point_clearance_detail(pts)[0]
    return float(cand[np.argmin(d)])


def min_clearance(problem: Problem, plan: Plan) -> Clearance:
    """The exact minimum gap of ``plan`` in ``problem``'s world, and where it is."""
    w = plan.waypoints
    m = plan.m
    r = problem.radius
    env = problem.env
    best = Clearance(np.inf, "robot-wall", (0,), None, -1, 0.0)

    # The start placement: the world and every pair of robots.
    c0, who0 = env.point_clearance_detail(w[0])
    i = int(np.argmin(c0))
    best = Clearance(float(c0[i] - r), "robot-obstacle" if who0[i] >= 0 else "robot-wall",
                     (i,), int(who0[i]) if who0[i] >= 0 else None, -1, 0.0)
    if m > 1:
        from scipy.spatial import cKDTree

        dd, jj = cKDTree(w[0]).query(w[0], k=2)
        i = int(np.argmin(dd[:, 1]))
        gap = float(dd[i, 1] - 2 * r)
        if gap < best.value:
            j = int(jj[i, 1])
            best = Clearance(gap, "robot-robot", (min(i, j), max(i, j)), None, -1, 0.0)

    for k in range(plan.steps):
        a, b = w[k], w[k + 1]
        moving = np.flatnonzero(np.any(a != b, axis=1))
        if len(moving) == 0:
            continue
        am, bm = a[moving], b[moving]
        cl, who = env.segment_clearance_detail(am, bm)
        idx = int(np.argmin(cl))
        if cl[idx] - r < best.value:
            i = int(moving[idx])
            ob = int(who[idx])
            theta = _segment_theta(a[i], b[i], problem, ob)
            best = Clearance(float(cl[idx] - r), "robot-obstacle" if ob >= 0 else "robot-wall",
                             (i,), ob if ob >= 0 else None, k, _theta_to_time(plan, k, theta))
        if m > 1:
            dist, theta = closest_approach(am[:, None], bm[:, None], a[None], b[None], return_theta=True)
            dist[np.arange(len(moving)), moving] = np.inf  # a robot and itself
            flat = int(np.argmin(dist))
            pi, j = divmod(flat, m)
            gap = float(dist[pi, j] - 2 * r)
            if gap < best.value:
                i = int(moving[pi])
                best = Clearance(gap, "robot-robot", (min(i, j), max(i, j)), None, k,
                                 _theta_to_time(plan, k, float(theta[pi, j])))
    return best


def check_plan(problem: Problem, plan: Plan, *, tol: float = _TOL) -> Clearance:
    """Raise :class:`PlanInvalid` unless ``plan`` solves ``problem`` with the margin.

    Checks: the plan starts at the start placement (robot ``i`` at
    ``start[i]``), ends on the target set (any matching: the problem is
    unlabeled), and its exact minimum gap is at least the margin.
    """
    if plan.waypoints.shape[1] != problem.m:
        raise PlanInvalid(f"plan moves {plan.waypoints.shape[1]} robots, problem has {problem.m}")
    if not np.allclose(plan.start, problem.start, atol=1e-6):
        i = int(np.argmax(np.linalg.norm(plan.start - problem.start, axis=1)))
        raise PlanInvalid(f"robot {i} does not start at its start position")
    if not _same_set(plan.end, problem.target):
        raise PlanInvalid("the plan does not end on the target placement")
    c = min_clearance(problem, plan)
    if c.value < problem.margin - tol:
        raise PlanInvalid(f"plan violates the margin {problem.margin:g}: {c.describe()}", c)
    return c


def _same_set(a: np.ndarray, b: np.ndarray, atol: float = 1e-6) -> bool:
    from scipy.optimize import linear_sum_assignment

    cost = np.linalg.norm(a[:, None] - b[None], axis=2)
    ri, ci = linear_sum_assignment(cost)
    return bool(cost[ri, ci].max() <= atol)
