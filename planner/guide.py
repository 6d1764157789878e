"""Guided pebble graphs: intermediate placements along single-robot shortest paths.

The paper samples pebble graphs uniformly.  A roadmap built only from such
graphs connects the start and target through placements spread over the
whole workspace, so robots travel far out of their way.  Guided graphs are
an extra source of samples (the uniform ones stay, so nothing is lost):

1. every start is assigned a target by a minimum-sum assignment on squared
   shortest-path lengths among the obstacles (the CAPT choice, which tends
   to avoid crossings);
2. each robot's path is the shortest polyline through a visibility graph of
   the starts, targets and obstacle corners (corners pushed out by the
   clearance; all visibility tests exact);
3. intermediate placement ``j`` of ``k`` puts every robot at fraction
   ``j / (k + 1)`` of its own path length.  Successive placements then
   differ by straight legs whose longest is ``max path / (k + 1)``, so
   connection steps between them add up to the bottleneck path length,
   and the makespan stays near its lower bound.

Points of a placement that crowd each other are dropped (a pebble graph's
vertices must be separated); the pumped free vertices make up for them.
"""

from __future__ import annotations

import time

import numpy as np
from scipy.optimize import linear_sum_assignment

from .problem import Problem
from .visible import Late, straight_lengths

__all__ = ["Late", "corner_points", "expanded_placement", "guided_placements", "shortest_paths", "straight_lengths"]


def corner_points(problem: Problem, slack: float = 1.02) -> np.ndarray:
    """Points just outside every convex polygon corner and around every circle.

    Obstacle by obstacle, in the problem's order: twelve points around a
    circle; for a polygon, one point along each outward edge normal of
    every convex corner, then one on each corner's bisector.
    """
    clr = problem.clearance * slack
    env = problem.env
    if not problem.obstacles:
        return np.zeros((0, 2))
    per_obstacle: dict[int, np.ndarray] = {}
    if len(env.circle_radii):
        k = 12
        ang = np.arange(k) * 2 * np.pi / k
        unit = np.stack([np.cos(ang), np.sin(ang)], axis=1)
        # The ring's chords must stay clear too: push by 1/cos(pi/k).
        rad = (env.circle_radii + clr) / np.cos(np.pi / k)
        ring = env.circle_centers[:, None] + rad[:, None, None] * unit[None]  # (C, k, 2)
        per_obstacle.update(zip(env.circle_ids, ring))
    if env.polygons:
        v, nxt, _ = env.edges  # every polygon's vertices (counter-clockwise) and their successors
        starts = env.edge_starts
        ends = np.append(starts[1:], len(v))
        prev_idx = np.arange(len(v)) - 1
        prev_idx[starts] = ends - 1  # the previous vertex within the same polygon
        e1 = v - v[prev_idx]
        e2 = nxt - v
        convex = (e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]) > 0
        n1 = np.stack([e1[:, 1], -e1[:, 0]], axis=1)  # outward normals (CCW)
        n2 = np.stack([e2[:, 1], -e2[:, 0]], axis=1)
        n1 /= np.linalg.norm(n1, axis=1, keepdims=True)
        n2 /= np.linalg.norm(n2, axis=1, keepdims=True)
        # Two points per convex corner, one along each outward normal, and
        # one on the bisector: the corner's rounded offset is then covered.
        bis = n1 + n2
        bis /= np.maximum(np.linalg.norm(bis, axis=1, keepdims=True), 1e-12)
        cos_half = np.maximum((bis * n1).sum(axis=1, keepdims=True), 0.2)
        cand = (v + clr * n1, v + clr * n2, v + clr * bis / cos_half)
        for pid, s0, s1 in zip(env.polygon_ids, starts, ends):
            sel = s0 + np.flatnonzero(convex[s0:s1])
            per_obstacle[pid] = np.concatenate([c[sel] for c in cand])
    pts = np.concatenate([per_obstacle[k] for k in sorted(per_obstacle)])
    inside = (pts[:, 0] > 0) & (pts[:, 0] < problem.width) & (pts[:, 1] > 0) & (pts[:, 1] < problem.height)
    pts = pts[inside]
    return pts[problem.env.points_clear(pts, problem.clearance)]


