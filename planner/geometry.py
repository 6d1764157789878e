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


def greedy_separated(cand: np.ndarray, sep: float, existing: np.ndarray | None = None,
                     limit: int | None = None) -> np.ndarray:
    """Indices of candidates accepted in order when ``sep`` from all accepted so far.

    Candidates too close to ``existing`` points are skipped; at most
    ``limit`` are accepted.  KD-trees keep this near-linear.
    """
    from scipy.spatial import cKDTree

    cand = np.asarray(cand, float).reshape(-1, 2)
    idx = np.arange(len(cand))
    if existing is not None and len(existing) and len(cand):
        d, _ = cKDTree(existing).query(cand, distance_upper_bound=sep)
        idx = idx[d >= sep]
    if len(idx) == 0 or limit == 0:
        return idx[:0]
    later = [[] for _ in range(len(idx))]
    for i, j in cKDTree(cand[idx]).query_pairs(sep, output_type="ndarray"):
        later[min(i, j)].append(max(i, j))
    blocked = np.zeros(len(idx), bool)
    accepted = []
    for i in range(len(idx)):
        if blocked[i]:
            continue
        accepted.append(i)
        if limit is not None and len(accepted) >= limit:
            break
        blocked[later[i]] = True
    return idx[accepted]


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


def _segment_edge_close(ax, ay, bx, by, cx, cy, dx, dy, clearance: float) -> np.ndarray:
    """Segments ``[a, b]`` and ``[c, d]`` (1-D coordinate arrays) come closer than ``clearance``.

    :func:`segment_segment_distance`'s test without its fourth distance
    (``d`` to ``[a, b]``: the caller tests every edge of a closed polygon,
    and ``d`` starts the next one), written on coordinate arrays; each
    distance is computed exactly as :func:`point_segment_distance` does, so
    the answers agree with :meth:`Environment.segment_clearance` to the bit.
    """
    abx, aby = bx - ax, by - ay
    cdx, cdy = dx - cx, dy - cy
    acx, acy = ax - cx, ay - cy
    bcx, bcy = bx - cx, by - cy
    cd2 = np.maximum(cdx * cdx + cdy * cdy, 1e-300)
    ab2 = np.maximum(abx * abx + aby * aby, 1e-300)
    bad = np.zeros(len(ax), bool)
    for px, py, ux, uy, u2 in ((acx, acy, cdx, cdy, cd2), (bcx, bcy, cdx, cdy, cd2), (-acx, -acy, abx, aby, ab2)):
        t = np.minimum(np.maximum((px * ux + py * uy) / u2, 0.0), 1.0)
        ex, ey = px - t * ux, py - t * uy
        bad |= np.sqrt(ex * ex + ey * ey) < clearance
    # a strict crossing (the orientations of _crossing)
    o1 = abx * (cy - ay) - aby * (cx - ax)
    o2 = abx * (dy - ay) - aby * (dx - ax)
    o3 = cdx * (ay - cy) - cdy * (ax - cx)
    o4 = cdx * (by - cy) - cdy * (bx - cx)
    return bad | ((o1 * o2 < 0.0) & (o3 * o4 < 0.0))


def _fold_min(best, who, d, ids):
    """Fold distances ``(n, K)`` to K obstacles into the running minimum and its owner."""
    j = np.argmin(d, axis=1)
    dj = d[np.arange(len(d)), j]
    better = dj < best
    return np.where(better, dj, best), np.where(better, np.asarray(ids)[j], who)


def _boxes_near(lo: np.ndarray, hi: np.ndarray, boxes: np.ndarray, clearance: float) -> np.ndarray:
    """``(N, B)``: which boxes ``[lo, hi]`` come within ``clearance`` of each of ``boxes``
    (rows ``xmin, ymin, xmax, ymax``); the gap along one axis bounds the distance from below."""
    gap_x = np.maximum(boxes[None, :, 0] - hi[:, None, 0], lo[:, None, 0] - boxes[None, :, 2])
    gap_y = np.maximum(boxes[None, :, 1] - hi[:, None, 1], lo[:, None, 1] - boxes[None, :, 3])
    return (gap_x < clearance) & (gap_y < clearance)


_CHUNK = 1 << 21  # entries of a (rows x obstacle features) temporary
_DENSE_PAIRS = 1 << 17  # up to this many (query, box) pairs the dense box test is used


