"""Exact, vectorised geometry kernels shared by the planner and the validator.

Every function here is closed-form: nothing is discretised.  Points and
segments are numpy arrays whose last axis has length 2; leading axes
broadcast like ordinary numpy operations.

Conventions (all distances are between *centres* and obstacle sets; the
caller subtracts the robot radius to get a gap between boundaries):

* Walls: the workspace is the rectangle ``[0, W] x [0, H]``; the wall
  clearance of a point is ``min(x, W - x, y, H - y)`` (negative outside).
* Circles: ``|p - c| - R`` (negative inside).
* Polygons: the Euclidean distance from the point (or the segment) to the
  closed polygon as a set, so ``0`` when they meet.  Polygons may be
  non-convex and of either winding.

Two robots moving on straight segments with one shared time parameter
``theta`` (``p(theta) = a + theta (b - a)``, ``q(theta) = c + theta (d - c)``)
come closest at ``theta* = clip(-w0.u / |u|^2, 0, 1)`` with ``w0 = a - c``
and ``u = (b - a) - (d - c)``; :func:`closest_approach` returns that distance.
Because every step of a plan shares one monotone time scaling, this is the
exact closest approach in time as well.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .boxes import BoxIndex, _box_gap_ok, _boxes_near, _segment_edge_close
from .nearest import fold_near
from .pointsets import greedy_separated

__all__ = [
    "Environment",
    "greedy_separated",
    "closest_approach",
    "point_segment_distance",
    "points_in_polygon",
    "segment_segment_distance",
]


def point_segment_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance from points ``p`` to segments ``[a, b]`` (broadcasting)."""
    p = np.asarray(p, float)
    a = np.asarray(a, float)
    b = np.asarray(b, float)
    ax, ay = a[..., 0], a[..., 1]
    abx = b[..., 0] - ax
    aby = b[..., 1] - ay
    apx = p[..., 0] - ax
    apy = p[..., 1] - ay
    # A zero-length segment has a zero numerator too, so t = 0 there.
    t = (apx * abx + apy * aby) / np.maximum(abx * abx + aby * aby, 1e-300)
    t = np.minimum(np.maximum(t, 0.0), 1.0)
    dx = apx - t * abx
    dy = apy - t * aby
    return np.sqrt(dx * dx + dy * dy)


def _orient(ax, ay, bx, by, cx, cy):
    """Twice the signed area of triangle (a, b, c)."""
    return (bx - ax) * (cy - ay) - (by - ay) * (cx - ax)


def _crossing(a, b, c, d) -> np.ndarray:
    """Segments ``[a, b]`` and ``[c, d]`` cross at interior points (strictly)."""
    ax, ay, bx, by = a[..., 0], a[..., 1], b[..., 0], b[..., 1]
    cx, cy, dx, dy = c[..., 0], c[..., 1], d[..., 0], d[..., 1]
    o1 = _orient(ax, ay, bx, by, cx, cy)
    o2 = _orient(ax, ay, bx, by, dx, dy)
    o3 = _orient(cx, cy, dx, dy, ax, ay)
    o4 = _orient(cx, cy, dx, dy, bx, by)
    return (o1 * o2 < 0.0) & (o3 * o4 < 0.0)


def segment_segment_distance(a, b, c, d) -> np.ndarray:
    """Distance between segments ``[a, b]`` and ``[c, d]`` (0 when they meet)."""
    a = np.asarray(a, float)
    b = np.asarray(b, float)
    c = np.asarray(c, float)
    d = np.asarray(d, float)
    dist = np.minimum(
        np.minimum(point_segment_distance(a, c, d), point_segment_distance(b, c, d)),
        np.minimum(point_segment_distance(c, a, b), point_segment_distance(d, a, b)),
    )
    return np.where(_crossing(a, b, c, d), 0.0, dist)


