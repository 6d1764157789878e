"""Robots spread along strokes: allocation per stroke, even spacing by arc
length, crowded pairs resolved, and the shape scaled to its size.

Robots are allocated to the strokes so that the spacing along every stroke
is about the same (:func:`_allocate`), then spread evenly along each
stroke; see :mod:`planner.strokes` for the drawing model.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from .stroke import Stroke

__all__ = ["SPACING_SLACK", "count_at_spacing", "scaled_shape", "stroke_points"]


# Two robots of different strokes closer than this fraction of the spacing
# along the strokes crowd each other (crossing strokes, acute junctions).
_CROWDED = 0.5
# Safety factor on the separation when a shape is enlarged, so that a
# formation is never on the edge of overlapping because of rounding.
SPACING_SLACK = 1.02
_ROUNDS = 24  # spreads at most to make up for crowded robots
_BISECT = 5  # bisection steps on the gap when the wanted one does not fit


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