#: Corner pairs tested for visibility at most (about): with more corners only
#: pairs closer than a radius are tested, chosen so that about this many are.
_CORNER_PAIRS = 40_000


def _corner_pairs(problem: Problem, pts: np.ndarray) -> np.ndarray:
    """``(P, 2)`` pairs ``i < j`` of corner points whose visibility is tested: all of
    them, or with many corners those closer than a radius that keeps about
    :data:`_CORNER_PAIRS` pairs (shortest paths then use chains of shorter
    visible segments, found in time and memory linear in the pairs)."""
    n = len(pts)
    radius = _corner_radius(problem, pts)
    if radius is None:
        i, j = np.triu_indices(n, k=1)
        return np.stack([i, j], axis=1)
    from scipy.spatial import cKDTree

    return cKDTree(pts).query_pairs(radius, output_type="ndarray")


def _corner_radius(problem: Problem, pts: np.ndarray) -> float | None:
    """``None`` (every pair) when the corners are few, else the radius that keeps about
    :data:`_CORNER_PAIRS` pairs of them (at least four separations)."""
    n = len(pts)
    if n * (n - 1) // 2 <= _CORNER_PAIRS:
        return None
    area = max(float(np.ptp(pts[:, 0]) * np.ptp(pts[:, 1])), 1e-9)
    return max(float(np.sqrt(2 * _CORNER_PAIRS * area / (np.pi * n * n))), 3 * problem.separation)


