"""Dense packings: the swarm flowed onto a lattice and off it again.

In an empty box at 50 % coverage (50 robots of radius 1, margin 0.1, a box
of side 17.7) the placements are dense liquids: most robots touch a
neighbour within a few tenths, no straight step of the whole swarm is
clear, and a single robot has almost nowhere to go.  Yet the box holds a
square grid of 8 x 8 points at a spacing of at least the separation, and
the robots are never far from some 50 of them.

1. **Sites** (:func:`packing_sites`): lattices of points pairwise at least
   the separation apart and clear of the walls: the square grid spanning
   the box, when it has at least ``m`` points, and a brick lattice (rows
   at the spacing that keeps diagonal neighbours a separation apart, odd
   rows shifted by half a spacing and one point shorter), its rows along
   x and along y.
2. **Flow** (:func:`flow`): many small steps of the whole swarm.  In each,
   every robot heads for its site of the minimum sum-of-squares matching
   (computed again every step: the problem is unlabeled), at most ``h``
   per step; pairs closer than ``separation + eps`` are then pushed apart
   along their line, symmetrically, a few rounds (``eps`` at most the
   sites' spacing over the separation, or robots could never settle on
   them), and positions clamped to the box (convex: a clamped step stays
   clear of the walls).  The step
   ``x -> x'`` is checked exactly (closest approach of every pair that can
   meet, :func:`planner.geometry.closest_approach`); the robots of a pair
   that comes closer than the separation stay where they are, and the
   check is repeated until it passes (all staying is always clear).  A
   robot within ``1e-3`` of its site lands on it.  Where the matched
   squared distance stops falling, the headings of the robots not yet on
   their sites get random noise.
3. **Route** (:func:`dense_plan`): the target placement is flowed onto all
   the sites of a lattice, giving ``C``; the start placement is flowed onto
   exactly ``C``; the plan is the first flow followed by the second
   reversed (a reversed step is clear when the step is: closest approaches
   do not depend on the direction), its rows matched where they meet.
   If that fails, the other way round (start onto the lattice, target onto
   its placement).  Steps are merged where the joined straight step is
   clear (:func:`planner.merge.merge_steps`) and the whole plan passes
   :func:`planner.validate.check_plan` before it is returned; anything
   that fails returns ``None``.
"""

from __future__ import annotations

import math
import time

import numpy as np
from scipy.optimize import linear_sum_assignment
from scipy.spatial import cKDTree

from .geometry import closest_approach
from .plan import Plan
from .problem import Problem

__all__ = ["BEST_OF_SHARE", "FLOW_SETTINGS", "FLOW_STEPS", "dense_plan", "flow", "packing_sites", "step_ok"]

#: Steps a flow may take before it gives up.
FLOW_STEPS = 300
# Lengths below are for the separation of 2.1 (robots of radius 1, margin 0.1) and
# scale with a problem's separation (:func:`_unit`).
_REF_SEPARATION = 2.1
_EPS = 0.03  # pairs pushed apart to separation + _EPS
_H = 0.15  # longest move of a flow step
_SNAP = 1e-3  # a robot this close to its site lands on it
_PATIENCE = 8  # flow steps without a better matched distance before noise


def _unit(problem: Problem) -> float:
    """The factor from the module's lengths (at separation 2.1) to ``problem``'s."""
    return problem.separation / _REF_SEPARATION


def _box(problem: Problem) -> tuple[np.ndarray, np.ndarray]:
    """The corners ``lo``, ``hi`` of the box of centres clear of the walls, rounded inwards:
    ``width - hi[0] >= clearance`` holds in floating point too (``width - clearance`` can
    round to a point a few 1e-16 too close, and the exact step test then refuses every
    joined step of a robot pushed against the right or top wall)."""
    c = problem.clearance
    lo, hi = np.full(2, c), np.array([problem.width - c, problem.height - c])
    for k, side in enumerate((problem.width, problem.height)):
        while side - hi[k] < c:
            hi[k] = np.nextafter(hi[k], -np.inf)
    return lo, hi


