"""Finishing a routing on the free-space roadmap one robot at a time.

Routing many robots at once (goal swapping, :mod:`planner.freespace`;
priority inheritance, :mod:`planner.pibt`) can end with a few robots that
keep stepping around each other near their targets, typically two robots
whose targets lie one behind the other in a narrow channel.  Once the
others rest, there is room: the targets are unlabeled, so it is enough to
move, one at a time, any robot not yet on a target along the shortest
roadmap path to any empty target on which every edge keeps the separation
from every other robot where it stands (exact point-segment distances; a
robot moving alone is then clear of everyone).  This is the sequential
pebble-motion view of the unlabeled problem (as in Solovey and Halperin's
pebble solver), run on the roadmap.
"""

from __future__ import annotations

import time

import numpy as np

__all__ = ["sequential_finish"]


def sequential_finish(roadmap, pos: np.ndarray, where: list[int], sep: float, deadline: float,
                      budget: int = 80) -> list[np.ndarray] | None:
    """Waypoints (one robot moving per step, one step per roadmap edge) that take the
    robots from ``pos`` (robot ``i`` on vertex ``where[i]``) onto the roadmap's targets
    (vertices ``m .. 2m - 1``); ``[]`` when they are there, ``None`` when no order of
    such moves was found within ``budget`` tries or the deadline.

    Which robot goes to which empty target first matters (a robot that stops at the
    mouth of a channel closes it to the others), so the orders are searched depth
    first, nearest pair first, backtracking when some robot is left without a path."""
    e = roadmap.edges
    if not len(e):
        return None
    left = [budget]
    moves = _search(roadmap, pos.copy(), list(where), sep, deadline, left)
    if moves is None:
        return None
    out, pos = [], pos.copy()
    for i, path in moves:
        for v in path:
            pos = pos.copy()
            pos[i] = roadmap.points[v]
            out.append(pos)
    return out


def _search(roadmap, pos, where, sep, deadline, left, depth: int = 0) -> list | None:
    """``[(robot, vertices it passes), ...]`` finishing the robots, or ``None``."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import dijkstra

    m = roadmap.m
    pts = roadmap.points
    targets = pts[m:2 * m]
    on = (np.abs(pos[:, None, :] - targets[None]).max(axis=2) <= 1e-12)  # (robot, target)
    off = np.flatnonzero(~on.any(axis=1))
    if not len(off):
        return []
    left[0] -= 1
    if left[0] < 0 or time.perf_counter() > deadline:
        return None
    empty = np.flatnonzero(~on.any(axis=0)) + m
    e = roadmap.edges
    eid, rid = _blocking_pairs(roadmap, pos, sep)  # edges passing closer than sep to robots
    blocked = np.bincount(eid, minlength=len(e))
    # Robots off target first; then robots on a target near an empty one, which may step
    # deeper in and leave their own target, at the mouth, to the others.
    near = np.flatnonzero(on.any(axis=1) & (np.hypot(*(pos[:, None, :] - pts[empty][None]).transpose(2, 0, 1)).min(axis=1)
                                             < 3 * sep)) if depth < 2 * len(off) + 4 else []
    options = []
    for rank, i in enumerate(off.tolist() + [int(j) for j in near]):
        ok = blocked - np.bincount(eid[rid == i], minlength=len(e)) == 0  # clear of every other robot
        if not ok.any():
            continue
        ee = e[ok]
        w = roadmap.length[ok] + 1e-12
        g = coo_matrix((np.r_[w, w], (np.r_[ee[:, 0], ee[:, 1]], np.r_[ee[:, 1], ee[:, 0]])),
                       shape=(roadmap.n, roadmap.n)).tocsr()
        d, pred = dijkstra(g, indices=where[i], return_predecessors=True)
        for k in empty[np.isfinite(d[empty])].tolist():
            options.append((rank >= len(off), d[k], i, k, pred))
    options.sort(key=lambda x: x[:2])
    for _, _, i, k, pred in options:
        path = [k]
        while path[-1] != where[i]:
            path.append(int(pred[path[-1]]))
        path = path[-2::-1]
        here, at = pos[i].copy(), where[i]
        pos[i], where[i] = pts[k], k
        rest = _search(roadmap, pos, where, sep, deadline, left, depth + 1)
        if rest is not None:
            return [(i, path)] + rest
        pos[i], where[i] = here, at
        if left[0] < 0:
            return None
    return None


def _blocking_pairs(roadmap, pos: np.ndarray, sep: float) -> tuple[np.ndarray, np.ndarray]:
    """``(edge ids, robot ids)`` of the roadmap edges passing closer than ``sep`` to a robot
    (exact point-segment distances, for the edges a KD-tree of edge midpoints finds near
    each robot)."""
    from scipy.spatial import cKDTree

    from .geometry import point_segment_distance

    pts, e = roadmap.points, roadmap.edges
    cache = roadmap.__dict__.setdefault("_mid_tree", {})
    if "tree" not in cache:
        cache["tree"] = cKDTree(0.5 * (pts[e[:, 0]] + pts[e[:, 1]]))
        cache["reach"] = 0.5 * float(roadmap.length.max()) + sep
    found = cache["tree"].query_ball_point(pos, cache["reach"])
    rid = np.repeat(np.arange(len(pos)), [len(f) for f in found])
    eid = np.fromiter((k for f in found for k in f), dtype=int, count=len(rid))
    if not len(eid):
        return eid, rid
    a, b = pts[e[eid, 0]], pts[e[eid, 1]]
    d = point_segment_distance(pos[rid], a, b)
    close = d < sep
    return eid[close], rid[close]
