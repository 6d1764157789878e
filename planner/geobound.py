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

Visibility is tested against the ``O`` shrunk inward by ``delta = 1e-6 c``:
a segment that does not enter the interior of any ``O`` keeps ``delta`` from
the shrunk ones, so it passes (the test can only admit more segments, which
again only shortens paths).  A segment is blocked when one of its sample
points falls in a cell of a raster that lies inside a shrunk ``O`` (a proof
that it meets one); the rest go to shapely's robust ``intersects`` over an
STR tree.  Only the corners where the union of the ``O`` is convex are graph
vertices (:func:`_union_corners`; no shortest path bends at the others).  Only segments that support the polygon at
each corner end (both neighbours on one side: the taut-string condition)
are graph edges.

Lengths up to a cap ``T`` only: a path of length at most ``T`` has no segment
longer than ``T``, so the graph of the segments up to ``T`` and a Dijkstra
search from each target stopped at ``T`` give every distance up to ``T``
exactly and tell the others apart as longer.  When the bottleneck of those
distances (the unknown ones counted as just above ``T``) is at most ``T``,
it is the bottleneck of the full graph; otherwise ``T`` grows (first
``1.3`` times the straight-line bottleneck, then by a quarter) up to the whole
graph (at once when there are at most 1000 corners).  Never dropping a
segment that a path up to ``T`` could use keeps the result equal to that of
the whole graph.