def _brick(wx: float, wy: float, sep: float) -> np.ndarray | None:
    """The brick lattice of the module docstring in ``[0, wx] x [0, wy]``, rows along x."""
    nx = int(wx // sep) + 1
    if nx < 2:
        return None
    dx = wx / (nx - 1)
    rise = math.sqrt(max(sep * sep - dx * dx / 4, 0.0))
    rows = int(wy // rise) + 1 if rise > 0 else int(wy // sep) + 1
    dy = wy / (rows - 1) if rows > 1 else 0.0
    return np.asarray([((j % 2) * dx / 2 + i * dx, j * dy) for j in range(rows) for i in range(nx - j % 2)], float)


def packing_sites(problem: Problem) -> list[np.ndarray]:
    """Lattices of clear points pairwise at least the separation apart, each with at least
    ``m`` points: the square grid spanning the box when it is big enough, then the brick
    lattice with rows along x and along y (see the module docstring)."""
    sep = problem.separation
    lo = problem.clearance + 1e-9 * max(problem.width, problem.height, 1.0)  # off the walls by a hair
    wx, wy = problem.width - 2 * lo, problem.height - 2 * lo
    if wx < 0 or wy < 0:
        return []
    nx, ny = int(wx // sep) + 1, int(wy // sep) + 1
    gx = (wx / (nx - 1) if nx > 1 else 0.0) * np.arange(nx)
    gy = (wy / (ny - 1) if ny > 1 else 0.0) * np.arange(ny)
    out = [np.stack(np.meshgrid(gx, gy, indexing="ij"), axis=-1).reshape(-1, 2), _brick(wx, wy, sep)]
    across = _brick(wy, wx, sep)
    out.append(None if across is None else across[:, ::-1])
    keep = []
    for s in out:
        if s is None:
            continue
        s = s[problem.env.points_clear(s + lo, problem.clearance)] + lo
        if len(s) >= problem.m and (len(s) < 2 or cKDTree(s).query(s, 2)[0][:, 1].min() >= sep):
            keep.append(s)
    return keep


def step_ok(problem: Problem, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The pairs ``(k, 2)`` of robots that come closer than the separation in the step
    ``a -> b`` (exact closest approach over every pair that can meet)."""
    reach = problem.separation + 2 * float(np.linalg.norm(b - a, axis=1).max(initial=0.0)) + 1e-9
    pairs = cKDTree(a).query_pairs(reach, output_type="ndarray")
    if len(pairs) == 0:
        return pairs
    i, j = pairs[:, 0], pairs[:, 1]
    return pairs[closest_approach(a[i], b[i], a[j], b[j]) < problem.separation]


def _push(problem: Problem, x: np.ndarray, lo: np.ndarray, hi: np.ndarray, eps: float) -> np.ndarray:
    """Pairs closer than ``separation + eps`` pushed apart, a few rounds, in the box."""
    want = problem.separation + eps
    for _ in range(20):
        pairs = cKDTree(x).query_pairs(want, output_type="ndarray")
        if len(pairs) == 0:
            break
        i, j = pairs[:, 0], pairs[:, 1]
        d = x[i] - x[j]
        n = np.maximum(np.linalg.norm(d, axis=1), 1e-12)
        push = (0.505 * (want - n) / n)[:, None] * d
        np.add.at(x, i, push)
        np.add.at(x, j, -push)
        x = np.clip(x, lo, hi)
    return x


def flow(problem: Problem, x: np.ndarray, sites: np.ndarray, deadline: float,
         rng: np.random.Generator, h: float = _H, eps: float = _EPS) -> list[np.ndarray] | None:
    """Waypoints from the placement ``x`` to one on ``m`` of ``sites`` (every step exactly
    clear), or ``None`` past :data:`FLOW_STEPS` steps or the deadline.  ``h`` and ``eps``
    are at the separation 2.1 and scale with ``problem``'s (:func:`_unit`)."""
    unit = _unit(problem)
    h, eps, snap = h * unit, eps * unit, _SNAP * unit
    lo, hi = _box(problem)
    if len(sites) > 1:
        # pairs pushed apart beyond the sites' own spacing could never settle on them (a
        # square grid of 18 x 18 in a box of side 38.4 is 2.13 apart, for a separation of 2.1:
        # 200 robots there found no plan in 60 s)
        spacing = float(cKDTree(sites).query(sites, k=2)[0][:, 1].min())
        eps = min(eps, max(0.0, spacing - problem.separation))
    x = np.array(x, float)
    out = [x.copy()]
    best, since = np.inf, 0
    for _ in range(FLOW_STEPS):
        if time.perf_counter() > deadline:
            return None
        _, col = linear_sum_assignment(((x[:, None] - sites[None]) ** 2).sum(axis=2))
        goal = sites[col]
        v = goal - x
        left = np.linalg.norm(v, axis=1)
        if left.max() == 0.0:
            return out
        cost = float((left**2).sum())
        best, since = (cost, 0) if cost < best - 1e-9 else (best, since + 1)
        if since >= _PATIENCE:  # stalled: shake the headings of the robots not yet on their sites
            off = left > snap
            v[off] += rng.normal(0.0, h * min(1.0, 0.2 * (since - _PATIENCE + 1)), (int(off.sum()), 2))
            left = np.linalg.norm(v, axis=1)
        nxt = _push(problem, x + v * np.minimum(1.0, h / np.maximum(left, 1e-300))[:, None], lo, hi, eps)
        near = np.linalg.norm(nxt - goal, axis=1) < snap
        nxt[near] = goal[near]
        while len(bad := step_ok(problem, x, nxt)):
            stay = np.unique(bad)
            nxt[stay] = x[stay]
        if np.array_equal(nxt, x):
            since += 1
            continue
        x = nxt
        out.append(x.copy())
    return None


def _joined(first: list[np.ndarray], second: list[np.ndarray]) -> np.ndarray | None:
    """``first`` then ``second`` reversed, the rows of the reversed part matched to the
    robots where the two meet (the same set of points), or ``None`` when they do not."""
    a, b = first[-1], second[-1]
    cost = ((a[:, None] - b[None]) ** 2).sum(axis=2)
    _, perm = linear_sum_assignment(cost)
    if not np.all(cost[np.arange(len(a)), perm] <= 1e-18):
        return None
    back = [w[perm] for w in second[::-1]]
    back[0] = a
    return np.asarray(first + back[1:])


#: ``(h, eps)`` of the flows tried, in this order (the spread of makespans between them is wide).
FLOW_SETTINGS = ((0.15, 0.1), (0.25, 0.1), (0.15, 0.03), (0.25, 0.03), (0.1, 0.1))

#: After the first plan, more tries while they fit in this share of the time limit.
BEST_OF_SHARE = 0.25


def dense_plan(problem: Problem, time_limit: float, rng: np.random.Generator,
               deadline: float | None = None) -> Plan | None:
    """The shortest of the plans through a lattice (see the module docstring) found by the
    tries of :data:`FLOW_SETTINGS`, each lattice and both ways, every one of which passed
    the exact validator; ``None`` (obstacles, no lattice fits, every flow stalled, or the
    time limit).  After the first plan, tries go on within :data:`BEST_OF_SHARE` of the
    limit."""
    from .merge import merge_steps
    from .timing import _drop_idle
    from .validate import PlanInvalid, check_plan

    t0 = time.perf_counter()
    deadline = min(t0 + time_limit, deadline if deadline is not None else math.inf)
    if problem.obstacles:
        return None
    best = None
    for h, eps in FLOW_SETTINGS:
        for sites in packing_sites(problem):
            for target_first in (True, False):
                now = time.perf_counter()
                if now > deadline or (best is not None and now > t0 + BEST_OF_SHARE * time_limit):
                    return best
                a, b = (problem.target, problem.start) if target_first else (problem.start, problem.target)
                onto = flow(problem, a, sites, deadline, rng, h, eps)
                into = None if onto is None else flow(problem, b, onto[-1], deadline, rng, h, eps)
                w = None if into is None else _joined(into, onto) if target_first else _joined(onto, into)
                if w is None:
                    continue
                w = merge_steps(problem, _drop_idle(list(w)), deadline)
                result = Plan.from_waypoints(w, problem.radius, problem.margin, problem.max_speed, problem.max_accel)
                if best is not None and result.makespan >= best.makespan:
                    continue
                try:
                    check_plan(problem, result)
                except PlanInvalid:  # never expected: every step was checked
                    continue
                best = result
    return best
