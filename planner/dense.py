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

Among obstacles (a hall with pillars, the arena of a ROS map): the lattices' points
are kept where they are clear of the obstacles, and shifted copies at the
separation join the candidates (the roomiest few are tried); a flow step that is
not clear of the obstacles keeps its robot where it was, and a robot pushed closer
than the clearance to an obstacle is moved back out along the clearance's
gradient.  Where a lattice has room to spare, auto mode tries :mod:`planner.packmeet`
(both placements onto one square lattice, the grid stage between them) first.
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

__all__ = ["BEST_OF_SHARE", "FLOW_SETTINGS", "FLOW_STEPS", "dense", "dense_plan", "flow", "packing_sites", "step_ok"]

#: Steps a flow may take before it gives up.
FLOW_STEPS = 300
# Lengths below are for the separation of 2.1 (robots of radius 1, margin 0.1) and
# scale with a problem's separation (:func:`_unit`).
_REF_SEPARATION = 2.1
_EPS = 0.03  # pairs pushed apart to separation + _EPS
_H = 0.15  # longest move of a flow step
_SNAP = 1e-3  # a robot this close to its site lands on it
_PATIENCE = 8  # flow steps without a better matched distance before noise
_MAX_LATTICES = 4  # lattices tried among obstacles (the ones with the most clear points)


def dense(problem: Problem, threshold: float) -> bool:
    """Whether the robots' discs cover at least ``threshold`` of the workspace's area
    outside the obstacles (their union, clipped to the workspace; not computed where the
    sum of the obstacles' areas already shows the coverage below ``threshold``)."""
    import shapely

    box = problem.width * problem.height
    discs = problem.m * math.pi * problem.radius**2
    if not problem.obstacles:
        return discs >= threshold * box
    from .cutbound import obstacle_shapes

    shapes = obstacle_shapes(problem)
    least_free = box - sum(s.area for s in shapes)  # overlaps counted twice: at most the free area
    if least_free > 0 and discs < threshold * least_free:
        return False
    taken = shapely.union_all(shapes).intersection(shapely.box(0, 0, problem.width, problem.height)).area
    return discs >= threshold * (box - taken)


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


def packing_sites(problem: Problem, deadline: float = math.inf) -> list[np.ndarray]:
    """Lattices of clear points pairwise at least the separation apart, each with at least
    ``m`` points: the square grid spanning the box when it is big enough, then the brick
    lattice with rows along x and along y (see the module docstring); those tested
    before ``deadline`` (on a large map each costs about 0.1 s)."""
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
    out = [None if s is None else s + lo for s in out]
    if problem.obstacles:  # obstacles take points: the lattices at their own spacing, shifted too
        out += _shifted(problem, lo, wx, wy)
    keep = []
    for s in out:
        if s is None:
            continue
        if time.perf_counter() > deadline:
            break
        s = s[problem.env.points_clear(s, problem.clearance)]
        if len(s) >= problem.m and (len(s) < 2 or cKDTree(s).query(s, 2)[0][:, 1].min() >= sep):
            keep.append(s)
    if problem.obstacles:  # the roomiest first, a few
        keep = sorted(keep, key=len, reverse=True)[:_MAX_LATTICES]
    return keep


