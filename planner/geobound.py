"""A makespan lower bound that respects the obstacles: the bottleneck assignment
over shortest free-space distances, each computed so that it never exceeds the
true shortest distance of a robot centre around the obstacles.

A robot centre must stay at least ``c = radius + margin`` from every obstacle
and wall: out of the open set ``F`` of points closer than ``c`` to an
obstacle, and inside the box ``[c, W - c] x [c, H - c]``.  For a convex
polygon ``P``, ``F`` near ``P`` is ``P`` grown by a disc of radius ``c``
(rounded corners).  The bound replaces it by an *inscribed* polygon ``O``:
at every corner ``v`` the points ``v + c n1`` and ``v + c n2`` (``n1, n2`` the
outward unit normals of the two edges there), which lie on the boundary of
the grown polygon, so ``O`` (their convex hull) lies in its closure and the
interior of ``O`` in ``F``.  A disc obstacle is replaced by the regular
16-gon inscribed in its grown circle.  Non-convex polygons are left out.
Every feasible path avoids the interiors of the ``O``; the shortest path in
the box among the ``O`` (polygonal obstacles) bends only at their corners,
so the shortest paths of the *visibility graph* over the starts, the targets
and the corners of the ``O`` inside the box are at most the true shortest
distances.  Leaving obstacles out, or growing them less, only shortens them.

Visibility is tested against the ``O`` shrunk inward by ``delta = 1e-6 c``
(shapely's robust ``intersects`` over an STR tree): a segment that does not
enter the interior of any ``O`` keeps ``delta`` from the shrunk ones, so it
passes (the test can only admit more segments, which again only shortens
paths).  Corners that lie inside another shrunk ``O`` are dropped (no
shortest path can use them).  Every pair of nodes is tested: dropping long
pairs, as the guide's corner graph does for speed, could lengthen paths.

The makespan bound is :func:`planner.profile.step_duration` of the
bottleneck assignment distance over these lengths (the time scaling's
fastest rest-to-rest move over that distance).
"""

from __future__ import annotations

import math
import time

import numpy as np

from .bounds import _bottleneck
from .plan import step_duration
from .problem import Problem

__all__ = ["geo_distances", "geo_lower_bound"]

_DELTA = 1e-6  # inward shrink of the inscribed polygons, in units of the clearance
_CIRCLE_SIDES = 16
_CHUNK = 20_000  # segments per exact clearance call
_BLOCK = 8  # corners per block of the via-corner minimum


def _inscribed(problem: Problem) -> list[np.ndarray]:
    """The inscribed polygons ``O`` (counter-clockwise), one per convex polygon or disc."""
    c = problem.clearance
    out = []
    for ob in problem.obstacles:
        if hasattr(ob, "vertices"):
            v = np.asarray(ob.vertices, float)
            e = np.roll(v, -1, axis=0) - v  # edge k: v[k] -> v[k + 1]
            e2 = np.roll(e, -1, axis=0)
            cross = e[:, 0] * e2[:, 1] - e[:, 1] * e2[:, 0]
            if (cross < -1e-12 * np.abs(e).max() ** 2).any():
                continue  # not convex: left out (the bound stays valid)
            n = np.stack([e[:, 1], -e[:, 0]], axis=1)
            n /= np.linalg.norm(n, axis=1, keepdims=True)
            n_in = np.roll(n, 1, axis=0)  # normal of the edge into vertex k
            pts = np.stack([v + c * n_in, v + c * n], axis=1).reshape(-1, 2)
        else:
            ang = np.arange(_CIRCLE_SIDES) * 2 * np.pi / _CIRCLE_SIDES
            pts = np.asarray(ob.center, float) + (ob.radius + c) * np.stack([np.cos(ang), np.sin(ang)], axis=1)
        keep = np.linalg.norm(pts - np.roll(pts, 1, axis=0), axis=1) > 1e-12 * c
        pts = pts[keep]
        if len(pts) >= 3:
            out.append(pts)
    return out


def _shrunk(poly: np.ndarray, delta: float) -> np.ndarray:
    """A convex counter-clockwise polygon with every edge moved inward by ``delta``."""
    e = np.roll(poly, -1, axis=0) - poly
    n = np.stack([e[:, 1], -e[:, 0]], axis=1)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    n_in = np.roll(n, 1, axis=0)
    s = n_in + n
    return poly - delta * s / (1.0 + (n_in * n).sum(axis=1))[:, None]


