"""Strokes: robots spread along polylines (and circular arcs) by arc length.

A drawing is a tuple of strokes.  A stroke is an open polyline, a closed
polyline (its last point equals its first; one with sharp corners is opened
at its first corner), or a circular arc.  Robots are allocated to the
strokes so that the spacing along every stroke is about the same
(:func:`_allocate`), then spread evenly along each stroke.

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
from functools import cached_property

import numpy as np
from scipy.spatial import cKDTree

from .geometry import point_segment_distance

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

# Two robots of different strokes closer than this fraction of the spacing
# along the strokes crowd each other (crossing strokes, acute junctions).
_CROWDED = 0.5
# Safety factor on the separation when a shape is enlarged, so that a
# formation is never on the edge of overlapping because of rounding.
SPACING_SLACK = 1.02
_ROUNDS = 24  # spreads at most to make up for crowded robots
_BISECT = 5  # bisection steps on the gap when the wanted one does not fit
_ON = 1e-9  # relative tolerance of "lies on" tests (of the drawing's size)


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


def _allocate(strokes: tuple[Stroke, ...], m: int, gap: float = 0.0) -> tuple[list[int], float]:
    """Robots per stroke so that the spacing along every stroke is about equal.

    With spacing ``d`` an open stroke of length ``l`` holds ``l/d + 1 - e``
    robots (``e`` excluded ends) and a closed one ``l/d``; ``d`` is found by
    bisection so that the counts sum to ``m``, then rounded by largest
    remainder.  With ``gap > 0`` no stroke gets so many robots that they
    would come closer than ``gap`` along it (the caller checks that the caps
    leave room for ``m``).  Returns the counts and ``d``.
    """
    lengths = np.array([s.length for s in strokes])
    base = np.array([0.0 if s.closed else 1.0 - s.excluded_ends for s in strokes])
    cap = np.full(len(strokes), np.inf)
    if gap > 0:
        cap = np.floor(np.maximum(lengths / gap + base, 0.0) + 1e-9)

    def counts(d):
        return np.minimum(np.maximum(lengths / d + base, 0.0), cap)

    lo, hi = 1e-9, lengths.sum() * 10 + 1.0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if counts(mid).sum() > m:
            lo = mid
        else:
            hi = mid
    c = counts(hi)
    k = np.floor(c + 1e-9).astype(int)
    rest = m - int(k.sum())
    # Largest remainder first, but strokes with equal remainders (mirror
    # images such as A's legs or N's uprights) get a robot all together or
    # not at all, so the letter stays symmetric; a leftover that no group
    # can take whole goes to the first strokes of the best group.
    remainder = np.round(c - k, 9)
    # A stroke that would round to a robot but has none yet comes first
    # (an A's crossbar before a second robot on each leg): every stroke of
    # the drawing that can show, shows, once there are two robots per stroke
    # (fewer only sketch the letter: an M of 4 keeps its feet).
    empty = (k == 0) & (c >= 0.5) & (k < cap) & (m >= 2 * len(strokes))
    for n in sorted(np.flatnonzero(empty), key=lambda n: -remainder[n]):
        if rest > 0:
            k[n] += 1
            rest -= 1
            remainder[n] = -1.0
    room = k < cap
    groups = [np.flatnonzero((remainder == r) & room) for r in sorted(set(remainder[room].tolist()), reverse=True)]
    for g in groups:
        if 0 < len(g) <= rest:
            k[g] += 1
            rest -= len(g)
    for g in groups:
        take = g[(k[g] < cap[g])][:rest]
        k[take] += 1
        rest -= len(take)
    return [int(v) for v in k], float(hi)


def _capacity(strokes: tuple[Stroke, ...], gap: float) -> int:
    """The most robots the strokes hold with neighbours along a stroke at least ``gap`` apart."""
    lengths = np.array([s.length for s in strokes])
    base = np.array([0.0 if s.closed else 1.0 - s.excluded_ends for s in strokes])
    return int(np.floor(np.maximum(lengths / gap + base, 0.0) + 1e-9).sum())


def count_at_spacing(strokes: tuple[Stroke, ...], spacing: float) -> int:
    """How many robots the strokes hold at about ``spacing`` apart along them (the inverse of the allocation)."""
    if not spacing > 0:
        raise ValueError(f"spacing must be > 0, got {spacing}")
    lengths = np.array([s.length for s in strokes])
    base = np.array([0.0 if s.closed else 1.0 - s.excluded_ends for s in strokes])
    return int(round(float(np.maximum(lengths / spacing + base, 0.0).sum())))


def _spread(strokes: tuple[Stroke, ...], m: int, gap: float = 0.0) -> tuple[np.ndarray, np.ndarray, float]:
    """``m`` points spread along the strokes, the stroke of each, and the spacing."""
    alloc, d = _allocate(strokes, m, gap)
    out, owner = [], []
    for n, (stroke, k) in enumerate(zip(strokes, alloc)):
        if k <= 0:
            continue
        ell = stroke.length
        if stroke.closed:
            # Half a step of phase keeps ring robots off the ring's start
            # point, where another stroke may end (phi's stem).
            s = (np.arange(k) + 0.5) * ell / k
        else:
            e = stroke.excluded_ends
            if k == 1 and e == 0:
                s = np.array([ell / 2])
            else:
                step = ell / (k - 1 + e)
                s = (step if not stroke.start_free else 0.0) + np.arange(k) * step
        out.append(stroke.at(s))
        owner.append(np.full(k, n))
    return np.concatenate(out), np.concatenate(owner), d


def _crowded(pts: np.ndarray, owner: np.ndarray, limit: float) -> np.ndarray:
    """Indices of robots to drop so that no two of different strokes are closer than ``limit``.

    Robots are kept in order (earlier strokes win): a greedy pick.
    """
    if limit <= 0 or len(pts) < 2:
        return np.zeros(0, int)
    pairs = cKDTree(pts).query_pairs(limit, output_type="ndarray")
    pairs = pairs[owner[pairs[:, 0]] != owner[pairs[:, 1]]]
    if not len(pairs):
        return np.zeros(0, int)
    pairs = np.sort(pairs, axis=1)
    pairs = pairs[np.lexsort((pairs[:, 1], pairs[:, 0]))]
    first = np.searchsorted(pairs[:, 0], np.arange(len(pts) + 1))
    dropped = np.zeros(len(pts), bool)
    for i in np.unique(pairs[:, 0]):
        if not dropped[i]:
            dropped[pairs[first[i] : first[i + 1], 1]] = True
    return np.flatnonzero(dropped)


def _attempt(strokes: tuple[Stroke, ...], m: int, gap: float) -> np.ndarray | None:
    """Spread robots, drop the crowded ones, spread more in their place; None if it does not settle."""
    n = m
    for _ in range(_ROUNDS):
        if n > 2 * m + 64 or (gap and _capacity(strokes, gap) < n):
            return None
        pts, owner, d = _spread(strokes, n, gap)
        drop = _crowded(pts, owner, max(_CROWDED * d, gap))
        keep = pts[np.setdiff1d(np.arange(len(pts)), drop)]
        if len(keep) >= m:
            # an overshoot loses its most crowded robots one by one
            while len(keep) > m:
                dist, _ = cKDTree(keep).query(keep, k=2)
                keep = np.delete(keep, int(np.argmin(dist[:, 1])), axis=0)
            return keep
        n += m - len(keep)
    return None


def stroke_points(strokes: tuple[Stroke, ...], m: int, gap: float = 0.0) -> np.ndarray:
    """``(m, 2)`` points along the strokes, in the strokes' own coordinates.

    Robots of different strokes that would come closer than half the
    spacing along the strokes (where strokes cross or meet at an acute
    angle) are resolved: such pairs lose one robot and the drawing is
    spread again with as many robots more, until exactly ``m`` remain.

    ``gap`` (strokes' units, optional): the distance the caller needs
    between any two robots.  No stroke then gets so many robots that they
    would come closer than that along it, and crowded pairs closer than
    ``gap`` are resolved too, so that the shape need not be enlarged.  When
    the strokes cannot hold ``m`` robots that far apart, the largest gap
    that works is found by bisection.
    """
    if m < 1:
        raise ValueError(f"m must be >= 1, got {m}")
    if not strokes or sum(s.length for s in strokes) <= 0:
        raise ValueError("the drawing has no length")
    if gap > 0:
        pts = _attempt(strokes, m, gap)
        if pts is not None:
            return pts
    pts = _attempt(strokes, m, 0.0)
    if pts is None:
        return _greedy(strokes, m)
    if gap > 0:
        lo, hi = 0.0, float(gap)
        for _ in range(_BISECT):
            mid = 0.5 * (lo + hi)
            better = _attempt(strokes, m, mid)
            if better is None:
                hi = mid
            else:
                lo, pts = mid, better
    return pts


def _greedy(strokes: tuple[Stroke, ...], m: int) -> np.ndarray:
    """Strokes that cross everywhere: ``m`` of many points along them, as far apart as greedy picking allows.

    Candidates are spread along the strokes at a fine spacing; the largest
    spacing whose greedy pick (in stroke order) keeps ``m`` of them is found
    by bisection, and the surplus loses its most crowded points.
    """
    cand, _, _ = _spread(strokes, 3 * m + 16)
    cand = np.unique(cand, axis=0)
    if len(cand) < m:
        raise ValueError(f"the strokes hold fewer than {m} distinct robot positions")
    # m points on curves of total length L are at most about L / (m - 1)
    # apart, and m points s apart need a box of side about s (sqrt(m) - 1)
    total = sum(s.length for s in strokes)
    size = float(np.ptp(cand, axis=0).max())
    lo, hi = 0.0, min(size, 2.0 * total / max(m - 1, 1), 2.0 * size / max(np.sqrt(m) - 1.0, 1.0))
    best = cand
    everyone = np.arange(len(cand))
    for _ in range(30):
        mid = 0.5 * (lo + hi)
        pick = np.delete(cand, _crowded(cand, everyone, mid), axis=0)
        if len(pick) >= m:
            lo, best = mid, pick
        else:
            hi = mid
    while len(best) > m:
        dist, _ = cKDTree(best).query(best, k=2)
        best = np.delete(best, int(np.argmin(dist[:, 1])), axis=0)
    return best


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


def scaled_shape(unit: np.ndarray, side: float, separation: float) -> np.ndarray:
    """Points centred on the origin with a bounding-box side of ``side``.

    The side is enlarged when two points would come closer than
    ``separation`` (times a 2 % slack).  ``unit`` is in any coordinates.
    """
    unit = np.asarray(unit, float)
    unit = unit - (unit.max(axis=0) + unit.min(axis=0)) / 2
    extent = max(float(np.ptp(unit, axis=0).max()), 1e-12)
    unit = unit / extent
    if len(unit) > 1:
        dmin = float(cKDTree(unit).query(unit, k=2)[0][:, 1].min())
        side = max(side, separation * SPACING_SLACK / max(dmin, 1e-12))
    return unit * side