def _near_pairs(problem: Problem, pts: np.ndarray, corners: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(point, corner)`` index pairs whose segments are tested: all, or those within
    the corner graph's radius when the corners are many."""
    radius = _corner_radius(problem, corners)
    if radius is None:
        i, j = np.divmod(np.arange(len(pts) * len(corners)), len(corners))
        return i, j
    from scipy.spatial import cKDTree

    lists = cKDTree(corners).query_ball_point(pts, radius)
    counts = np.fromiter((len(x) for x in lists), int, len(lists))
    return np.repeat(np.arange(len(pts)), counts), np.fromiter((j for x in lists for j in x), int, int(counts.sum()))


def _corner_graph(problem: Problem, deadline: float | None = None):
    """Corner points and their visibility graph as a sparse matrix of lengths (cached).
    Raises :class:`Late` when ``deadline`` passes first."""
    cached = problem.__dict__.get("_corner_graph")
    if cached is not None:
        return cached

    from scipy.sparse import coo_matrix

    corners = corner_points(problem)
    pairs = _corner_pairs(problem, corners)
    if len(pairs):
        keep = np.zeros(len(pairs), bool)
        for c0 in range(0, len(pairs), 8192):
            if deadline is not None and time.perf_counter() > deadline:
                raise Late("corner visibility graph")
            sl = slice(c0, c0 + 8192)
            keep[sl] = problem.env.segments_clear(corners[pairs[sl, 0]], corners[pairs[sl, 1]], problem.clearance)
        pairs = pairs[keep]
    length = np.linalg.norm(corners[pairs[:, 0]] - corners[pairs[:, 1]], axis=1) if len(pairs) else np.zeros(0)
    n = len(corners)
    graph = coo_matrix((np.r_[length, length], (np.r_[pairs[:, 0], pairs[:, 1]], np.r_[pairs[:, 1], pairs[:, 0]])),
                       shape=(n, n)).tocsr()
    cached = (corners, graph)
    problem.__dict__["_corner_graph"] = cached
    return cached


def shortest_paths(problem: Problem, starts: np.ndarray, targets: np.ndarray, deadline: float | None = None):
    """Shortest obstacle-avoiding path lengths ``(m, m)`` and a path builder.

    Returns ``(length, path)`` where ``path(i, j)`` is the ``(p, 2)``
    polyline from ``starts[i]`` to ``targets[j]``; ``length`` is ``inf``
    where the visibility graph has no path.  Results are remembered per
    problem and pair of placements.
    """
    key = (np.ascontiguousarray(starts, float).tobytes(), np.ascontiguousarray(targets, float).tobytes())
    memo = problem.__dict__.setdefault("_shortest_paths", {})
    if key in memo:
        return memo[key]
    memo[key] = result = _shortest_paths(problem, np.asarray(starts, float), np.asarray(targets, float), deadline)
    return result


def _shortest_paths(problem: Problem, starts: np.ndarray, targets: np.ndarray, deadline: float | None = None):
    """Dijkstra from every start over one sparse graph: the starts, the corners and
    the targets, joined by clear segments (start-corner, corner-corner,
    corner-target; a clear start-target segment is taken directly)."""
    from scipy.sparse import bmat, coo_matrix, csr_matrix
    from scipy.sparse.csgraph import dijkstra

    corners, graph_cc = _corner_graph(problem, deadline)
    direct = straight_lengths(problem, starts, targets, deadline)
    if len(corners) == 0:
        return direct, lambda i, j: np.stack([starts[i], targets[j]])
    m, c, n = len(starts), len(corners), len(targets)
    if m * c * c <= 2_000_000 and _corner_radius(problem, corners) is None:
        return _shortest_paths_dense(problem, starts, targets, corners, graph_cc, direct)
    # starts -> corners and corners -> targets in one clearance call
    si, sc = _near_pairs(problem, starts, corners)
    tj, tc = _near_pairs(problem, targets, corners)
    a = np.concatenate([starts[si], corners[tc]])
    b = np.concatenate([corners[sc], targets[tj]])
    ok = problem.env.segments_clear(a, b, problem.clearance)
    ok_s, ok_t = ok[: len(si)], ok[len(si) :]
    si, sc, tj, tc = si[ok_s], sc[ok_s], tj[ok_t], tc[ok_t]
    dsc = np.linalg.norm(starts[si] - corners[sc], axis=1) + 1e-300
    dct = np.linalg.norm(targets[tj] - corners[tc], axis=1) + 1e-300
    # node order: starts (m), corners (c), targets (n); directed start -> corner -> target
    s_to_c = csr_matrix((dsc, (si, sc)), shape=(m, c))
    c_to_t = csr_matrix((dct, (tc, tj)), shape=(c, n))
    g = bmat([[None, s_to_c, None], [None, graph_cc, c_to_t], [coo_matrix((n, m)), None, coo_matrix((n, n))]],
             format="csr")
    dist, pred = dijkstra(g, directed=True, indices=np.arange(m), return_predecessors=True)
    length_via = dist[:, m + c :]
    length = np.minimum(direct, length_via)

    def path(i: int, j: int) -> np.ndarray:
        if direct[i, j] <= length_via[i, j]:
            return np.stack([starts[i], targets[j]])
        chain = []
        node = int(pred[i, m + c + j])
        while node >= m:  # a corner
            chain.append(node - m)
            node = int(pred[i, node])
        return np.vstack([starts[i], corners[chain[::-1]], targets[j]])

    return length, path


def _shortest_paths_dense(problem, starts, targets, corners, graph_cc, direct):
    """:func:`_shortest_paths` for few corners: all corner pairs' shortest distances
    at once, then start -> first corner -> ... -> last corner -> target minimised
    with arrays (cheaper than a graph search at this size)."""
    from scipy.sparse.csgraph import shortest_path

    dist_cc, pred_cc = shortest_path(graph_cc, directed=False, return_predecessors=True)
    m, c, n = len(starts), len(corners), len(targets)
    a = np.concatenate([np.repeat(starts, c, axis=0), np.tile(corners, (n, 1))])
    b = np.concatenate([np.tile(corners, (m, 1)), np.repeat(targets, c, axis=0)])
    ok = problem.env.segments_clear(a, b, problem.clearance)
    vis_sc = ok[: m * c].reshape(m, c)
    vis_ct = ok[m * c :].reshape(n, c).T
    dsc = np.where(vis_sc, np.linalg.norm(starts[:, None] - corners[None], axis=2), np.inf)
    dct = np.where(vis_ct, np.linalg.norm(corners[:, None] - targets[None], axis=2), np.inf)
    via_first = dsc[:, :, None] + dist_cc[None]  # (m, c, c): start, first, last
    first_of = np.argmin(via_first, axis=1)  # (m, c): best first corner per last corner
    to_last = np.take_along_axis(via_first, first_of[:, None, :], axis=1)[:, 0, :]  # (m, c)
    through = to_last[:, :, None] + dct[None]  # (m, c, n)
    last_of = np.argmin(through, axis=1)  # (m, n)
    length_via = np.take_along_axis(through, last_of[:, None, :], axis=1)[:, 0, :]
    length = np.minimum(direct, length_via)

    def path(i: int, j: int) -> np.ndarray:
        if direct[i, j] <= length_via[i, j]:
            return np.stack([starts[i], targets[j]])
        last = int(last_of[i, j])
        first = int(first_of[i, last])
        chain = [last]
        while chain[-1] != first:
            chain.append(int(pred_cc[first, chain[-1]]))
        return np.vstack([starts[i], corners[chain[::-1]], targets[j]])

    return length, path


def _points_along(paths: list[np.ndarray], fractions: np.ndarray) -> np.ndarray:
    """``(m, F, 2)``: the point at each fraction of each polyline's length."""
    v = max(len(p) for p in paths)
    pad = np.stack([np.vstack([p, np.repeat(p[-1:], v - len(p), axis=0)]) for p in paths])  # (m, V, 2)
    seg = np.linalg.norm(np.diff(pad, axis=1), axis=2)  # (m, V-1)
    cum = np.concatenate([np.zeros((len(paths), 1)), np.cumsum(seg, axis=1)], axis=1)  # (m, V)
    s = fractions[None, :] * cum[:, -1:]  # (m, F)
    k = (cum[:, None, :] <= s[:, :, None]).sum(axis=2) - 1
    k = np.clip(k, 0, v - 2)
    seg_k = np.take_along_axis(seg, k, axis=1)
    u = np.where(seg_k > 0, (s - np.take_along_axis(cum, k, axis=1)) / np.maximum(seg_k, 1e-300), 0.0)
    u = np.clip(u, 0.0, 1.0)
    a = np.take_along_axis(pad, k[:, :, None], axis=1)
    b = np.take_along_axis(pad, k[:, :, None] + 1, axis=1)
    return a + u[:, :, None] * (b - a)


def guided_placements(problem: Problem, start=None, target=None, max_leg: float | None = None,
                      max_graphs: int = 4):
    """Intermediate placements along the assigned shortest paths.

    ``start`` and ``target`` default to the problem's placements.
    Returns a list of ``(k_points, 2)`` arrays (each already thinned to
    separated, clear points) and the assignment ``sigma`` (start ``i`` is
    guided to ``target[sigma[i]]``; -1 when unmatched).  ``k`` is the
    smallest count (at most ``max_graphs``) whose straight legs all stay
    clear of the obstacles; none when no such count exists.
    """
    start = problem.start if start is None else np.asarray(start, float)
    target = problem.target if target is None else np.asarray(target, float)
    length, path = shortest_paths(problem, start, target)
    finite = np.isfinite(length)
    cost = np.where(finite, length**2, 1e18)
    rows, cols = linear_sum_assignment(cost)  # rectangular when a placement was thinned
    sigma = np.full(len(start), -1)
    sigma[rows] = cols
    paths = [path(i, j) if finite[i, j] else np.stack([start[i], target[j]]) for i, j in zip(rows, cols)]
    lens = np.array([np.linalg.norm(np.diff(p, axis=0), axis=1).sum() for p in paths])
    k0 = 1
    if max_leg is not None:
        k0 = max(k0, int(np.ceil(lens.max() / max_leg)) - 1)
    for k in range(k0, max_graphs + 1):
        fr = np.arange(1, k + 1) / (k + 1)
        pts = _points_along(paths, fr)  # (m, k, 2)
        seq = np.concatenate([start[rows][:, None], pts, target[cols][:, None]], axis=1)
        a = seq[:, :-1].reshape(-1, 2)
        b = seq[:, 1:].reshape(-1, 2)
        if np.all(problem.env.segments_clear(a, b, problem.clearance)):
            return [_repair(problem, pts[:, j]) for j in range(k)], sigma
    return [], sigma


#: CAPT (Turpin, Michael, Kumar 2014): with starts and goals at least
#: ``sqrt(2) * d`` apart, synchronised straight lines along a minimum-sum-of-
#: squares assignment keep every pair at least ``d`` apart.
CAPT_FACTOR = float(np.sqrt(2.0))


def expanded_placement(problem: Problem, pts: np.ndarray, slack: float = 1.03) -> np.ndarray | None:
    """The placement scaled about its centre until neighbours are CAPT-spaced.

    Scaling by ``f >= 1`` (plus a translation) moves every pair apart
    monotonically, so the synchronised straight move into it never brings
    two robots closer.  The scaled placement is shifted back inside the
    walls if needed; ``None`` when no scaling is needed or it does not fit
    clear of the obstacles (robots that would hit one are dropped instead
    when only a few do).
    """
    pts = np.asarray(pts, float)
    if len(pts) < 2:
        return None
    d = np.linalg.norm(pts[:, None] - pts[None], axis=2)
    np.fill_diagonal(d, np.inf)
    need = CAPT_FACTOR * problem.separation * slack
    f = need / d.min()
    if f <= 1.0:
        return None
    c = 0.5 * (pts.max(axis=0) + pts.min(axis=0))
    out = c + f * (pts - c)
    lo = out.min(axis=0) - problem.clearance
    hi = out.max(axis=0) + problem.clearance
    size = np.array([problem.width, problem.height])
    if np.any(hi - lo > size):
        return None
    out = out + np.maximum(0.0, -lo) - np.maximum(0.0, hi - size)
    return _repair(problem, out)


def _repair(problem: Problem, pts: np.ndarray, rings: int = 4, per_ring: int = 16) -> np.ndarray:
    """Keep the placement's points in order, moving crowded or blocked ones nearby.

    A point that is not clear, or too close to one kept before it, is moved
    to the nearest candidate on rings of growing radius around it that is
    clear and separated; it is dropped only when none is.
    """
    sep2 = problem.separation ** 2
    pts = np.asarray(pts, float).reshape(-1, 2)
    ang = np.arange(per_ring) * 2 * np.pi / per_ring
    unit = np.stack([np.cos(ang), np.sin(ang)], axis=1)
    offsets = np.concatenate([[[0.0, 0.0]]] + [0.5 * problem.separation * r * unit for r in range(1, rings + 1)])
    cand = pts[:, None, :] + offsets[None]  # (n, C, 2)
    clear = problem.env.points_clear(cand.reshape(-1, 2), problem.clearance).reshape(len(pts), -1)
    out = np.empty((0, 2))
    for i in range(len(pts)):
        ok = clear[i]
        if len(out):
            near = ((pts[i] - out) ** 2).sum(axis=1) < (2 * rings * problem.separation) ** 2
            if near.any():
                ok = ok & (((cand[i][:, None] - out[near][None]) ** 2).sum(axis=2) >= sep2).all(axis=1)
        j = np.flatnonzero(ok)
        if len(j):
            out = np.vstack([out, cand[i, j[0]]])
    return out