def _world(problem: Problem, deadline: float | None = None):
    """``(corners (V, 2), their two polygon neighbours (V, 2, 2), STR tree of the shrunk
    polygons, corner-corner distances (V, V))`` (cached)."""
    cached = problem.__dict__.get("_geo_world")
    if cached is not None:
        return cached
    import shapely
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import shortest_path

    c = problem.clearance
    polys = _inscribed(problem)
    tree = shapely.STRtree([shapely.Polygon(_shrunk(p, _DELTA * c)) for p in polys])
    if not polys:
        z = np.zeros((0, 2))
        cached = (z, np.zeros((0, 2, 2)), tree, np.zeros((0, 0)))
        problem.__dict__["_geo_world"] = cached
        return cached
    nodes = np.concatenate(polys)
    side = np.concatenate([np.stack([np.roll(p, 1, axis=0), np.roll(p, -1, axis=0)], axis=1) for p in polys])
    tol = 1e-9 * max(problem.width, problem.height)
    keep = ((nodes[:, 0] >= c - tol) & (nodes[:, 0] <= problem.width - c + tol)
            & (nodes[:, 1] >= c - tol) & (nodes[:, 1] <= problem.height - c + tol))
    hit = tree.query(shapely.points(nodes), predicate="intersects")[0]
    keep[hit] = False
    nodes, side = nodes[keep], side[keep]
    v = len(nodes)
    keep_i, keep_j = [], []
    rows = max(1, _CHUNK // max(v, 1))
    for a0 in range(0, v, rows):  # pairs i < j, a block of rows i at a time
        if deadline is not None and time.perf_counter() > deadline:
            raise TimeoutError("geo lower bound")
        ci, cj = np.nonzero(np.arange(a0, min(a0 + rows, v))[:, None] < np.arange(v)[None])
        ci += a0
        t = _tangent(nodes, side, ci, nodes[cj]) & _tangent(nodes, side, cj, nodes[ci])
        ci, cj = ci[t], cj[t]
        ok = _clear(tree, nodes[ci], nodes[cj], deadline)
        keep_i.append(ci[ok])
        keep_j.append(cj[ok])
    ci, cj = np.concatenate(keep_i), np.concatenate(keep_j)
    w = np.linalg.norm(nodes[ci] - nodes[cj], axis=1) + 1e-300
    g = coo_matrix((np.r_[w, w], (np.r_[ci, cj], np.r_[cj, ci])), shape=(v, v)).tocsr()
    cached = (nodes, side, tree, shortest_path(g, method="D", directed=False))
    problem.__dict__["_geo_world"] = cached
    return cached


def _tangent(nodes: np.ndarray, side: np.ndarray, k: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Whether the line from corner ``nodes[k]`` to ``x`` supports the corner's polygon there
    (both polygon neighbours on one closed side): only such segments end or start a
    bend of a shortest path at a corner (taut-string argument), so the others are skipped."""
    u = nodes[k]
    d = x - u
    a = side[k, 0] - u
    b = side[k, 1] - u
    ca = d[:, 0] * a[:, 1] - d[:, 1] * a[:, 0]
    cb = d[:, 0] * b[:, 1] - d[:, 1] * b[:, 0]
    scale = 1e-12 * (np.abs(d).sum(axis=1) + 1.0) ** 2
    return ~(((ca > scale) & (cb < -scale)) | ((ca < -scale) & (cb > scale)))


def _clear(tree, a: np.ndarray, b: np.ndarray, deadline) -> np.ndarray:
    """Segments ``a -> b`` that meet none of the tree's (shrunk) polygons."""
    import shapely

    ok = np.ones(len(a), bool)
    for s in range(0, len(a), _CHUNK):
        if deadline is not None and time.perf_counter() > deadline:
            raise TimeoutError("geo lower bound")
        seg = np.stack([a[s : s + _CHUNK], b[s : s + _CHUNK]], axis=1)
        hit = tree.query(shapely.linestrings(seg), predicate="intersects")[0]
        ok[s + hit] = False
    return ok


def _via_corners(problem: Problem, starts, targets, deadline) -> np.ndarray:
    """``(m, n)`` shortest lengths start -> corners -> target (``inf`` if none)."""
    nodes, side, tree, dcc = _world(problem, deadline)
    m, n, v = len(starts), len(targets), len(nodes)
    if v == 0:
        return np.full((m, n), np.inf)
    out = []
    for pts in (starts, targets):
        p, k = np.divmod(np.arange(len(pts) * v), v)
        t = _tangent(nodes, side, k, pts[p])
        p, k = p[t], k[t]
        ok = _clear(tree, pts[p], nodes[k], deadline)
        d = np.full((len(pts), v), np.inf)
        d[p[ok], k[ok]] = np.linalg.norm(pts[p[ok]] - nodes[k[ok]], axis=1)
        out.append(d)
    ds, dt = out
    # min over first corner a and last corner b of ds[i, a] + dcc[a, b] + dt[j, b], in blocks
    to_last = np.full((m, v), np.inf)
    for a0 in range(0, v, _BLOCK):
        blk = ds[:, a0 : a0 + _BLOCK, None] + dcc[None, a0 : a0 + _BLOCK]  # (m, A, v)
        np.minimum(to_last, blk.min(axis=1), out=to_last)
    res = np.full((m, n), np.inf)
    for b0 in range(0, v, _BLOCK):
        blk = to_last[:, None, b0 : b0 + _BLOCK] + dt[None, :, b0 : b0 + _BLOCK]  # (m, n, B)
        np.minimum(res, blk.min(axis=2), out=res)
    return res


def geo_distances(problem: Problem, starts=None, targets=None, deadline: float | None = None) -> np.ndarray:
    """``(len(starts), len(targets))`` shortest lengths in the visibility graph of the
    module (lower bounds on the free-space distances; ``inf`` where it has no path).
    Defaults: the problem's start and target.  Raises ``TimeoutError`` when
    ``deadline`` passes first."""
    starts = np.asarray(problem.start if starts is None else starts, float)
    targets = np.asarray(problem.target if targets is None else targets, float)
    direct = np.linalg.norm(starts[:, None] - targets[None], axis=2)
    if not problem.obstacles:
        return direct
    via = _via_corners(problem, starts, targets, deadline)
    i, j = np.nonzero(direct < via)
    _, _, tree, _ = _world(problem)
    ok = _clear(tree, starts[i], targets[j], deadline)
    out = via.copy()
    out[i[ok], j[ok]] = direct[i[ok], j[ok]]
    return out


def _bottleneck_of(d: np.ndarray) -> float:
    from scipy.optimize import linear_sum_assignment

    d = np.where(np.isinf(d), 1e300, d)
    r, col = linear_sum_assignment(np.minimum(d, 1e12))
    return _bottleneck(d, float(d[r, col].max()))


def _decisive_distances(problem: Problem, deadline) -> np.ndarray:
    """:func:`geo_distances` of the problem where they can change the bottleneck, and
    lower bounds (the smaller of the straight and the via-corner length) elsewhere.

    With ``lo`` the bottleneck when every straight segment is taken to be clear and
    ``hi`` the one over via-corner paths only, the graph's bottleneck lies in
    ``[lo, hi]``; a pair's straight segment can only decide it when its length is
    below both the via length and ``hi`` and the via length is above ``lo``.  Only
    those segments are tested: the bottleneck of the result equals the graph's."""
    s, t = problem.start, problem.target
    direct = np.linalg.norm(s[:, None] - t[None], axis=2)
    if not problem.obstacles:
        return direct
    via = _via_corners(problem, s, t, deadline)
    low = np.minimum(via, direct)
    lo, hi = _bottleneck_of(low), _bottleneck_of(via)
    i, j = np.nonzero((direct < via) & (direct <= hi) & (via > lo))
    _, _, tree, _ = _world(problem)
    ok = _clear(tree, s[i], t[j], deadline)
    low[i[~ok], j[~ok]] = via[i[~ok], j[~ok]]
    return low


def geo_lower_bound(problem: Problem, deadline: float | None = None) -> float:
    """Makespan lower bound [s] over shortest free-space distances (cached; see the module).

    ``inf`` when some start cannot reach enough targets in the visibility graph; raises
    ``TimeoutError`` when ``deadline`` passes first (nothing is cached then)."""
    cached = problem.__dict__.get("_geo_lower_bound")
    if cached is not None:
        return cached
    if problem.m == 0:
        return 0.0
    d = _decisive_distances(problem, deadline)
    big = np.isinf(d)
    if big.any():
        finite = d[~big]
        d = np.where(big, (finite.max() if len(finite) else 1.0) * 1e6, d)
    from scipy.optimize import linear_sum_assignment

    r, col = linear_sum_assignment(d)
    high = float(d[r, col].max())
    d_star = _bottleneck(d, high)
    bound = math.inf if d_star >= 1e5 * max(problem.width, problem.height) else float(
        step_duration(d_star, problem.max_speed, problem.max_accel))
    problem.__dict__["_geo_lower_bound"] = bound
    problem.__dict__["_geo_bottleneck"] = d_star
    return bound