def closest_approach(a, b, c, d, *, return_theta: bool = False):
    """Closest distance of two points moving ``a -> b`` and ``c -> d`` together.

    Both move with the same parameter ``theta`` in ``[0, 1]``.  A robot that
    does not move has ``a == b``.  With ``return_theta`` the minimising
    ``theta`` is returned as well.
    """
    a = np.asarray(a, float)
    b = np.asarray(b, float)
    c = np.asarray(c, float)
    d = np.asarray(d, float)
    wx = a[..., 0] - c[..., 0]
    wy = a[..., 1] - c[..., 1]
    ux = (b[..., 0] - a[..., 0]) - (d[..., 0] - c[..., 0])
    uy = (b[..., 1] - a[..., 1]) - (d[..., 1] - c[..., 1])
    # No relative motion: a zero numerator too, so theta = 0.
    t = -(wx * ux + wy * uy) / np.maximum(ux * ux + uy * uy, 1e-300)
    t = np.minimum(np.maximum(t, 0.0), 1.0)
    dx = wx + t * ux
    dy = wy + t * uy
    dist = np.sqrt(dx * dx + dy * dy)
    if return_theta:
        return dist, t
    return dist


def points_in_polygon(points: np.ndarray, poly: np.ndarray) -> np.ndarray:
    """Even-odd test of points ``(N, 2)`` against one simple polygon ``(k, 2)``.

    Points exactly on the boundary may fall either way; callers that need
    the boundary use distances, which are 0 there.
    """
    points = np.asarray(points, float).reshape(-1, 2)
    a = poly
    b = np.roll(poly, -1, axis=0)
    px = points[:, 0:1]
    py = points[:, 1:2]
    ay, by = a[None, :, 1], b[None, :, 1]
    ax, bx = a[None, :, 0], b[None, :, 0]
    straddle = (ay > py) != (by > py)
    with np.errstate(invalid="ignore", divide="ignore"):
        xint = ax + (py - ay) * (bx - ax) / np.where(by != ay, by - ay, 1.0)
    cross = straddle & (px < xint)
    return (np.count_nonzero(cross, axis=1) % 2) == 1


def _fold_min(best, who, d, ids):
    """Fold distances ``(n, K)`` to K obstacles into the running minimum and its owner."""
    j = np.argmin(d, axis=1)
    dj = d[np.arange(len(d)), j]
    better = dj < best
    return np.where(better, dj, best), np.where(better, np.asarray(ids)[j], who)


_CHUNK = 1 << 21  # entries of a (rows x obstacle features) temporary
_PIECES_PER_CALL = 200_000  # segment pieces met with the box index in one KD-tree query
_DENSE_PAIRS = 1 << 17  # up to this many (query, box) pairs the dense box test is used
_NEAR_PAIRS = 1 << 22  # above this many (query, edge) pairs the clearance details use near edges only


