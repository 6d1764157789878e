"""The witnesses' own closed-form distance kernels, independent of :mod:`planner.geometry`.

The contact witnesses check the planner's plans, so they must not share its
geometry code: a bug in one kernel would otherwise blind both the exact
validator and the physics witness.  These kernels are written apart, with
other formulations, and tested against :mod:`planner.geometry` on random
inputs (``tests/sim/test_kernels.py``):

* point-segment distance by *Voronoi regions* (behind ``a``, behind ``b``,
  or beside the segment, where it is the perpendicular ``|cross| / |ab|``),
  not by clamping a projection parameter;
* point in polygon by the *winding number* (signed crossings of upward and
  downward edges, decided by orientation), not by even-odd ray crossings;
* wall clearance as the distance to the rectangle's centre lines,
  ``min(W/2 - |x - W/2|, H/2 - |y - H/2|)``.

Swept kernels (a centre moving on a straight line over one step, ``p(s) =
p0 + s (p1 - p0)``, ``s`` in ``[0, 1]``):

* two moving discs: the relative position ``d(s) = d0 + s e`` has
  ``|d(s)|^2 = |d0|^2 + 2 s (d0.e) + s^2 |e|^2``, a quadratic whose minimum
  on ``[0, 1]`` is at an end or at its vertex ``-(d0.e)/|e|^2``;
* a moving centre and a segment: the distance between the swept path and
  the segment, i.e. 0 where they cross, else the least of the four
  endpoint-to-segment distances;
* a moving centre and a circle: the distance from the circle's centre to
  the swept path, minus the circle's radius;
* walls: the wall clearance is concave (a minimum of linear functions), so
  its minimum over a straight move is at one of the two ends.

All kernels broadcast over leading axes; the last axis of a point is 2.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "circle_clearance",
    "inside_polygon",
    "polygon_signed_distance",
    "segment_distance",
    "swept_circle_distance",
    "swept_pair_distance",
    "swept_segment_distance",
    "swept_wall_clearance",
    "wall_clearance",
]


def _cross(ux, uy, vx, vy):
    return ux * vy - uy * vx


def segment_distance(p, a, b) -> np.ndarray:
    """Distance from points ``p`` to segments ``[a, b]`` (broadcasting), by Voronoi regions."""
    p, a, b = (np.asarray(x, float) for x in (p, a, b))
    ex, ey = b[..., 0] - a[..., 0], b[..., 1] - a[..., 1]
    ax, ay = p[..., 0] - a[..., 0], p[..., 1] - a[..., 1]
    bx, by = p[..., 0] - b[..., 0], p[..., 1] - b[..., 1]
    behind_a = ax * ex + ay * ey <= 0.0  # also every point of a zero-length segment
    behind_b = bx * ex + by * ey >= 0.0
    length = np.hypot(ex, ey)
    with np.errstate(invalid="ignore", divide="ignore"):
        beside = np.abs(_cross(ex, ey, ax, ay)) / length
    return np.where(behind_a, np.hypot(ax, ay), np.where(behind_b, np.hypot(bx, by), beside))


def inside_polygon(points, poly) -> np.ndarray:
    """``(N,)`` whether each point is inside the simple polygon ``poly`` ``(k, 2)`` (winding number).

    Points on the boundary may fall either way; distances are 0 there.
    """
    pts = np.asarray(points, float).reshape(-1, 2)
    poly = np.asarray(poly, float)
    a = poly[None, :, :]
    b = np.roll(poly, -1, axis=0)[None, :, :]
    px, py = pts[:, None, 0], pts[:, None, 1]
    side = _cross(b[..., 0] - a[..., 0], b[..., 1] - a[..., 1], px - a[..., 0], py - a[..., 1])
    up = (a[..., 1] <= py) & (b[..., 1] > py) & (side > 0.0)
    down = (a[..., 1] > py) & (b[..., 1] <= py) & (side < 0.0)
    winding = up.sum(axis=1) - down.sum(axis=1)
    return winding != 0


def polygon_signed_distance(points, poly) -> np.ndarray:
    """``(N,)`` distance from each point to the polygon's boundary, negative inside."""
    pts = np.asarray(points, float).reshape(-1, 2)
    poly = np.asarray(poly, float)
    d = segment_distance(pts[:, None, :], poly[None], np.roll(poly, -1, axis=0)[None]).min(axis=1)
    return np.where(inside_polygon(pts, poly), -d, d)


def circle_clearance(points, centers, radii) -> np.ndarray:
    """``(N, C)`` distance from each point to each circle's rim, negative inside."""
    pts = np.asarray(points, float).reshape(-1, 2)
    c = np.asarray(centers, float).reshape(-1, 2)
    return np.hypot(pts[:, None, 0] - c[None, :, 0], pts[:, None, 1] - c[None, :, 1]) - np.asarray(radii, float)[None]


def wall_clearance(points, width: float, height: float) -> np.ndarray:
    """Distance from each point to the nearest side of ``[0, W] x [0, H]`` (negative outside)."""
    p = np.asarray(points, float)
    hw, hh = 0.5 * float(width), 0.5 * float(height)
    return np.minimum(hw - np.abs(p[..., 0] - hw), hh - np.abs(p[..., 1] - hh))


# -- swept ------------------------------------------------------------------------------


