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
    abx = b[..., 0] - a[..., 0]
    aby = b[..., 1] - a[..., 1]
    apx = p[..., 0] - a[..., 0]
    apy = p[..., 1] - a[..., 1]
    den = abx * abx + aby * aby
    with np.errstate(invalid="ignore", divide="ignore"):
        t = np.where(den > 0.0, (apx * abx + apy * aby) / np.where(den > 0.0, den, 1.0), 0.0)
    t = np.clip(t, 0.0, 1.0)
    dx = apx - t * abx
    dy = apy - t * aby
    return np.sqrt(dx * dx + dy * dy)


def _orient(ax, ay, bx, by, cx, cy):
    """Twice the signed area of triangle (a, b, c)."""
    return (bx - ax) * (cy - ay) - (by - ay) * (cx - ax)


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
    o1 = _orient(a[..., 0], a[..., 1], b[..., 0], b[..., 1], c[..., 0], c[..., 1])
    o2 = _orient(a[..., 0], a[..., 1], b[..., 0], b[..., 1], d[..., 0], d[..., 1])
    o3 = _orient(c[..., 0], c[..., 1], d[..., 0], d[..., 1], a[..., 0], a[..., 1])
    o4 = _orient(c[..., 0], c[..., 1], d[..., 0], d[..., 1], b[..., 0], b[..., 1])
    crossing = (o1 * o2 < 0.0) & (o3 * o4 < 0.0)
    return np.where(crossing, 0.0, dist)


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
    uu = ux * ux + uy * uy
    with np.errstate(invalid="ignore", divide="ignore"):
        t = np.where(uu > 0.0, -(wx * ux + wy * uy) / np.where(uu > 0.0, uu, 1.0), 0.0)
    t = np.clip(t, 0.0, 1.0)
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
        """All polygon edges as ``(A (E, 2), B (E, 2), owner (E,))``; cached."""
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
        return cached

    # -- points ---------------------------------------------------------------
    def wall_clearance(self, p: np.ndarray) -> np.ndarray:
        p = np.asarray(p, float)
        x, y = p[..., 0], p[..., 1]
        return np.minimum(np.minimum(x, self.width - x), np.minimum(y, self.height - y))

    def point_clearance_detail(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Clearance of each point and what attains it (obstacle index, -1 = wall)."""
        pts = np.asarray(points, float).reshape(-1, 2)
        n = len(pts)
        best = self.wall_clearance(pts)
        who = np.full(n, -1)
        if len(self.circle_radii):
            d = (
                np.sqrt(((pts[:, None, :] - self.circle_centers[None]) ** 2).sum(-1))
                - self.circle_radii[None]
            )
            j = np.argmin(d, axis=1)
            dj = d[np.arange(n), j]
            better = dj < best
            best = np.where(better, dj, best)
            who = np.where(better, np.asarray(self.circle_ids)[j], who)
        if self.polygons:
            a, b, owner = self.edges
            d = point_segment_distance(pts[:, None, :], a[None], b[None])  # (n, E)
            for i, poly in enumerate(self.polygons):
                di = d[:, owner == i].min(axis=1)
                di = np.where(points_in_polygon(pts, poly), 0.0, di)
                better = di < best
                best = np.where(better, di, best)
                who = np.where(better, self.polygon_ids[i], who)
        return best, who

    def point_clearance(self, points: np.ndarray) -> np.ndarray:
        """Distance from each centre to the nearest wall or obstacle."""
        return self.point_clearance_detail(points)[0]

    # -- segments -------------------------------------------------------------
    def segment_clearance(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """Exact minimum clearance of centres moving along segments ``a -> b``."""
        return self.segment_clearance_detail(a, b)[0]

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
        n = len(a)
        best = np.minimum(self.wall_clearance(a), self.wall_clearance(b))
        who = np.full(n, -1)
        if len(self.circle_radii):
            d = point_segment_distance(self.circle_centers[None], a[:, None], b[:, None])
            d = d - self.circle_radii[None]
            j = np.argmin(d, axis=1)
            dj = d[np.arange(n), j]
            better = dj < best
            best = np.where(better, dj, best)
            who = np.where(better, np.asarray(self.circle_ids)[j], who)
        if self.polygons:
            ea, eb, owner = self.edges
            d = segment_segment_distance(a[:, None], b[:, None], ea[None], eb[None])
            j = np.argmin(d, axis=1)
            dj = d[np.arange(n), j]
            pid = np.asarray(self.polygon_ids)[owner[j]]
            for i, poly in enumerate(self.polygons):
                inside = points_in_polygon(a, poly)
                dj = np.where(inside, 0.0, dj)
                pid = np.where(inside, self.polygon_ids[i], pid)
            better = dj < best
            best = np.where(better, dj, best)
            who = np.where(better, pid, who)
        return best, who
