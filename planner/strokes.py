"""Strokes: robots spread along polylines (and circular arcs) by arc length.

A drawing is a tuple of strokes.  A stroke is an open polyline, a closed
polyline (its last point equals its first; one with sharp corners is opened
at its first corner), or a circular arc.  Robots are allocated to the
strokes so that the spacing along every stroke is about the same
(:func:`planner.spread._allocate`), then spread evenly along each stroke.

Where strokes meet only one of them puts a robot on the shared point: an end
of a stroke is *excluded* when it lies on an earlier stroke, or inside (not
at an end of) a later one.  Open polylines are split at sharp corners
(turning by more than :data:`CORNER_DEGREES`) so that every such corner holds
a robot and the two arms never crowd each other.  Strokes that cross or
touch elsewhere can still bring two robots close: such pairs lose one robot
each and the drawing is spread again with as many more (:func:`stroke_points`;
strokes that cross everywhere fall back to a greedy pick along them).

The same sampler draws the paper's letters, user-drawn ``strokes:`` and the
skeletons of rendered text.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .spread import SPACING_SLACK, count_at_spacing, scaled_shape, stroke_points
from .stroke import Stroke

__all__ = [
    "Arc",
    "CORNER_DEGREES",
    "MAX_POINTS",
    "MAX_STROKES",
    "MAX_TOTAL",
    "Stroke",
    "bounds",
    "check_polylines",
    "count_at_spacing",
    "drawing",
    "extent",
    "scaled_shape",
    "stroke_length",
    "stroke_points",
    "strokes_shape",
]

#: Open polylines are split where they turn by more than this [degrees].
CORNER_DEGREES = 40.0
#: Bounds of a drawing given as plain polylines.
MAX_STROKES = 64
MAX_POINTS = 512  # per stroke
MAX_TOTAL = 1024  # points over all strokes

_ON = 1e-9  # relative tolerance of "lies on" tests (of the drawing's size)


def stroke_length(polyline) -> float:
    """Length of a polyline ``(k, 2)`` [same units as its points]."""
    p = np.asarray(polyline, float)
    return float(np.linalg.norm(np.diff(p, axis=0), axis=1).sum())


def check_polylines(polylines, field: str = "strokes") -> tuple[np.ndarray, ...]:
    """Check plain polylines and return them as float arrays.

    Raises ``ValueError`` (``"FIELD[i]: reason"``) unless there are 1 to
    :data:`MAX_STROKES` strokes of 2 to :data:`MAX_POINTS` finite points each
    (at most :data:`MAX_TOTAL` in all) with some length in total.
    """
    if not isinstance(polylines, (list, tuple)) or not 1 <= len(polylines) <= MAX_STROKES:
        n = len(polylines) if isinstance(polylines, (list, tuple)) else "no"
        raise ValueError(f"{field}: must be a list of 1 to {MAX_STROKES} strokes, got {n}")
    out, total = [], 0
    for i, line in enumerate(polylines):
        try:
            p = np.asarray(line, float)
        except (TypeError, ValueError):
            raise ValueError(f"{field}[{i}]: must be a list of [x, y] points") from None
        if p.ndim != 2 or p.shape[1] != 2 or not 2 <= len(p) <= MAX_POINTS:
            raise ValueError(f"{field}[{i}]: must be a list of 2 to {MAX_POINTS} points [x, y]")
        if not np.all(np.isfinite(p)):
            raise ValueError(f"{field}[{i}]: holds a non-finite coordinate")
        total += len(p)
        if total > MAX_TOTAL:
            raise ValueError(f"{field}: more than {MAX_TOTAL} points in all")
        out.append(p)
    if sum(stroke_length(p) for p in out) <= 0:
        raise ValueError(f"{field}: every stroke has zero length; draw at least one line")
    return tuple(out)


def _first_corner(ring: np.ndarray) -> int | None:
    """Index of the first sharp corner of a closed polyline (its points without the repeat), or None."""
    keep = np.linalg.norm(ring - np.roll(ring, 1, axis=0), axis=1) > 0
    idx = np.flatnonzero(keep)
    q = ring[idx]
    if len(q) < 3:
        return None
    a = q - np.roll(q, 1, axis=0)
    b = np.roll(q, -1, axis=0) - q
    cos = np.einsum("ij,ij->i", a, b) / (np.linalg.norm(a, axis=1) * np.linalg.norm(b, axis=1))
    sharp = np.flatnonzero(cos < np.cos(np.radians(CORNER_DEGREES)))
    return int(idx[sharp[0]]) if len(sharp) else None


def _split_at_corners(p: np.ndarray) -> list[np.ndarray]:
    """An open polyline cut at its sharp corners (duplicate points dropped first)."""
    keep = np.concatenate([[True], np.linalg.norm(np.diff(p, axis=0), axis=1) > 0])
    p = p[keep]
    if len(p) <= 2:
        return [p if len(p) == 2 else np.vstack([p, p])]
    d = np.diff(p, axis=0)
    a, b = d[:-1], d[1:]
    cos = np.einsum("ij,ij->i", a, b) / (np.linalg.norm(a, axis=1) * np.linalg.norm(b, axis=1))
    corner = np.flatnonzero(cos < np.cos(np.radians(CORNER_DEGREES))) + 1
    cuts = [0, *corner.tolist(), len(p) - 1]
    return [p[i : j + 1] for i, j in zip(cuts[:-1], cuts[1:])]


@dataclass(frozen=True)
class Arc:
    """A circular arc from angle ``t0`` to ``t1`` [radians] (a full turn is closed)."""

    cx: float
    cy: float
    r: float
    t0: float
    t1: float


def drawing(items) -> tuple[Stroke, ...]:
    """Strokes from plain polylines ``(k, 2)`` and :class:`Arc` items, in their order.

    A polyline whose last point equals its first is closed.  Open polylines
    are split at their sharp corners; the ends that lie on other strokes are
    marked excluded (see the module docstring).
    """
    raw: list[Stroke] = []
    for item in items:
        if isinstance(item, Arc):
            closed = abs(abs(item.t1 - item.t0) - 2 * np.pi) <= 1e-12
            raw.append(Stroke(arc=(item.cx, item.cy, item.r, item.t0, item.t1), closed=closed))
            continue
        p = np.asarray(item, float)
        size = max(float(np.ptp(p, axis=0).max()), 1.0)
        if len(p) >= 4 and np.linalg.norm(p[0] - p[-1]) <= _ON * size:
            corner = _first_corner(p[:-1])
            if corner is None:  # smooth all round: a closed stroke
                raw.append(Stroke(points=tuple(map(tuple, p[:-1])), closed=True))
                continue
            # a closed outline with corners (a square): opened at a corner
            ring = np.roll(p[:-1], -corner, axis=0)
            p = np.vstack([ring, ring[:1]])
        raw.extend(Stroke(points=tuple(map(tuple, piece))) for piece in _split_at_corners(p))
    return _mark_junctions(raw)


def _mark_junctions(strokes: list[Stroke]) -> tuple[Stroke, ...]:
    """Exclude the ends that lie on an earlier stroke or inside a later one."""
    if not strokes:
        return ()
    n = len(strokes)
    ends = np.stack([s.ends for s in strokes]).reshape(-1, 2)  # end 2j, 2j + 1 of stroke j
    tol = _ON * max(float(np.ptp(ends, axis=0).max()), 1.0)
    owner = np.repeat(np.arange(n), 2)
    taken = np.zeros(2 * n, bool)
    for i, other in enumerate(strokes):
        # only the ends inside this stroke's bounding box can lie on it
        box = _box(other)
        near = np.flatnonzero(np.all((ends >= box[0] - tol) & (ends <= box[1] + tol), axis=1) & (owner != i))
        near = near[~taken[near]]
        if not len(near):
            continue
        on = other.distance(ends[near]) <= tol
        if not on.any():
            continue
        near = near[on]
        if other.closed:
            at_end = np.zeros(len(near), bool)
        else:
            e = other.ends
            at_end = np.minimum(np.linalg.norm(ends[near] - e[0], axis=1),
                                np.linalg.norm(ends[near] - e[1], axis=1)) <= tol
        taken[near[(owner[near] > i) | ~at_end]] = True
    out = []
    for j, st in enumerate(strokes):
        if st.closed:
            out.append(st)
            continue
        free = [not taken[2 * j], not taken[2 * j + 1]]
        if np.linalg.norm(ends[2 * j] - ends[2 * j + 1]) <= tol and st.length > 0:
            free[1] = False  # an outline opened at its one corner ends where it starts
        if st.length == 0.0 and not free[0]:
            free[1] = False  # a dot on another stroke adds nothing
        out.append(Stroke(st.points, st.arc, st.closed, free[0], free[1]))
    return tuple(out)


def _box(st: Stroke) -> np.ndarray:
    """``[[xmin, ymin], [xmax, ymax]]`` of a stroke (an arc's whole circle)."""
    if st.arc is not None:
        cx, cy, r, _, _ = st.arc
        return np.array([[cx - r, cy - r], [cx + r, cy + r]])
    p = np.asarray(st.points, float)
    return np.stack([p.min(axis=0), p.max(axis=0)])


def bounds(strokes: tuple[Stroke, ...]) -> np.ndarray:
    """``[[xmin, ymin], [xmax, ymax]]`` of the strokes (arcs sampled every degree or finer)."""
    pts = []
    for st in strokes:
        if st.arc is None:
            pts.append(np.asarray(st.points, float))
        else:
            n = max(2, int(np.degrees(abs(st.arc[4] - st.arc[3]))) + 1)
            pts.append(st.at(np.linspace(0.0, st.length, n)))
    allpts = np.concatenate(pts)
    return np.stack([allpts.min(axis=0), allpts.max(axis=0)])


def extent(strokes: tuple[Stroke, ...]) -> float:
    """The longer side of the strokes' bounding box."""
    return float(np.ptp(bounds(strokes), axis=0).max())


def strokes_shape(strokes: tuple[Stroke, ...], m: int, side: float, separation: float) -> np.ndarray:
    """``m`` robots along the strokes, centred, scaled to ``side`` (see :func:`scaled_shape`).

    The robots are spread so that they need no enlargement where the
    strokes allow it: two robots at least ``separation`` (with its slack)
    apart at the requested size.
    """
    size = extent(strokes)
    gap = separation * SPACING_SLACK * size / side if size > 0 and side > 0 else 0.0
    return scaled_shape(stroke_points(strokes, m, gap), side, separation)
