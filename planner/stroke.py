"""One stroke of a drawing: an open or closed polyline, or a circular arc,
measured and sampled by arc length (see :mod:`planner.strokes`)."""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from .geometry import point_segment_distance

__all__ = ["Stroke"]


@dataclass(frozen=True)
class Stroke:
    """A polyline (``arc is None``) or an arc ``(cx, cy, r, theta0, theta1)`` [radians].

    ``start_free``/``end_free`` say whether a robot may sit on the first or
    last point (False where the point lies on another stroke); a closed
    stroke has no ends.
    """

    points: tuple = ()
    arc: tuple | None = None
    closed: bool = False
    start_free: bool = True
    end_free: bool = True

    @cached_property
    def length(self) -> float:
        if self.arc is not None:
            _, _, r, t0, t1 = self.arc
            return abs(t1 - t0) * r
        p = self._path()
        return float(np.linalg.norm(np.diff(p, axis=0), axis=1).sum())

    def _path(self) -> np.ndarray:
        p = np.asarray(self.points, float)
        return np.vstack([p, p[:1]]) if self.closed else p

    @property
    def ends(self) -> np.ndarray:
        """First and last point ``(2, 2)``."""
        if self.arc is not None:
            return self.at(np.array([0.0, self.length]))
        p = np.asarray(self.points, float)
        return np.stack([p[0], p[-1]])

    def at(self, s: np.ndarray) -> np.ndarray:
        """Points at arc lengths ``s`` from the stroke's start."""
        s = np.asarray(s, float)
        if self.arc is not None:
            cx, cy, r, t0, t1 = self.arc
            th = t0 + np.sign(t1 - t0) * s / r
            return np.stack([cx + r * np.cos(th), cy + r * np.sin(th)], axis=-1)
        p = self._path()
        seg = np.linalg.norm(np.diff(p, axis=0), axis=1)
        cum = np.concatenate([[0.0], np.cumsum(seg)])
        k = np.clip(np.searchsorted(cum, s, side="right") - 1, 0, len(seg) - 1)
        u = (s - cum[k]) / np.where(seg[k] > 0, seg[k], 1.0)
        return p[k] + u[:, None] * (p[k + 1] - p[k])

    def distance(self, q: np.ndarray) -> np.ndarray:
        """Distance from points ``q`` ``(n, 2)`` to the stroke."""
        q = np.asarray(q, float).reshape(-1, 2)
        if self.arc is not None:
            cx, cy, r, t0, t1 = self.arc
            lo, hi = min(t0, t1), max(t0, t1)
            v = q - [cx, cy]
            th = np.arctan2(v[:, 1], v[:, 0])
            # the angle brought into [lo, lo + 2 pi)
            th = lo + np.mod(th - lo, 2 * np.pi)
            on_arc = th <= hi
            d_ring = np.abs(np.hypot(v[:, 0], v[:, 1]) - r)
            e = self.ends
            d_end = np.minimum(np.linalg.norm(q - e[0], axis=1), np.linalg.norm(q - e[1], axis=1))
            return np.where(on_arc, d_ring, d_end)
        p = self._path()
        if len(p) == 1:
            return np.linalg.norm(q - p[0], axis=1)
        return point_segment_distance(q[:, None], p[None, :-1], p[None, 1:]).min(axis=1)

    @property
    def excluded_ends(self) -> int:
        return 0 if self.closed else int(not self.start_free) + int(not self.end_free)
