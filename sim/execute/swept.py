"""The monitor's swept check: contacts along straight moves between two samples.

:func:`swept_hits` takes the positions at the two ends of ``K`` straight
moves (``p0 -> p1``, all robots moving over the same time span) and returns
every robot pair, robot-obstacle pair whose least gap *during* the move is
below 0, with the move parameter of the closest approach.  The distances
are closed form (:mod:`sim.execute.kernels`); nothing is sampled.

Broad phase, so that the cost stays near that of the sampled check:

* robot pairs: a Verlet list per block of moves.  Every position of a
  robot in the block (a point on one of its moves) lies within ``reach`` of
  its position at the start of the block (a ball is convex), so a pair
  farther apart than ``2 r + 2 reach`` there never touches in the block.
  When that list is too long (fast, sparse robots) each move is handled
  alone with a KD-tree of the moves' midpoints, reaching half the longest
  move on each side plus ``2 r``.
* polygons: a move is measured against a polygon's edges only when the
  move's bounding box, grown by ``r``, meets the polygon's.
* walls are never swept: the wall clearance is concave, so its minimum over
  a straight move is at an end, where the sampled check sees it.
"""

from __future__ import annotations

import numpy as np

from .contacts import ROBOT_OBSTACLE, ROBOT_ROBOT
from .kernels import swept_circle_distance, swept_pair_distance, swept_segment_distance

__all__ = ["swept_hits"]

_BLOCK = 16  # moves that share one Verlet list
_PAIRS_PER_ROBOT = 40  # above this many candidates per robot, per-move midpoint trees


def swept_hits(radius: float, env, p0: np.ndarray, p1: np.ndarray) -> list[tuple]:
    """Rows ``(k, kind, a, b, gap, s)``: move ``k``, what touches, the least gap (``< 0``), at ``s`` in [0, 1].

    ``p0`` and ``p1`` are ``(K, m, 2)``.  ``b`` is the other robot (``a <
    b``) or the obstacle index.
    """
    p0 = np.asarray(p0, float)
    p1 = np.asarray(p1, float)
    hits: list[tuple] = []
    if p0.size == 0:
        return hits
    _robot_pairs(float(radius), p0, p1, hits)
    _obstacles(float(radius), env, p0, p1, hits)
    return hits


def _robot_pairs(r: float, p0, p1, hits) -> None:
    from scipy.spatial import cKDTree

    k_all, m = p0.shape[:2]
    if m < 2:
        return
    two_r = 2.0 * r
    for k0 in range(0, k_all, _BLOCK):
        a, b = p0[k0 : k0 + _BLOCK], p1[k0 : k0 + _BLOCK]
        base = a[0]
        reach = 0.0
        for ends in (a, b):
            move = ends - base
            reach = max(reach, float(np.sqrt(np.einsum("kmx,kmx->km", move, move).max())))
        pairs = cKDTree(base).query_pairs(two_r + 2.0 * reach + 1e-9, output_type="ndarray")
        if len(pairs) > _PAIRS_PER_ROBOT * m:
            for k in range(len(a)):
                mid = 0.5 * (a[k] + b[k])
                half = 0.5 * float(np.sqrt(((b[k] - a[k]) ** 2).sum(axis=1).max()))
                pk = cKDTree(mid).query_pairs(two_r + 2.0 * half + 1e-9, output_type="ndarray")
                _pair_hits(two_r, a[k : k + 1], b[k : k + 1], pk, k0 + k, hits)
        elif len(pairs):
            _pair_hits(two_r, a, b, pairs, k0, hits)


def _pair_hits(two_r: float, a, b, pairs, k0: int, hits) -> None:
    if len(pairs) == 0:
        return
    pi, pj = pairs[:, 0], pairs[:, 1]
    d, s = swept_pair_distance(a[:, pi], b[:, pi], a[:, pj], b[:, pj])  # (k, p)
    for k, q in zip(*np.nonzero(d < two_r)):
        i, j = int(pi[q]), int(pj[q])
        hits.append((k0 + int(k), ROBOT_ROBOT, min(i, j), max(i, j), float(d[k, q]) - two_r, float(s[k, q])))


def _obstacles(r: float, env, p0, p1, hits) -> None:
    k_all, m = p0.shape[:2]
    a = p0.reshape(-1, 2)
    b = p1.reshape(-1, 2)
    if len(env.circle_radii):
        d, s = swept_circle_distance(a[:, None, :], b[:, None, :], env.circle_centers[None], env.circle_radii[None])
        for row, c in zip(*np.nonzero(d < r)):
            k, i = divmod(int(row), m)
            hits.append((k, ROBOT_OBSTACLE, i, int(env.circle_ids[c]), float(d[row, c]) - r, float(s[row, c])))
    if not env.polygons:
        return
    lo = np.minimum(a, b) - r
    hi = np.maximum(a, b) + r
    for poly, ob in zip(env.polygons, env.polygon_ids):
        plo, phi = poly.min(axis=0), poly.max(axis=0)
        sel = np.flatnonzero(np.all((lo <= phi) & (hi >= plo), axis=1))
        if len(sel) == 0:
            continue
        d, s = swept_segment_distance(a[sel, None, :], b[sel, None, :], poly[None], np.roll(poly, -1, axis=0)[None])
        e = np.argmin(d, axis=1)
        rows = np.arange(len(sel))
        dmin, smin = d[rows, e], s[rows, e]
        for q in np.flatnonzero(dmin < r):
            k, i = divmod(int(sel[q]), m)
            hits.append((k, ROBOT_OBSTACLE, i, int(ob), float(dmin[q]) - r, float(smin[q])))
