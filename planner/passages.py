"""Narrow passages: where only one robot fits, found exactly, lined with vertices.

Uniform sampling almost never puts a vertex in a gap barely wider than a
robot (the free strip for the centre can be a tenth of a unit wide), and a
random vertex in it would not line up with neighbours on both sides.  So
the passages are found from the geometry instead: every pair of obstacle
features (polygon edges, circles, the four walls) whose distance ``d``
satisfies ``2 (r + margin) <= d < 2 (r + margin) + separation`` is a
passage one robot at a time can use.  Its *chain* is a row of vertices,
one separation apart, along the passage's axis (perpendicular to the
shortest segment between the two features) through the middle of that
segment, kept where they are clear; consecutive chain vertices make
straight edges through the passage.  The chains are added to pebble
graphs as fixed vertices (the bridge test in :mod:`planner.pebble` is the
randomised version of the same idea).
"""

from __future__ import annotations

import numpy as np

from .problem import Circle, Problem

__all__ = ["narrow_passages", "passage_points"]


def _features(problem: Problem):
    """Segments ``(a, b, owner)`` of polygon edges and walls, and circles."""
    w, h = problem.width, problem.height
    segs = []
    for k, ob in enumerate(problem.obstacles):
        if isinstance(ob, Circle):
            continue
        v = ob.vertices
        for i in range(len(v)):
            segs.append((v[i], v[(i + 1) % len(v)], k))
    corners = np.array([[0, 0], [w, 0], [w, h], [0, h]], float)
    for i in range(4):
        segs.append((corners[i], corners[(i + 1) % 4], -1 - i))  # each wall its own owner
    circles = [(np.asarray(ob.center), ob.radius, k) for k, ob in enumerate(problem.obstacles)
               if isinstance(ob, Circle)]
    return segs, circles


def _closest_on_segment(p, a, b):
    ab = b - a
    t = float(np.clip(np.dot(p - a, ab) / max(np.dot(ab, ab), 1e-300), 0.0, 1.0))
    return a + t * ab


def _segment_pair(a, b, c, d):
    """Closest points of two segments (the middle of the overlap when parallel)."""
    cands = [
        (a, _closest_on_segment(a, c, d)),
        (b, _closest_on_segment(b, c, d)),
        (_closest_on_segment(c, a, b), c),
        (_closest_on_segment(d, a, b), d),
    ]
    dist = np.array([np.linalg.norm(p - q) for p, q in cands])
    best = dist.min()
    tied = [cands[i] for i in np.flatnonzero(dist <= best + 1e-9)]
    p = np.mean([x[0] for x in tied], axis=0)
    q = np.mean([x[1] for x in tied], axis=0)
    return p, q, best


def _pairs_within(a: np.ndarray, b: np.ndarray, reach: float) -> tuple[np.ndarray, np.ndarray]:
    """Index pairs ``i < j`` (lexicographic) of segments ``a -> b`` holding every pair closer
    than ``reach``: segments are cut into pieces at most ``L`` long and two pieces
    whose closest points are within ``reach`` have centres within ``reach + L``
    (a KD-tree finds those), so memory grows with the pairs near each other, not
    with the square of the segments (9744 edges of a maze: 47 M pairs)."""
    from scipy.spatial import cKDTree

    n_seg = len(a)
    length = np.linalg.norm(b - a, axis=1)
    piece = max(reach, float(np.median(length)) if n_seg else 0.0, 1e-9)
    n = np.maximum(1, np.ceil(length / piece).astype(int))
    seg = np.repeat(np.arange(n_seg), n)
    k = np.arange(len(seg)) - np.repeat(np.cumsum(n) - n, n)
    f = ((k + 0.5) / n[seg])[:, None]
    centres = a[seg] + f * (b[seg] - a[seg])
    half = float((length / n).max(initial=0.0)) / 2
    pairs = cKDTree(centres).query_pairs(reach + 2 * half + 1e-9 * (1 + reach + half), output_type="ndarray")
    si, sj = seg[pairs[:, 0]], seg[pairs[:, 1]]
    lo, hi = np.minimum(si, sj), np.maximum(si, sj)
    key = np.unique(lo[lo != hi].astype(np.int64) * n_seg + hi[lo != hi])
    return key // n_seg, key % n_seg


def narrow_passages(problem: Problem) -> list[tuple[np.ndarray, np.ndarray]]:
    """Passages as ``(middle point, unit axis)`` pairs, one robot wide.

    Distances between all feature pairs are computed at once (exact,
    vectorised); closest points are worked out only for the pairs in range.
    """
    from .geometry import point_segment_distance, segment_segment_distance

    clr = problem.clearance
    lo, hi = 2 * clr, 2 * clr + problem.separation
    segs, circles = _features(problem)
    found = []
    if segs:
        a = np.array([x[0] for x in segs], float)
        b = np.array([x[1] for x in segs], float)
        owner = np.array([x[2] for x in segs])
        i, j = _pairs_within(a, b, hi)
        keep = owner[i] != owner[j]
        i, j = i[keep], j[keep]
        d = segment_segment_distance(a[i], b[i], a[j], b[j])
        near = np.flatnonzero(d < hi)
        # one passage per pair of owners, where they come closest (a pair closer
        # than a robot needs anywhere has no passage)
        best: dict[tuple[int, int], tuple[float, int]] = {}
        for k in near[np.argsort(d[near], kind="stable")].tolist():
            key = (int(owner[i[k]]), int(owner[j[k]]))
            if key not in best:
                best[key] = (float(d[k]), k)
        for dist, k in sorted(best.values(), key=lambda x: x[1]):
            if dist >= lo:
                p, q, _ = _segment_pair(a[i[k]], b[i[k]], a[j[k]], b[j[k]])
                found.append((p, q))
        for center, radius, _ in circles:
            d = point_segment_distance(center[None], a, b) - radius
            for k in np.flatnonzero((d >= lo) & (d < hi)):
                p = _closest_on_segment(center, a[k], b[k])
                q = center + radius * (p - center) / np.linalg.norm(p - center)
                found.append((p, q))
    for i in range(len(circles)):
        for j in range(i + 1, len(circles)):
            (c1, r1, _), (c2, r2, _) = circles[i], circles[j]
            u = (c2 - c1) / max(np.linalg.norm(c2 - c1), 1e-300)
            p, q = c1 + r1 * u, c2 - r2 * u
            if lo <= np.linalg.norm(q - p) < hi:
                found.append((p, q))
    out = []
    for p, q in found:
        n = q - p
        n = n / max(np.linalg.norm(n), 1e-300)
        out.append((0.5 * (p + q), np.array([-n[1], n[0]])))
    return out


def passage_points(problem: Problem, reach: int = 4) -> np.ndarray:
    """Chain vertices of every narrow passage: the middle and ``reach`` steps each way.

    Steps are a separation (plus 1 %) long; only clear points are kept, and
    points of different chains that crowd each other are thinned (the
    first kept wins).
    """
    from .geometry import greedy_separated

    cached = problem.__dict__.get(f"_lanes_{reach}")
    if cached is not None:
        return cached
    step = problem.separation * 1.01
    pts = []
    for mid, axis in narrow_passages(problem):
        k = np.arange(-reach, reach + 1)
        order = np.argsort(np.abs(k), kind="stable")  # middle first
        pts.append(mid + step * k[order, None] * axis)
    if not pts:
        out = np.zeros((0, 2))
    else:
        pts = np.concatenate(pts)
        pts = pts[problem.env.points_clear(pts, problem.clearance)]
        out = pts[greedy_separated(pts, problem.separation)]
    problem.__dict__[f"_lanes_{reach}"] = out
    return out
