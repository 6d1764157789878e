"""A makespan lower bound from narrow passages: robots pass a cut one at a time.

Let ``c = radius + margin``, ``s = 2 radius + margin`` (the separation),
``v`` and ``A`` the speed and acceleration limits.  A robot centre stays in
the free space ``F`` (points at least ``c`` from every obstacle and wall).
The bound works with an over-approximation ``F'`` of ``F``: obstacles grown
by ``c - delta`` with round joins inscribed in the true arcs, the box shrunk
by ``c - delta`` (as in :mod:`planner.feasibility`), so ``F`` lies in ``F'``.

A *cut* is a thin rectangle ``Q`` (half-width ``eps``) around a segment
across a passage between two obstacles, or an obstacle and a wall.  Let
``a`` be the diameter of ``Q`` meet ``F'`` (computed from its convex hull,
rounded up); only cuts with ``a < s`` are used.  Let ``U`` be the union of
the components of ``F' - Q`` holding more starts than targets, and
``k = sum over those components of (starts - targets)``.

Claim: every plan that honours ``v`` and ``A`` and starts and ends at rest has

    T >= max( max_j [tau(d_j) + (k - j) D] + tau(e_1),
              max_j [tau(e_j) + (k - j) D] + tau(d_1) ),   j = 1 .. k,

with ``D = (s - a) / v``, ``d_1 <= d_2 <= ...`` the distances from the
starts in ``U`` to ``Q`` meet ``F'``, ``e_1 <= e_2 <= ...`` those of the
targets outside ``U``, and ``tau(d)`` the shortest time to cover ``d`` from
rest under ``v`` and ``A`` (``sqrt(2 d / A)`` up to ``v^2 / (2 A)``, else
``d / v + v / (2 A)``; the speed at time ``t`` is at most ``min(A t, v)``).
``tau`` is the pure kinematic bound, valid mid-step too, so it does not
rely on the plan's time scaling (:func:`planner.profile.step_duration`
bounds whole rest-to-rest steps only).

Proof.  At most ``n_t(C)`` robots end in a component ``C``, so at least
``k`` robots start in ``U`` and end outside it (no start or target lies in
``Q``: such cuts are skipped).  A robot's path is continuous and stays in
``F``, inside ``F'``; leaving the component of ``F' - Q`` it starts in, it
is in ``Q`` at some time ``t_i``, at a point ``x_i`` of ``Q`` meet ``F'``.
For two such robots ``i, j``: at ``t_i`` robot ``j`` is within
``v |t_i - t_j|`` of ``x_j``, and must be ``s`` from ``x_i``, so
``s <= |x_i - x_j| + v |t_i - t_j| <= a + v |t_i - t_j|``, i.e. their times
are ``D`` apart.  At most ``j - 1`` starts in ``U`` lie nearer than
``d_j``, so at least ``k - j + 1`` crossing robots need ``t_i >= tau(d_j)``;
their times are ``D`` apart, so the latest is at least
``tau(d_j) + (k - j) D``, and that robot still has ``e_1`` or more to go to
a target, where it arrives at rest (``tau`` again, backwards in time).
The second term is the same argument with time reversed (targets outside
``U``).  Every distance is the exact Euclidean distance to ``Q`` meet ``F'``
less a hair, ``a`` is rounded up, and ``D``, ``tau`` only grow with ``a`` and
shrink with the distances, so rounding keeps the bound valid.

Cuts are the shortest segments between pairs of obstacle features closer
than ``2 c + s`` (shapely's ``shortest_line``), narrowest first, at most
:data:`MAX_CUTS`; the bound is the largest over them, NaN when none applies
(no narrow passage, or none with ``k >= 1``) or when ``deadline`` passes.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from .problem import Circle, Problem

__all__ = ["MAX_CUTS", "Cut", "best_lower_bound", "crossing_time", "cut_lower_bound", "cuts", "obstacle_shapes"]

MAX_CUTS = 64  # candidate cuts evaluated, narrowest first
_QUAD_SEGS = 16
_EPS = 1e-6  # half-width of a cut, in units of the clearance


@dataclass(frozen=True)
class Cut:
    """One cut: the segment ``p``-``q``, the diameter ``a`` of its free part, ``k``
    robots that must cross it, and the makespan bound ``bound`` [s] it proves."""

    p: tuple[float, float]
    q: tuple[float, float]
    a: float
    k: int
    bound: float


def crossing_time(d, max_speed: float, max_accel: float):
    """Shortest time to cover ``d`` from rest (or to rest) with speed at most ``max_speed``
    and acceleration at most ``max_accel`` (any motion, not only the plan's time scaling)."""
    d = np.maximum(np.asarray(d, float), 0.0)
    ramp = max_speed * max_speed / (2.0 * max_accel)
    t = np.where(d <= ramp, np.sqrt(2.0 * d / max_accel), d / max_speed + max_speed / (2.0 * max_accel))
    return t if t.ndim else float(t)


def _free_space(problem: Problem, grow: float):
    """``F'``: the box shrunk by ``grow`` minus every obstacle grown by ``grow``."""
    import shapely
    from shapely.geometry import Point, box
    from shapely.geometry import Polygon as ShapelyPolygon

    grown = []
    for ob in problem.obstacles:
        if isinstance(ob, Circle):
            grown.append(Point(ob.center).buffer(ob.radius + grow, quad_segs=_QUAD_SEGS))
        else:
            g = ShapelyPolygon(ob.vertices)
            if not g.is_valid:
                g = shapely.make_valid(g)
            grown.append(g.buffer(grow, quad_segs=_QUAD_SEGS))
    room = box(grow, grow, problem.width - grow, problem.height - grow)
    free = room.difference(shapely.union_all(grown)) if grown else room
    return [g for g in getattr(free, "geoms", [free]) if g.geom_type == "Polygon" and g.area > 0]


def obstacle_shapes(problem: Problem) -> list:
    """The obstacles as shapely polygons (circles inscribed, :data:`_QUAD_SEGS` segments a
    quarter circle)."""
    from shapely.geometry import Point
    from shapely.geometry import Polygon as ShapelyPolygon

    return [Point(ob.center).buffer(ob.radius, quad_segs=_QUAD_SEGS) if isinstance(ob, Circle)
            else ShapelyPolygon(ob.vertices).buffer(0) for ob in problem.obstacles]


def _features(problem: Problem) -> list:
    """Obstacles (circles as inscribed polygons: only where a cut is tried) and the four walls."""
    from shapely.geometry import LineString

    out = obstacle_shapes(problem)
    w, h = problem.width, problem.height
    corners = [(0, 0), (w, 0), (w, h), (0, h)]
    out += [LineString([corners[i], corners[(i + 1) % 4]]) for i in range(4)]
    return out


def _candidates(problem: Problem, feats: list) -> list[tuple[np.ndarray, np.ndarray, float]]:
    """Shortest segments ``(p, q, g)`` between features with ``0 < g < 2 c + s``, narrowest first."""
    import shapely

    hi = 2 * problem.clearance + problem.separation
    tree = shapely.STRtree(feats)
    ia, ib = tree.query(feats, predicate="dwithin", distance=hi)
    keep = ia < ib
    ia, ib = ia[keep], ib[keep]
    if len(ia) == 0:
        return []
    arr = np.asarray(feats, dtype=object)
    lines = shapely.shortest_line(arr[ia], arr[ib])
    xy = shapely.get_coordinates(lines).reshape(-1, 2, 2)
    g = np.linalg.norm(xy[:, 1] - xy[:, 0], axis=1)
    ok = (g > 0) & (g < hi)
    order = np.flatnonzero(ok)[np.argsort(g[ok], kind="stable")]
    return [(xy[i, 0], xy[i, 1], float(g[i])) for i in order.tolist()]


def _diameter(geom) -> float:
    import shapely

    pts = shapely.get_coordinates(geom.convex_hull)
    if len(pts) < 2:
        return 0.0
    return float(np.linalg.norm(pts[:, None] - pts[None], axis=2).max())


def _bound(k: int, gap: float, ds: np.ndarray, es: np.ndarray, problem: Problem) -> float:
    """The claim's right-hand side for ``k`` crossings ``gap`` seconds apart."""
    v, acc = problem.max_speed, problem.max_accel
    j = np.arange(k)  # j - 1 of the docstring
    ts = crossing_time(np.sort(ds)[:k], v, acc)
    te = crossing_time(np.sort(es)[:k], v, acc)
    first = float((ts + (k - 1 - j) * gap).max()) + float(te[0])
    second = float((te + (k - 1 - j) * gap).max()) + float(ts[0])
    return max(first, second)


def _locate(parts: list, points: np.ndarray) -> np.ndarray | None:
    """The part index holding each point (``None`` when some point is in none or in two)."""
    import shapely

    tree = shapely.STRtree(parts)
    pts = shapely.points(points)
    idx_pt, idx_part = tree.query(pts)  # boxes only: the exact test below runs on prepared parts
    shapely.prepare(parts)  # (a maze's free space is one polygon of thousands of vertices)
    keep = shapely.intersects(np.asarray(parts, dtype=object)[idx_part], pts[idx_pt])
    idx_pt, idx_part = idx_pt[keep], idx_part[keep]
    if len(points) and (np.bincount(idx_pt, minlength=len(points)) != 1).any():
        return None
    out = np.empty(len(points), int)
    out[idx_pt] = idx_part
    return out


def _evaluate(problem: Problem, parts: list, p: np.ndarray, q: np.ndarray) -> Cut | None:
    import shapely
    from shapely.geometry import LineString

    c, sep = problem.clearance, problem.separation
    u = (q - p) / np.linalg.norm(q - p)
    seg = LineString([p - 0.5 * c * u, q + 0.5 * c * u])
    rect = seg.buffer(_EPS * c, cap_style="flat")
    hit = [i for i, g in enumerate(parts) if g.intersects(rect)]
    if not hit:
        return None
    piece = shapely.union_all([parts[i].intersection(rect) for i in hit])
    if piece.is_empty:
        return None
    extent = max(problem.width, problem.height)
    a = _diameter(piece) * (1 + 1e-9) + 1e-9 * extent
    if a >= sep:
        return None
    pieces = [part for i, part in enumerate(parts) if i not in hit]
    for i in hit:
        rest = parts[i].difference(rect)
        pieces += [g for g in getattr(rest, "geoms", [rest]) if g.geom_type == "Polygon" and g.area > 0]
    ws, wt = _locate(pieces, problem.start), _locate(pieces, problem.target)
    if ws is None or wt is None:
        return None
    surplus = np.bincount(ws, minlength=len(pieces)) - np.bincount(wt, minlength=len(pieces))
    k = int(surplus[surplus > 0].sum())
    if k < 1:
        return None
    in_u = surplus > 0
    tol = 1e-9 * extent
    ds = shapely.distance(shapely.points(problem.start[in_u[ws]]), piece) - tol
    es = shapely.distance(shapely.points(problem.target[~in_u[wt]]), piece) - tol
    gap = (sep - a) / problem.max_speed
    bound = _bound(k, gap, ds, es, problem)
    return Cut((float(p[0]), float(p[1])), (float(q[0]), float(q[1])), a, k, bound)


def cuts(problem: Problem, deadline: float | None = None) -> list[Cut]:
    """Every cut that proves a bound (see the module's docstring), narrowest first.

    Raises ``TimeoutError`` when ``deadline`` (a ``time.perf_counter`` value) passes.
    """
    if problem.m == 0 or not problem.obstacles:
        return []
    c = problem.clearance
    delta = 1e-7 + 1e-12 * max(problem.width, problem.height)
    grow = c - delta
    if problem.width <= 2 * grow or problem.height <= 2 * grow:
        return []
    parts = _free_space(problem, grow)
    out = []
    seen: list[np.ndarray] = []
    for p, q, _ in _candidates(problem, _features(problem)):
        if deadline is not None and time.perf_counter() > deadline:
            raise TimeoutError("cut bound: out of its time budget")
        mid = 0.5 * (p + q)
        if any(np.linalg.norm(mid - s) < 0.5 * problem.separation for s in seen):
            continue  # the same passage again (another pair of edges of it)
        seen.append(mid)
        if len(seen) > MAX_CUTS:
            break
        cut = _evaluate(problem, parts, p, q)
        if cut is not None:
            out.append(cut)
    return out


def cut_lower_bound(problem: Problem, deadline: float | None = None) -> float:
    """The largest makespan bound [s] over the cuts of ``problem``; NaN when no cut
    applies or ``deadline`` (a ``time.perf_counter`` value) passes first."""
    try:
        found = cuts(problem, deadline)
    except TimeoutError:
        return math.nan
    return max((x.bound for x in found), default=math.nan)


def best_lower_bound(stats) -> float:
    """The largest finite makespan bound of a :class:`planner.stats.PlanStats` (NaN: none)."""
    values = [getattr(stats, name, math.nan) for name in
              ("makespan_lower_bound_s", "makespan_lower_bound_geo_s", "makespan_lower_bound_cut_s")]
    finite = [float(v) for v in values if v is not None and math.isfinite(v)]
    return max(finite, default=math.nan)