def _rows_per_chunk(width: int) -> int:
    return max(1, _CHUNK // max(width, 1))


def _ball_pairs(tree, centers: np.ndarray, radius: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(query, item)`` index pairs with the item's indexed point within ``radius[query]``."""
    if len(centers) == 0 or tree is None:
        return np.zeros(0, int), np.zeros(0, int)
    lists = tree.query_ball_point(centers, radius, return_sorted=False)
    counts = np.fromiter((len(x) for x in lists), int, len(lists))
    qi = np.repeat(np.arange(len(centers)), counts)
    items = np.fromiter((j for x in lists for j in x), int, int(counts.sum()))
    return qi, items


def _box_gap_ok(lo, hi, boxes, clearance) -> np.ndarray:
    """Row-wise :func:`_boxes_near`: box ``[lo[k], hi[k]]`` within ``clearance`` of ``boxes[k]``."""
    gap_x = np.maximum(boxes[:, 0] - hi[:, 0], lo[:, 0] - boxes[:, 2])
    gap_y = np.maximum(boxes[:, 1] - hi[:, 1], lo[:, 1] - boxes[:, 3])
    return (gap_x < clearance) & (gap_y < clearance)


@dataclass(frozen=True, eq=False)
class Environment:
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

    # -- derived arrays -------------------------------------------------------
    @property
    def edges(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """All polygon edges as ``(A (E, 2), B (E, 2), owner (E,))``; cached.

        Edges are stored polygon after polygon, so per-polygon reductions
        use ``np.*.reduceat`` at :attr:`edge_starts`.
        """
        cached = self.__dict__.get("_edges")
        if cached is None:
            if self.polygons:
                a = np.concatenate(self.polygons)
                b = np.concatenate([np.roll(p, -1, axis=0) for p in self.polygons])
                owner = np.concatenate(
                    [np.full(len(p), i) for i, p in enumerate(self.polygons)]
                )
            else:
                a = b = np.zeros((0, 2))
                owner = np.zeros(0, int)
            cached = (a, b, owner)
            object.__setattr__(self, "_edges", cached)
            starts = np.concatenate([[0], np.cumsum([len(p) for p in self.polygons])[:-1]]).astype(int)
            object.__setattr__(self, "_starts", starts)
        return cached

    @property
    def edge_boxes(self) -> np.ndarray:
        """``(E, 4)`` bounding boxes ``xmin, ymin, xmax, ymax`` of the polygon edges; cached."""
        cached = self.__dict__.get("_edge_boxes")
        if cached is None:
            a, b, _ = self.edges
            cached = np.concatenate([np.minimum(a, b), np.maximum(a, b)], axis=1)
            object.__setattr__(self, "_edge_boxes", cached)
        return cached

    @property
    def edge_starts(self) -> np.ndarray:
        self.edges
        return self.__dict__["_starts"]

    def _index(self, name: str, boxes: np.ndarray):
        """A KD-tree over ``boxes``' pieces (cached): each box is cut along its longer
        side into pieces of at most ``piece`` wide, and the tree holds their centres;
        returns ``(tree, piece owner, largest piece half-diagonal)``."""
        cached = self.__dict__.get(name)
        if cached is None:
            from scipy.spatial import cKDTree

            if len(boxes) == 0:
                cached = (None, np.zeros(0, int), 0.0)
            else:
                ext = boxes[:, 2:] - boxes[:, :2]
                piece = max(float(np.median(ext.max(axis=1))), 1e-9)
                n = np.maximum(1, np.ceil(ext.max(axis=1) / piece).astype(int))
                owner = np.repeat(np.arange(len(boxes)), n)
                k = np.arange(len(owner)) - np.repeat(np.cumsum(n) - n, n)
                f0, f1 = k / n[owner], (k + 1) / n[owner]
                lo, hi = boxes[owner, :2], boxes[owner, 2:]
                # cut along each box's longer side
                along_x = (ext[owner, 0] >= ext[owner, 1])[:, None]
                span = hi - lo
                plo = np.where(along_x, lo + np.stack([f0 * span[:, 0], 0 * f0], 1), lo + np.stack([0 * f0, f0 * span[:, 1]], 1))
                phi = np.where(along_x, lo + np.stack([f1 * span[:, 0], span[:, 1]], 1), lo + np.stack([span[:, 0], f1 * span[:, 1]], 1))
                half = 0.5 * float(np.linalg.norm(phi - plo, axis=1).max())
                cached = (cKDTree(0.5 * (plo + phi)), owner, half)
            object.__setattr__(self, name, cached)
        return cached

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

    def point_clearance_detail(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Clearance of each point and what attains it (obstacle index, -1 = wall)."""
        pts = np.asarray(points, float).reshape(-1, 2)
        width = len(self.circle_radii) + len(self.edges[0])
        rows = _rows_per_chunk(width)
        if len(pts) > rows:
            parts = [self.point_clearance_detail(pts[r : r + rows]) for r in range(0, len(pts), rows)]
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
        if self.polygons and n:
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

    @property
    def obstacle_boxes(self) -> np.ndarray:
        """``(O, 4)`` bounding boxes ``xmin, ymin, xmax, ymax`` of all obstacles; cached."""
        cached = self.__dict__.get("_boxes")
        if cached is None:
            boxes = [np.r_[p.min(axis=0), p.max(axis=0)] for p in self.polygons]
            boxes += [np.r_[c - r, c + r] for c, r in zip(self.circle_centers, self.circle_radii)]
            cached = np.asarray(boxes, float).reshape(-1, 4)
            object.__setattr__(self, "_boxes", cached)
        return cached

    def _near_obstacles(self, a: np.ndarray, b: np.ndarray, clearance: float) -> np.ndarray:
        """Which segments ``a -> b`` may come within ``clearance`` of an obstacle (every one
        that does, among those whose box comes within ``clearance`` of the obstacle's box)."""
        qi, _ = self._pairs_near("_obstacle_index", self.obstacle_boxes, a, b, clearance)
        out = np.zeros(len(a), bool)
        out[qi] = True
        return out

    def segments_clear(self, a: np.ndarray, b: np.ndarray, clearance: float) -> np.ndarray:
        """Whether centres moving along ``a -> b`` keep ``clearance`` everywhere (exact).

        Same answer as ``segment_clearance(a, b) >= clearance``, faster: a
        segment whose bounding box stays ``clearance`` away from every
        obstacle's box only needs the wall test (linear along the segment,
        so its ends decide).
        """
        a = np.asarray(a, float).reshape(-1, 2)
        b = np.asarray(b, float).reshape(-1, 2)
        ok = np.minimum(self.wall_clearance(a), self.wall_clearance(b)) >= clearance
        near = ok & self._near_obstacles(a, b, clearance)
        if near.any():
            ok[near] = self._segments_keep(a[near], b[near], clearance)
        return ok

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

    def points_clear(self, points: np.ndarray, clearance: float) -> np.ndarray:
        """Whether each centre keeps ``clearance`` from walls and obstacles (exact)."""
        p = np.asarray(points, float).reshape(-1, 2)
        ok = self.wall_clearance(p) >= clearance
        near = ok & self._near_obstacles(p, p, clearance)
        if near.any():
            ok[near] = self._segments_keep(p[near], p[near], clearance)  # a point is a zero-length segment
        return ok

    def segment_clearance_detail(self, a: np.ndarray, b: np.ndarray):
        """Exact minimum clearance along segments ``a -> b`` and what attains it.

        ``a`` and ``b`` are ``(N, 2)``; returns ``(clearance (N,), who (N,))``
        with ``who`` the obstacle index or -1 for the wall.  Walls: the wall
        clearance is linear along a segment inside the rectangle, so its
        minimum is at an end.  Circles: point-to-segment distance of the
        centre, minus the radius.  Polygons: segment-to-polygon set distance
        (0 when the segment enters the polygon, which an end point inside or
        an edge crossing reveals).
        """
        a = np.asarray(a, float).reshape(-1, 2)
        b = np.asarray(b, float).reshape(-1, 2)
        rows = _rows_per_chunk(3 * (len(self.circle_radii) + len(self.edges[0])))
        if len(a) > rows:
            parts = [self.segment_clearance_detail(a[r : r + rows], b[r : r + rows]) for r in range(0, len(a), rows)]
            return np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts])
        n = len(a)
        best = np.minimum(self.wall_clearance(a), self.wall_clearance(b))
        who = np.full(n, -1)
        if len(self.circle_radii):
            d = point_segment_distance(self.circle_centers[None], a[:, None], b[:, None])
            d = d - self.circle_radii[None]
            best, who = _fold_min(best, who, d, self.circle_ids)
        if self.polygons and n:
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