def _rows_per_chunk(width: int) -> int:
    return max(1, _CHUNK // max(width, 1))


@dataclass(frozen=True, eq=False)
class Environment(BoxIndex):
    """The static world in array form: walls, polygon edges and circles.

    ``polygons`` and ``circles`` keep the obstacle order of the problem so
    that :meth:`point_clearance_detail` can name the obstacle it reports.
    """

    width: float
    height: float
    polygons: tuple[np.ndarray, ...]  # each (k, 2)
    polygon_ids: tuple[int, ...]  # obstacle index of each polygon
    circle_centers: np.ndarray  # (C, 2)
    circle_radii: np.ndarray  # (C,)
    circle_ids: tuple[int, ...]

    @classmethod
    def build(cls, width, height, obstacles) -> "Environment":
        """Build from a sequence of obstacles with ``vertices`` or ``center``/``radius``."""
        polys, pids, cc, cr, cids = [], [], [], [], []
        for k, ob in enumerate(obstacles):
            if hasattr(ob, "vertices"):
                polys.append(np.asarray(ob.vertices, float))
                pids.append(k)
            else:
                cc.append(np.asarray(ob.center, float))
                cr.append(float(ob.radius))
                cids.append(k)
        return cls(
            float(width),
            float(height),
            tuple(polys),
            tuple(pids),
            np.asarray(cc, float).reshape(-1, 2),
            np.asarray(cr, float),
            tuple(cids),
        )

    def _pairs_near(self, name: str, boxes: np.ndarray, a: np.ndarray, b: np.ndarray,
                    clearance: float) -> tuple[np.ndarray, np.ndarray]:
        """``(query, box)`` pairs for segments ``a -> b`` (points: ``a == b``) and
        ``boxes``: every pair whose segment comes within ``clearance`` of the box, and
        only pairs passing the box-gap test of :func:`_boxes_near`.

        The segments are cut into pieces about as long as the index's box pieces, and
        two KD-trees of piece centres meet at the distance that two pieces within
        ``clearance`` of each other can have; memory and time grow with the pairs
        found, not with segments x boxes.
        """
        if len(a) == 0 or len(boxes) == 0:
            return np.zeros(0, int), np.zeros(0, int)
        if len(a) * len(boxes) <= _DENSE_PAIRS:  # small: the dense test is cheaper
            return np.nonzero(_boxes_near(np.minimum(a, b), np.maximum(a, b), boxes, clearance))
        tree, owner, half = self._index(name, boxes)
        from scipy.spatial import cKDTree

        length = np.linalg.norm(b - a, axis=1)
        piece = max(2.0 * half, float(length.sum()) / 4_000_000, 1e-9)
        n = np.maximum(1, np.ceil(length / piece).astype(int))
        if len(a) > 1 and int(n.sum()) > _PIECES_PER_CALL:
            # Many queries (a large map's roadmap edges): in groups of about
            # _PIECES_PER_CALL pieces, so that the pairs held at once stay bounded.
            group = np.cumsum(n) // _PIECES_PER_CALL
            parts = np.split(np.arange(len(a)), np.flatnonzero(np.diff(group)) + 1)
            found = [self._pairs_near(name, boxes, a[rows], b[rows], clearance) for rows in parts]
            return (np.concatenate([rows[q] for rows, (q, _) in zip(parts, found)]),
                    np.concatenate([bi for _, bi in found]))
        seg = np.repeat(np.arange(len(a)), n)
        k = np.arange(len(seg)) - np.repeat(np.cumsum(n) - n, n)
        f = ((k + 0.5) / n[seg])[:, None]
        centres = a[seg] + f * (b[seg] - a[seg])
        reach = float((length / n).max(initial=0.0)) / 2 + half + max(clearance, 0.0) + 1e-9 * (1 + half)
        hits = cKDTree(centres).sparse_distance_matrix(tree, reach, output_type="ndarray")
        qi, bi = seg[hits["i"]], owner[hits["j"]]  # repeats are harmless: every use ORs or ANDs
        ok = _box_gap_ok(np.minimum(a[qi], b[qi]), np.maximum(a[qi], b[qi]), boxes[bi], clearance)
        return qi[ok], bi[ok]

    def _inside(self, pts: np.ndarray) -> np.ndarray:
        """``(N, P)`` even-odd inside test against every polygon at once (only the
        pairs whose polygon's box holds the point are computed)."""
        pts = np.asarray(pts, float).reshape(-1, 2)
        n_poly = len(self.polygons)
        out = np.zeros((len(pts), n_poly), bool)
        if n_poly == 0 or len(pts) == 0:
            return out
        a, b, _ = self.edges
        if len(pts) * len(a) <= _DENSE_PAIRS:  # small: every edge at once
            px, py = pts[:, 0:1], pts[:, 1:2]
            ay, by = a[None, :, 1], b[None, :, 1]
            straddle = (ay > py) != (by > py)
            with np.errstate(invalid="ignore", divide="ignore"):
                xint = a[None, :, 0] + (py - ay) * (b[None, :, 0] - a[None, :, 0]) / np.where(by != ay, by - ay, 1.0)
            cross = (straddle & (px < xint)).astype(np.int32)
            return (np.add.reduceat(cross, self.edge_starts, axis=1) % 2) == 1
        boxes = self.obstacle_boxes[:n_poly]
        # a point inside a polygon lies in its box: a gap <= 0, below any positive clearance
        qi, pj = self._pairs_near("_poly_index", boxes, pts, pts, 1e-300)
        if len(qi) == 0:
            return out
        starts = self.edge_starts
        sizes = np.array([len(p) for p in self.polygons])
        cnt = sizes[pj]
        pair = np.repeat(np.arange(len(qi)), cnt)
        e = np.repeat(starts[pj], cnt) + (np.arange(len(pair)) - np.repeat(np.cumsum(cnt) - cnt, cnt))
        px, py = pts[qi[pair], 0], pts[qi[pair], 1]
        ay, by = a[e, 1], b[e, 1]
        straddle = (ay > py) != (by > py)
        with np.errstate(invalid="ignore", divide="ignore"):
            xint = a[e, 0] + (py - ay) * (b[e, 0] - a[e, 0]) / np.where(by != ay, by - ay, 1.0)
        cross = straddle & (px < xint)
        odd = (np.bincount(pair[cross], minlength=len(qi)) % 2) == 1
        out[qi[odd], pj[odd]] = True
        return out

    def wall_clearance(self, p: np.ndarray) -> np.ndarray:
        p = np.asarray(p, float)
        x, y = p[..., 0], p[..., 1]
        return np.minimum(np.minimum(x, self.width - x), np.minimum(y, self.height - y))

    def point_clearance_detail(self, points: np.ndarray, polygons: bool = True) -> tuple[np.ndarray, np.ndarray]:
        """Clearance of each point and what attains it (obstacle index, -1 = wall);
        ``polygons=False``: walls and circles only."""
        pts = np.asarray(points, float).reshape(-1, 2)
        if polygons and self.polygons and len(pts) * len(self.edges[0]) > _NEAR_PAIRS:
            best, who = self.point_clearance_detail(pts, polygons=False)
            return fold_near(self, best, who, pts, None, (point_segment_distance, _crossing))
        width = len(self.circle_radii) + (len(self.edges[0]) if polygons else 0)
        rows = _rows_per_chunk(width)
        if len(pts) > rows:
            parts = [self.point_clearance_detail(pts[r : r + rows], polygons) for r in range(0, len(pts), rows)]
            return np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts])
        n = len(pts)
        best = self.wall_clearance(pts)
        who = np.full(n, -1)
        if len(self.circle_radii):
            d = (
                np.sqrt(((pts[:, None, :] - self.circle_centers[None]) ** 2).sum(-1))
                - self.circle_radii[None]
            )
            best, who = _fold_min(best, who, d, self.circle_ids)
        if polygons and self.polygons and n:
            a, b, _ = self.edges
            d = point_segment_distance(pts[:, None, :], a[None], b[None])  # (n, E)
            dp = np.minimum.reduceat(d, self.edge_starts, axis=1)  # (n, P)
            dp[self._inside(pts)] = 0.0
            best, who = _fold_min(best, who, dp, self.polygon_ids)
        return best, who

    def point_clearance(self, points: np.ndarray) -> np.ndarray:
        """Distance from each centre to the nearest wall or obstacle."""
        return self.point_clearance_detail(points)[0]

    # -- segments -------------------------------------------------------------
    def segment_clearance(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """Exact minimum clearance of centres moving along segments ``a -> b``."""
        return self.segment_clearance_detail(a, b)[0]

    def _segments_keep(self, a: np.ndarray, b: np.ndarray, clearance: float) -> np.ndarray:
        """``segment_clearance(a, b) >= clearance`` for segments inside the walls' margin.

        The same closed forms as :meth:`segment_clearance_detail` without
        tracking which obstacle is nearest: every circle's centre and every
        polygon edge keep the distance, no edge is crossed, and (then the
        segment lies wholly inside or wholly outside each polygon) its first
        end is outside every polygon.
        """
        ok = np.ones(len(a), bool)
        if len(self.circle_radii):
            n_poly = len(self.polygons)
            qi, oi = self._pairs_near("_obstacle_index", self.obstacle_boxes, a, b, clearance)
            circ = oi >= n_poly
            qi, ci = qi[circ], oi[circ] - n_poly
            d = point_segment_distance(self.circle_centers[ci], a[qi], b[qi])
            ok[qi[d - self.circle_radii[ci] < clearance]] = False
        if self.polygons and clearance > 0:  # a polygon's set distance is never below 0
            ea, eb, _ = self.edges
            # Only (segment, edge) pairs whose bounding boxes come within
            # ``clearance`` can fail: a box gap bounds the distance from below,
            # and a crossing needs overlapping boxes.  The index finds them.
            ii, ee = self._pairs_near("_edge_index", self.edge_boxes, a, b, clearance)
            if len(ii):
                bad = _segment_edge_close(a[ii, 0], a[ii, 1], b[ii, 0], b[ii, 1],
                                          ea[ee, 0], ea[ee, 1], eb[ee, 0], eb[ee, 1], clearance)
                ok[ii[bad]] = False
            # Then the segment lies wholly inside or wholly outside each polygon:
            # its first end decides (inside only within the polygon's box).
            boxes = self.obstacle_boxes[: len(self.polygons)]  # polygons come first
            live = np.flatnonzero(ok)
            if len(live) * len(boxes) <= _DENSE_PAIRS:
                in_box = ((a[live, None] >= boxes[None, :, :2]) & (a[live, None] <= boxes[None, :, 2:])).all(axis=2)
                check = live[in_box.any(axis=1)]
            else:
                qi, _ = self._pairs_near("_poly_index", boxes, a[live], a[live], 1e-300)
                check = live[np.unique(qi)]
            if len(check):
                ok[check] = ~self._inside(a[check]).any(axis=1)
        return ok

    def segment_clearance_detail(self, a: np.ndarray, b: np.ndarray, polygons: bool | str = True):
        """Exact minimum clearance along segments ``a -> b`` and what attains it.

        ``a`` and ``b`` are ``(N, 2)``; returns ``(clearance (N,), who (N,))``
        with ``who`` the obstacle index or -1 for the wall.  Walls: the wall
        clearance is linear along a segment inside the rectangle, so its
        minimum is at an end.  Circles: point-to-segment distance of the
        centre, minus the radius.  Polygons: segment-to-polygon set distance
        (0 when the segment enters the polygon, which an end point inside or
        an edge crossing reveals).  ``polygons``: ``False`` leaves them out, ``"dense"``
        folds every edge, ``True`` near edges only on many (:mod:`planner.nearest`).
        """
        a = np.asarray(a, float).reshape(-1, 2)
        b = np.asarray(b, float).reshape(-1, 2)
        if polygons is True and self.polygons and len(a) * len(self.edges[0]) > _NEAR_PAIRS:
            best, who = self.segment_clearance_detail(a, b, polygons=False)
            return fold_near(self, best, who, a, b, (point_segment_distance, _crossing))
        rows = _rows_per_chunk(3 * (len(self.circle_radii) + (len(self.edges[0]) if polygons else 0)))
        if len(a) > rows:
            parts = [self.segment_clearance_detail(a[r : r + rows], b[r : r + rows], polygons)
                     for r in range(0, len(a), rows)]
            return np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts])
        n = len(a)
        best = np.minimum(self.wall_clearance(a), self.wall_clearance(b))
        who = np.full(n, -1)
        if len(self.circle_radii):
            d = point_segment_distance(self.circle_centers[None], a[:, None], b[:, None])
            d = d - self.circle_radii[None]
            best, who = _fold_min(best, who, d, self.circle_ids)
        if polygons and self.polygons and n:
            ea, eb, _ = self.edges
            # Segment to polygon edge: the distance is attained at an end of
            # one of them; every polygon vertex starts an edge, so the
            # vertices need one pass; a crossing makes it 0.
            a1, b1 = a[:, None], b[:, None]
            d = np.minimum(
                np.minimum(point_segment_distance(a1, ea[None], eb[None]),
                           point_segment_distance(b1, ea[None], eb[None])),
                point_segment_distance(ea[None], a1, b1),
            )
            d[_crossing(a1, b1, ea[None], eb[None])] = 0.0
            dp = np.minimum.reduceat(d, self.edge_starts, axis=1)  # (n, P)
            dp[self._inside(a)] = 0.0
            best, who = _fold_min(best, who, dp, self.polygon_ids)
        return best, who
