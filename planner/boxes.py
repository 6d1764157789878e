"""Derived arrays and box pruning for :class:`planner.geometry.Environment`.

The polygon edges, bounding boxes of the obstacles and of the edges,
KD-tree indexes over pieces of those boxes, and the boolean clearance tests
that use them (:meth:`BoxIndex.segments_clear`, :meth:`BoxIndex.points_clear`):
only the (segment, obstacle) pairs whose boxes come within the clearance
are tested exactly, so the answers equal those of the exact kernels.
:class:`BoxIndex` is the environment's base class; it reads the
environment's fields and exact kernels through ``self``.
"""

from __future__ import annotations

import numpy as np

__all__ = ["BoxIndex"]


def _segment_edge_close(ax, ay, bx, by, cx, cy, dx, dy, clearance: float) -> np.ndarray:
    """Segments ``[a, b]`` and ``[c, d]`` (1-D coordinate arrays) come closer than ``clearance``.

    :func:`planner.geometry.segment_segment_distance`'s test without its fourth distance
    (``d`` to ``[a, b]``: the caller tests every edge of a closed polygon,
    and ``d`` starts the next one), written on coordinate arrays; each
    distance is computed exactly as :func:`planner.geometry.point_segment_distance` does, so
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



def _boxes_near(lo: np.ndarray, hi: np.ndarray, boxes: np.ndarray, clearance: float) -> np.ndarray:
    """``(N, B)``: which boxes ``[lo, hi]`` come within ``clearance`` of each of ``boxes``
    (rows ``xmin, ymin, xmax, ymax``); the gap along one axis bounds the distance from below."""
    gap_x = np.maximum(boxes[None, :, 0] - hi[:, None, 0], lo[:, None, 0] - boxes[None, :, 2])
    gap_y = np.maximum(boxes[None, :, 1] - hi[:, None, 1], lo[:, None, 1] - boxes[None, :, 3])
    return (gap_x < clearance) & (gap_y < clearance)


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


class BoxIndex:
    """The derived arrays and box-pruned tests of :class:`planner.geometry.Environment` (its base class)."""

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
        _ = self.edges  # computes and caches the starts too
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
                phi = np.where(along_x, lo + np.stack([f1 * span[:, 0], span[:, 1]], 1),
                       lo + np.stack([span[:, 0], f1 * span[:, 1]], 1))
                half = 0.5 * float(np.linalg.norm(phi - plo, axis=1).max())
                cached = (cKDTree(0.5 * (plo + phi)), owner, half)
            object.__setattr__(self, name, cached)
        return cached

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

    def points_clear(self, points: np.ndarray, clearance: float) -> np.ndarray:
        """Whether each centre keeps ``clearance`` from walls and obstacles (exact)."""
        p = np.asarray(points, float).reshape(-1, 2)
        ok = self.wall_clearance(p) >= clearance
        near = ok & self._near_obstacles(p, p, clearance)
        if near.any():
            ok[near] = self._segments_keep(p[near], p[near], clearance)  # a point is a zero-length segment
        return ok