def swept_pair_distance(p0, p1, q0, q1):
    """Least distance of two centres moving ``p0 -> p1`` and ``q0 -> q1`` over the same step.

    Returns ``(distance, s)``: the minimum over ``s`` in ``[0, 1]`` and the
    ``s`` where it is attained (the first end on ties).
    """
    p0, p1, q0, q1 = (np.asarray(x, float) for x in (p0, p1, q0, q1))
    dx, dy = p0[..., 0] - q0[..., 0], p0[..., 1] - q0[..., 1]
    ex = (p1[..., 0] - p0[..., 0]) - (q1[..., 0] - q0[..., 0])
    ey = (p1[..., 1] - p0[..., 1]) - (q1[..., 1] - q0[..., 1])
    c0 = dx * dx + dy * dy  # f(s) = c0 + 2 s c1 + s^2 c2
    c1 = dx * ex + dy * ey
    c2 = ex * ex + ey * ey
    f1 = c0 + 2.0 * c1 + c2
    with np.errstate(invalid="ignore", divide="ignore"):
        vertex = -c1 / c2
    interior = (c2 > 0.0) & (vertex > 0.0) & (vertex < 1.0)
    fv = np.where(interior, c0 + c1 * np.where(interior, vertex, 0.0), np.inf)
    best = np.minimum(np.minimum(c0, f1), fv)
    s = np.where(fv <= np.minimum(c0, f1), np.where(interior, vertex, 0.0), np.where(f1 < c0, 1.0, 0.0))
    return np.sqrt(np.maximum(best, 0.0)), s


def _param_on(p0, p1, x):
    """The parameter ``s`` in ``[0, 1]`` of the point of ``[p0, p1]`` nearest to ``x``."""
    ex, ey = p1[..., 0] - p0[..., 0], p1[..., 1] - p0[..., 1]
    num = (x[..., 0] - p0[..., 0]) * ex + (x[..., 1] - p0[..., 1]) * ey
    den = ex * ex + ey * ey
    with np.errstate(invalid="ignore", divide="ignore"):
        s = np.where(den > 0.0, num / den, 0.0)
    return np.clip(s, 0.0, 1.0)


def swept_segment_distance(p0, p1, a, b):
    """Least distance of a centre moving ``p0 -> p1`` to the segment ``[a, b]``.

    Returns ``(distance, s)``: 0 where the path crosses the segment, else the
    least of the four endpoint-to-segment distances, and the path parameter
    of the nearest point.
    """
    p0, p1, a, b = (np.asarray(x, float) for x in (p0, p1, a, b))
    ux, uy = p1[..., 0] - p0[..., 0], p1[..., 1] - p0[..., 1]
    vx, vy = b[..., 0] - a[..., 0], b[..., 1] - a[..., 1]
    o_a = _cross(ux, uy, a[..., 0] - p0[..., 0], a[..., 1] - p0[..., 1])
    o_b = _cross(ux, uy, b[..., 0] - p0[..., 0], b[..., 1] - p0[..., 1])
    o_p0 = _cross(vx, vy, p0[..., 0] - a[..., 0], p0[..., 1] - a[..., 1])
    o_p1 = _cross(vx, vy, p1[..., 0] - a[..., 0], p1[..., 1] - a[..., 1])
    cross = (np.sign(o_a) * np.sign(o_b) < 0) & (np.sign(o_p0) * np.sign(o_p1) < 0)
    cand = np.stack(np.broadcast_arrays(
        segment_distance(p0, a, b), segment_distance(p1, a, b),
        segment_distance(a, p0, p1), segment_distance(b, p0, p1)), axis=-1)
    pick = np.argmin(cand, axis=-1)
    dist = np.take_along_axis(cand, pick[..., None], axis=-1)[..., 0]
    shape = dist.shape
    s_cand = np.stack(np.broadcast_arrays(
        np.zeros(shape), np.ones(shape), _param_on(p0, p1, a), _param_on(p0, p1, b)), axis=-1)
    s = np.take_along_axis(s_cand, pick[..., None], axis=-1)[..., 0]
    with np.errstate(invalid="ignore", divide="ignore"):
        s_cross = o_p0 / (o_p0 - o_p1)
    return np.where(cross, 0.0, dist), np.where(cross, s_cross, s)


def swept_circle_distance(p0, p1, center, radius):
    """Least distance of a centre moving ``p0 -> p1`` to a circle's rim (negative inside).

    Returns ``(distance, s)``.
    """
    p0, p1, center = (np.asarray(x, float) for x in (p0, p1, center))
    s = _param_on(p0, p1, np.broadcast_to(center, np.broadcast_shapes(p0.shape, center.shape)))
    qx = p0[..., 0] + s * (p1[..., 0] - p0[..., 0]) - center[..., 0]
    qy = p0[..., 1] + s * (p1[..., 1] - p0[..., 1]) - center[..., 1]
    return np.hypot(qx, qy) - np.asarray(radius, float), s


def swept_wall_clearance(p0, p1, width: float, height: float):
    """Least wall clearance of a centre moving ``p0 -> p1``: at an end (the clearance is concave).

    Returns ``(clearance, s)``.
    """
    c0 = wall_clearance(p0, width, height)
    c1 = wall_clearance(p1, width, height)
    return np.minimum(c0, c1), np.where(c1 < c0, 1.0, 0.0)