The makespan bound is :func:`planner.profile.step_duration` of the
bottleneck assignment distance over these lengths (the time scaling's
fastest rest-to-rest move over that distance).
"""

from __future__ import annotations

import math
import time

import numpy as np

from .bounds import _bottleneck, _perfect
from .geopolys import _inscribed, _shrunk, _union_corners
from .plan import step_duration
from .problem import Problem

__all__ = ["geo_distances", "geo_lower_bound"]

_DELTA = 1e-6  # inward shrink of the inscribed polygons, in units of the clearance
_CHUNK = 20_000  # segments per exact clearance call
_SAMPLES = 2_000_000  # raster samples per step of the blocking filter
_RASTER_CELLS = 4_000_000  # at most this many raster cells
_ROWS = 256  # corners per block of the pair search
_FIRST, _GROW = 1.3, 1.25  # first length cap over the straight bottleneck, and its growth
_SMALL = 1000  # at most this many corners: no length cap


def _check(deadline) -> None:
    if deadline is not None and time.perf_counter() > deadline:
        raise TimeoutError("geo lower bound")


class _World:
    """The corners, their polygon neighbours, the STR tree and raster of the shrunk
    polygons, and the corner-corner edges found so far (up to length ``reach``)."""

    def __init__(self, problem: Problem) -> None:
        import shapely

        c = problem.clearance
        polys = _inscribed(problem)
        shrunk = [_shrunk(p, _DELTA * c) for p in polys]
        self.tree = shapely.STRtree([shapely.Polygon(p) for p in shrunk])
        self.diag = math.hypot(problem.width, problem.height)
        self.reach = 0.0
        self.edges: list[np.ndarray] = [np.zeros((0, 3))]
        self._raster(problem, shrunk)
        if not polys:
            self.nodes, self.side = np.zeros((0, 2)), np.zeros((0, 2, 2))
            return
        tol = 1e-9 * max(problem.width, problem.height)
        nodes, side = _union_corners(polys, tol)
        keep = ((nodes[:, 0] >= c - tol) & (nodes[:, 0] <= problem.width - c + tol)
                & (nodes[:, 1] >= c - tol) & (nodes[:, 1] <= problem.height - c + tol))
        keep[self.tree.query(shapely.points(nodes), predicate="intersects")[0]] = False
        self.nodes, self.side = nodes[keep], side[keep]

    def _raster(self, problem: Problem, shrunk: list[np.ndarray]) -> None:
        """``self.full[ix, iy]``: the cell ``[ix h, (ix + 1) h] x [iy h, (iy + 1) h]`` lies
        inside a shrunk polygon (all four corners strictly inside a convex one)."""
        h = max(problem.clearance / 2, math.sqrt(problem.width * problem.height / _RASTER_CELLS))
        nx, ny = max(1, math.ceil(problem.width / h)), max(1, math.ceil(problem.height / h))
        full = np.zeros((nx, ny), bool)
        for q in shrunk:
            x0, y0 = np.clip(np.ceil(q.min(axis=0) / h).astype(int), 0, [nx, ny])
            x1, y1 = np.clip(np.floor(q.max(axis=0) / h).astype(int), 0, [nx, ny])
            if x1 <= x0 or y1 <= y0:
                continue
            gx, gy = np.meshgrid(np.arange(x0, x1 + 1) * h, np.arange(y0, y1 + 1) * h, indexing="ij")
            inside = np.ones(gx.shape, bool)
            e = np.roll(q, -1, axis=0) - q
            for k in range(len(q)):
                scale = 1e-9 * (abs(e[k]).sum() + 1.0) * (problem.width + problem.height)
                inside &= e[k, 0] * (gy - q[k, 1]) - e[k, 1] * (gx - q[k, 0]) > scale
            full[x0:x1, y0:y1] |= inside[:-1, :-1] & inside[1:, :-1] & inside[:-1, 1:] & inside[1:, 1:]
        self.h, self.full = h, full

    def sampled_hit(self, a: np.ndarray, b: np.ndarray, step: float) -> np.ndarray:
        """Segments ``a -> b`` with a sample point (spacing about ``step``) in a full raster
        cell: they meet a shrunk polygon."""
        out = np.zeros(len(a), bool)
        k = np.maximum(1, np.ceil(np.linalg.norm(b - a, axis=1) / step)).astype(np.int64)
        ends = np.cumsum(k)
        s0 = 0
        while s0 < len(a):
            s1 = max(s0 + 1, int(np.searchsorted(ends, ends[s0] - k[s0] + _SAMPLES, side="right")))
            kk = k[s0:s1]
            seg = np.repeat(np.arange(s0, s1), kk)
            t = (np.arange(len(seg)) - np.repeat(np.cumsum(kk) - kk, kk) + 0.5) / k[seg]
            p = a[seg] + t[:, None] * (b[seg] - a[seg])
            ix = np.clip((p[:, 0] / self.h).astype(np.int64), 0, self.full.shape[0] - 1)
            iy = np.clip((p[:, 1] / self.h).astype(np.int64), 0, self.full.shape[1] - 1)
            out[seg[self.full[ix, iy]]] = True
            s0 = s1
        return out

    def clear(self, a: np.ndarray, b: np.ndarray, deadline) -> np.ndarray:
        """Segments ``a -> b`` that meet none of the shrunk polygons."""
        import shapely

        ok = np.ones(len(a), bool)
        for s in range(0, len(a), _CHUNK):
            _check(deadline)
            idx = np.arange(s, min(s + _CHUNK, len(a)))
            for step in (16 * self.h, 4 * self.h):
                idx = idx[~self.sampled_hit(a[idx], b[idx], step)]
            ok[s : s + _CHUNK] = False
            ok[idx] = True
            if len(idx):
                hit = self.tree.query(shapely.linestrings(np.stack([a[idx], b[idx]], axis=1)), predicate="intersects")[0]
                ok[idx[hit]] = False
        return ok

    def near(self, pts: np.ndarray | None, r0: float, r1: float, deadline):
        """``(i, k, length)`` of the pairs point ``i`` (or corner ``i < k`` when ``pts`` is
        None) and corner ``k`` with ``r0 < length <= r1``, tangent at the corners, clear."""
        from scipy.spatial import cKDTree

        v = len(self.nodes)
        src = self.nodes if pts is None else pts
        if v == 0 or len(src) == 0 or r1 <= r0:
            return np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0)
        tree = cKDTree(self.nodes)
        out_i, out_k = [], []
        for a0 in range(0, len(src), _ROWS):
            _check(deadline)
            blk = cKDTree(src[a0 : a0 + _ROWS]).sparse_distance_matrix(tree, min(r1, 2 * self.diag), output_type="ndarray")
            i, k, d = blk["i"].astype(np.int64) + a0, blk["j"].astype(np.int64), blk["v"]
            sel = (d > r0) & ((i < k) if pts is None else True)
            i, k = i[sel], k[sel]
            t = _tangent(self.nodes, self.side, k, src[i])
            if pts is None:
                t &= _tangent(self.nodes, self.side, i, src[k])
            i, k = i[t], k[t]
            ok = self.clear(src[i], self.nodes[k], deadline)
            out_i.append(i[ok])
            out_k.append(k[ok])
        i, k = np.concatenate(out_i), np.concatenate(out_k)
        return i, k, np.linalg.norm(src[i] - self.nodes[k], axis=1)

    def grow(self, r: float, deadline) -> None:
        """Corner-corner edges up to length ``r``."""
        if r > self.reach:
            i, k, w = self.near(None, self.reach, r, deadline)
            self.edges.append(np.stack([i, k, w], axis=1))
            self.reach = r


def _world(problem: Problem) -> _World:
    world = problem.__dict__.get("_geo_world")
    if world is None:
        world = problem.__dict__["_geo_world"] = _World(problem)
    return world


class _Via:
    """Shortest start -> corners -> target lengths up to a cap (``inf`` beyond)."""

    def __init__(self, world: _World, starts: np.ndarray, targets: np.ndarray) -> None:
        self.world, self.starts, self.targets = world, starts, targets
        self.reach = 0.0
        self.s_edges: list[tuple] = []
        self.t_edges: list[tuple] = []

    def lengths(self, cap: float, deadline) -> np.ndarray:
        """``(m, n)`` lengths up to ``cap`` (exact there, ``inf`` above)."""
        from scipy.sparse import coo_matrix
        from scipy.sparse.csgraph import dijkstra

        w = self.world
        r = min(cap, 2 * w.diag)  # no segment is longer than the box's diagonal
        w.grow(r, deadline)
        if r > self.reach:
            self.s_edges.append(w.near(self.starts, self.reach, r, deadline))
            self.t_edges.append(w.near(self.targets, self.reach, r, deadline))
            self.reach = r
        v, m, n = len(w.nodes), len(self.starts), len(self.targets)
        cc = np.concatenate(w.edges)
        si, sk, sw = (np.concatenate(x) for x in zip(*self.s_edges))
        ti, tk, tw = (np.concatenate(x) for x in zip(*self.t_edges))
        a, b = cc[:, 0].astype(np.int64), cc[:, 1].astype(np.int64)
        rows = np.concatenate([a, b, v + ti, sk])
        cols = np.concatenate([b, a, tk, v + n + si])
        wts = np.concatenate([cc[:, 2], cc[:, 2], tw, sw]) + 1e-300  # no explicit zeros
        g = coo_matrix((wts, (rows, cols)), shape=(v + n + m, v + n + m)).tocsr()
        _check(deadline)
        d = dijkstra(g, directed=True, indices=v + np.arange(n), limit=cap)
        return np.ascontiguousarray(d[:, v + n :].T)


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
    world = _world(problem)
    via = _Via(world, starts, targets).lengths(math.inf, deadline)
    i, j = np.nonzero(direct < via)
    ok = world.clear(starts[i], targets[j], deadline)
    out = via.copy()
    out[i[ok], j[ok]] = direct[i[ok], j[ok]]
    return out


def _bottleneck_of(d: np.ndarray) -> float:
    from scipy.optimize import linear_sum_assignment

    d = np.where(np.isinf(d), 1e300, d)
    r, col = linear_sum_assignment(np.minimum(d, 1e12))
    return _bottleneck(d, float(d[r, col].max()))


def _graph_bottleneck(problem: Problem, deadline) -> float:
    """The bottleneck of :func:`geo_distances` of the problem (``>= 1e300`` when it has no
    perfect assignment), with the length cap of the module.

    At a cap ``T``, ``via`` (exact up to ``T``) gives ``low``, the via length or ``T+``
    (just above ``T``) where unknown; ``lo`` the bottleneck of ``min(direct, low)``,
    ``hi`` the one of the known via lengths.  A pair's straight segment can only
    decide the bottleneck when ``direct < low``, ``direct <= hi`` and ``low > lo``:
    only those are tested (the others keep ``min(direct, low)``).  Every entry is
    then at most the graph's length, and every entry up to the result ``b`` equals a
    length up to ``b`` when ``b <= T``: ``b`` is the graph's bottleneck."""
    s, t = problem.start, problem.target
    direct = np.linalg.norm(s[:, None] - t[None], axis=2)
    if not problem.obstacles:
        return _bottleneck_of(direct)
    world = _world(problem)
    via_of = _Via(world, s, t)
    cap = _FIRST * _bottleneck_of(direct) + 1e-9 * world.diag if len(world.nodes) > _SMALL else math.inf
    seen = np.zeros(direct.shape, np.int8)  # straight segment: 0 not tested, 1 clear, 2 blocked
    while True:
        if cap > 4 * world.diag:
            cap = math.inf
        via = via_of.lengths(cap, deadline)
        low = np.where(np.isinf(via), np.nextafter(cap, math.inf), via)
        best = np.minimum(direct, low)
        if not _perfect(best <= cap):  # even the lower bounds need more than the cap
            cap *= _GROW
            continue
        lo, hi = _bottleneck_of(best), _bottleneck_of(via)
        need = (direct < low) & (direct <= hi) & (low > lo)
        i, j = np.nonzero(need & (seen == 0))
        seen[i, j] = np.where(world.clear(s[i], t[j], deadline), 1, 2)
        i, j = np.nonzero(need & (seen == 2))
        best[i, j] = low[i, j]
        b = _bottleneck_of(best)
        if b <= cap:
            return b
        cap = max(_GROW * cap, b if b < 1e299 else 0.0)


def geo_lower_bound(problem: Problem, deadline: float | None = None) -> float:
    """Makespan lower bound [s] over shortest free-space distances (cached; see the module).

    ``inf`` when some start cannot reach enough targets in the visibility graph; raises
    ``TimeoutError`` when ``deadline`` passes first (nothing is cached then)."""
    cached = problem.__dict__.get("_geo_lower_bound")
    if cached is not None:
        return cached
    if problem.m == 0:
        return 0.0
    d_star = _graph_bottleneck(problem, deadline)
    bound = math.inf if d_star >= 1e5 * max(problem.width, problem.height) else float(
        step_duration(d_star, problem.max_speed, problem.max_accel))
    problem.__dict__["_geo_lower_bound"] = bound
    problem.__dict__["_geo_bottleneck"] = d_star
    return bound
