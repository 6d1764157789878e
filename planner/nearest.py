"""Exact distances from many segments to many polygon edges, near ones only.

:meth:`planner.geometry.Environment.segment_clearance_detail` folds every
query against every polygon edge: ``queries x edges`` closed forms.  On a
map of thousands of obstacles that is most of a plan's exact check (a maze
of 128 x 128 cells: 2,436 rectangles, 9,744 edges, 5.8 s for one plan).
The nearest edge of a segment is usually close by, so the same closed forms
are evaluated here only on the (query, edge) pairs that the edge index
(:meth:`planner.boxes.BoxIndex._pairs_near`) finds within a radius ``r``:

* every edge within ``r`` of a query's segment is among its pairs (a box gap
  never exceeds the distance to what the box holds), so a query whose
  smallest found distance is at most ``r`` has its exact minimum;
* the others have every edge farther than ``r``; they are asked again at
  ``4 r`` until none is left (at the box's diagonal every edge is found).

The values are the very closed forms of the dense pass (point-segment
distances at the four ends, 0 on a strict crossing), so the minimum is the
same number; which polygon is reported on an exact tie may differ.
"""

from __future__ import annotations

import numpy as np

__all__ = ["LONG", "fold_near", "nearest_polygon", "start_radius"]


def _pair_distance(a, b, ea, eb, points: bool, kernels) -> np.ndarray:
    point_segment_distance, _crossing = kernels
    if points:
        return point_segment_distance(a, ea, eb)
    d = np.minimum(np.minimum(point_segment_distance(a, ea, eb), point_segment_distance(b, ea, eb)),
                   point_segment_distance(ea, a, b))
    d[_crossing(a, b, ea, eb)] = 0.0
    return d


def start_radius(env) -> float:
    """The first radius asked: a few typical edge lengths (most queries are settled in the
    first round).  Segments much longer than it meet many edges on their way and go to
    the dense pass instead (:data:`LONG`)."""
    cached = env.__dict__.get("_near_radius")
    if cached is None:
        boxes = env.edge_boxes
        diag = float(np.hypot(env.width, env.height))
        cached = max(4.0 * float(np.median(np.hypot(*(boxes[:, 2:] - boxes[:, :2]).T))), 1e-6 * diag, 1e-12)
        object.__setattr__(env, "_near_radius", cached)
    return cached


#: segments longer than this many start radii are left to the dense pass
LONG = 4.0


def nearest_polygon(env, a: np.ndarray, b: np.ndarray, points: bool, kernels) -> tuple[np.ndarray, np.ndarray]:
    """``(distance (n,), polygon (n,))``: for each segment ``a[i] -> b[i]`` (points when
    ``points``, then ``b`` is ignored) the smallest set distance to a polygon of ``env``
    (0 inside one) and that polygon's position in ``env.polygons`` (-1, ``inf``: none).
    ``kernels``: the closed forms ``(point_segment_distance, crossing)`` of
    :mod:`planner.geometry` (passed in: that module calls this one)."""
    a = np.asarray(a, float).reshape(-1, 2)
    b = a if points else np.asarray(b, float).reshape(-1, 2)
    n = len(a)
    dist = np.full(n, np.inf)
    poly = np.full(n, -1)
    if n == 0 or not env.polygons:
        return dist, poly
    ea, eb, owner = env.edges
    boxes = env.edge_boxes
    lo = np.minimum(boxes[:, :2].min(axis=0), np.minimum(a.min(axis=0), b.min(axis=0)))
    hi = np.maximum(boxes[:, 2:].max(axis=0), np.maximum(a.max(axis=0), b.max(axis=0)))
    reach_all = float(np.hypot(*(hi - lo))) + 1.0  # every edge lies within this of every query
    r = start_radius(env)
    pending = np.arange(n)
    while len(pending):
        last = r >= reach_all
        qi, ei = env._pairs_near("_edge_index", boxes, a[pending], b[pending], r)
        if len(qi):
            q = pending[qi]
            d = _pair_distance(a[q], b[q], ea[ei], eb[ei], points, kernels)
            low = np.full(n, np.inf)
            np.minimum.at(low, q, d)
            # on a tie the first polygon, as the dense pass's argmin reports it
            at = d == low[q]
            first = np.full(n, len(env.polygons))
            np.minimum.at(first, q[at], owner[ei[at]])
            got = np.unique(q)
            settled = got[(low[got] <= r) | last]
            dist[settled] = low[settled]
            poly[settled] = first[settled]
            done = np.zeros(n, bool)
            done[settled] = True
            pending = pending[~done[pending]]
        elif last:
            break
        r *= 4.0
    rows = max(1, (1 << 21) // len(env.polygons))  # bounded (rows, P) temporaries
    for s in range(0, n, rows):
        # a point (or a segment's first end) inside a polygon: distance 0
        inside = env._inside(a[s : s + rows])
        ii = np.flatnonzero(inside.any(axis=1))
        pj = np.argmax(inside[ii], axis=1)  # the first polygon holding it
        k = s + ii
        poly[k] = np.where(dist[k] == 0.0, np.minimum(poly[k], pj), pj)
        dist[k] = 0.0
    return dist, poly


def fold_near(env, best: np.ndarray, who: np.ndarray, a: np.ndarray, b: np.ndarray | None, kernels):
    """The polygons folded into the clearance details ``(best, who)`` of the walls and
    circles (``who``: obstacle index, -1 the wall), for points ``a`` (``b`` None) or
    segments ``a -> b``: near edges only, except segments longer than :data:`LONG`
    start radii, which get the dense pass."""
    best, who = np.array(best, float), np.array(who)
    ids = np.asarray(env.polygon_ids)
    if b is None:
        near = np.ones(len(a), bool)
    else:
        near = np.linalg.norm(b - a, axis=1) <= LONG * start_radius(env)
    d, k = nearest_polygon(env, a[near], a[near] if b is None else b[near], b is None, kernels)
    better = d < best[near]
    best[near] = np.where(better, d, best[near])
    who[near] = np.where(better, ids[np.maximum(k, 0)], who[near])
    if b is not None and not near.all():  # long segments meet many edges on their way
        far = ~near
        dp, wp = env.segment_clearance_detail(a[far], b[far], polygons="dense")
        better = dp < best[far]
        best[far], who[far] = np.where(better, dp, best[far]), np.where(better, wp, who[far])
    return best, who