def _shifted(problem: Problem, lo: float, wx: float, wy: float) -> list[np.ndarray]:
    """The square and brick lattices at the separation (a hair more), shifted by thirds of
    it along both axes: among obstacles a shift can hold many more clear points."""
    sep = problem.separation * (1 + 1e-9)
    square = np.stack(np.meshgrid(np.arange(int(wx // sep) + 2) * sep, np.arange(int(wy // sep) + 2) * sep,
                                  indexing="ij"), axis=-1).reshape(-1, 2)
    brick = _brick(wx + sep, wy + sep, sep)
    out = []
    for base in (square, brick):
        if base is None:
            continue
        for fx in (0.0, 1 / 3, 2 / 3):
            for fy in (0.0, 1 / 3, 2 / 3):
                pts = base + lo - sep * np.array([fx, fy])
                inside = (pts[:, 0] >= lo) & (pts[:, 1] >= lo) & (pts[:, 0] <= lo + wx) & (pts[:, 1] <= lo + wy)
                out.append(pts[inside])
    return out


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
    if problem.obstacles:
        x = _off_obstacles(problem, x, eps)
    return x


def _off_obstacles(problem: Problem, x: np.ndarray, eps: float) -> np.ndarray:
    """Centres pushed closer than the clearance to an obstacle moved back out along the
    clearance's gradient (central differences of the exact clearance) to ``clearance +
    eps``; a centre inside an obstacle (no gradient) is left for the step test, which
    keeps it where it was.  Centres still clear stay put: a site next to an obstacle
    stays reachable (pushing every centre nearer than ``clearance + eps`` kept robots
    off such sites for good)."""
    env, c = problem.env, problem.clearance
    out = np.flatnonzero(~env.points_clear(x, c))  # the indexed exact test first
    if len(out) == 0:
        return x
    clr = env.point_clearance(x[out])
    inside = (clr < c) & (clr > 0)
    near, clr = out[inside], clr[inside]
    if len(near) == 0:
        return x
    p = x[near]
    d = 1e-6 * problem.separation
    grad = np.stack([env.point_clearance(p + [d, 0]) - env.point_clearance(p - [d, 0]),
                     env.point_clearance(p + [0, d]) - env.point_clearance(p - [0, d])], axis=1) / (2 * d)
    norm = np.linalg.norm(grad, axis=1)
    ok = norm > 0.5  # the wall or an obstacle, not a ridge between two
    x = x.copy()
    want = c + eps
    x[near[ok]] += ((want - clr[ok]) / norm[ok])[:, None] * grad[ok]
    return x


_NEAR_SITES = 16  # sites per robot in the sparse matching (:func:`_assign`)


def _assign(x: np.ndarray, sites: np.ndarray) -> np.ndarray:
    """The site of every robot in the minimum sum-of-squares matching.  With many more sites
    than robots (at least twice as many) the matching is first sought among each robot's
    :data:`_NEAR_SITES` nearest sites (a sparse problem, exact on that graph), and the full
    one only where that has no complete matching."""
    m, n = len(x), len(sites)
    if n >= 2 * m and n > _NEAR_SITES:
        from scipy.sparse import csr_matrix
        from scipy.sparse.csgraph import min_weight_full_bipartite_matching

        d, j = cKDTree(sites).query(x, _NEAR_SITES)
        graph = csr_matrix((d.ravel() ** 2 + 1e-300, (np.repeat(np.arange(m), _NEAR_SITES), j.ravel())), shape=(m, n))
        try:
            return min_weight_full_bipartite_matching(graph)[1]
        except ValueError:  # no complete matching among the nearest sites
            pass
    return linear_sum_assignment(((x[:, None] - sites[None]) ** 2).sum(axis=2))[1]


def flow(problem: Problem, x: np.ndarray, sites: np.ndarray, deadline: float,
         rng: np.random.Generator, h: float = _H, eps: float = _EPS, steps: int = FLOW_STEPS
         ) -> list[np.ndarray] | None:
    """Waypoints from the placement ``x`` to one on ``m`` of ``sites`` (every step exactly
    clear), or ``None`` past ``steps`` steps or the deadline.  ``h`` and ``eps``
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
    for _ in range(steps):
        if time.perf_counter() > deadline:
            return None
        col = _assign(x, sites)
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
        if problem.obstacles:  # a move that is not clear of the obstacles: the robot stays
            moved = np.flatnonzero(np.any(nxt != x, axis=1))
            blocked = moved[~problem.env.segments_clear(x[moved], nxt[moved], problem.clearance)]
            nxt[blocked] = x[blocked]
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


def _better(problem: Problem, w, best: Plan | None, deadline: float) -> Plan | None:
    """The plan of raw waypoints ``w`` (merged, exactly validated) when shorter than ``best``."""
    from .merge import merge_steps
    from .timing import _drop_idle
    from .validate import PlanInvalid, check_plan

    if w is None:
        return None
    w = merge_steps(problem, _drop_idle(list(w)), deadline)
    result = Plan.from_waypoints(w, problem.radius, problem.margin, problem.max_speed, problem.max_accel)
    if best is not None and result.makespan >= best.makespan:
        return None
    try:
        check_plan(problem, result)
    except PlanInvalid:  # never expected: every step was checked
        return None
    return result


def dense_plan(problem: Problem, time_limit: float, rng: np.random.Generator,
               deadline: float | None = None) -> Plan | None:
    """The shortest of the plans through a lattice (see the module docstring) found by the
    tries of :data:`FLOW_SETTINGS`, each lattice and both ways, every one of which passed
    the exact validator; ``None`` (no lattice fits, every flow stalled, or the time
    limit).  After the first plan, tries go on within :data:`BEST_OF_SHARE` of the
    limit."""
    t0 = time.perf_counter()
    deadline = min(t0 + time_limit, deadline if deadline is not None else math.inf)
    best = None
    lattices = packing_sites(problem, deadline)
    for h, eps in FLOW_SETTINGS:
        for sites in lattices:
            for target_first in (True, False):
                now = time.perf_counter()
                if now > deadline or (best is not None and now > t0 + BEST_OF_SHARE * time_limit):
                    return best
                a, b = (problem.target, problem.start) if target_first else (problem.start, problem.target)
                onto = flow(problem, a, sites, deadline, rng, h, eps)
                into = None if onto is None else flow(problem, b, onto[-1], deadline, rng, h, eps)
                w = None if into is None else _joined(into, onto) if target_first else _joined(onto, into)
                best = _better(problem, w, best, deadline) or best
    return best
