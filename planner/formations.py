"""Formations: the paper's letters, a line and random placements (Algorithm 1).

A letter is a set of strokes (polylines and circular arcs) in a unit box.
Robots are spread evenly along the strokes by arc length; where two strokes
meet, only one of them puts a robot on the junction.  The shape is then
scaled so that its bounding-box side is ``scale * min(W, H)``, enlarged when
two robots would come closer than the separation, rotated about its centre
and shifted to a centre that keeps every robot clear (Algorithm 1: ROTATE,
SHIFT; the centre is resampled until the placement is clear).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from .geometry import Environment, greedy_separated
from .problem import ProblemError, describe_obstacle

__all__ = [
    "DEFAULT_COUNTS",
    "FORMATIONS",
    "formation_shape",
    "place_formation",
]

#: Table I of the paper; ``None`` means the formation needs an explicit count.
DEFAULT_COUNTS: dict[str, int | None] = {
    "line": None,
    "A": 10,
    "C": 7,
    "M": 11,
    "N": 10,
    "lambda": 7,
    "phi": 11,
    "random": None,
}
FORMATIONS = tuple(DEFAULT_COUNTS)

# Safety factor on the separation when a shape is enlarged, so that a
# formation is never on the edge of overlapping because of rounding.
_SPACING_SLACK = 1.02


@dataclass(frozen=True)
class _Stroke:
    """A polyline (``arc is None``) or an arc ``(cx, cy, r, theta0, theta1)``.

    ``start_free``/``end_free`` say whether a robot may sit on the first or
    last point (False where the point lies on another stroke); a closed
    stroke has no ends.
    """

    points: tuple = ()
    arc: tuple | None = None
    closed: bool = False
    start_free: bool = True
    end_free: bool = True

    @property
    def length(self) -> float:
        if self.arc is not None:
            _, _, r, t0, t1 = self.arc
            return abs(t1 - t0) * r
        p = np.asarray(self.points, float)
        if self.closed:
            p = np.vstack([p, p[:1]])
        return float(np.linalg.norm(np.diff(p, axis=0), axis=1).sum())

    def at(self, s: np.ndarray) -> np.ndarray:
        """Points at arc lengths ``s`` from the stroke's start."""
        s = np.asarray(s, float)
        if self.arc is not None:
            cx, cy, r, t0, t1 = self.arc
            th = t0 + np.sign(t1 - t0) * s / r
            return np.stack([cx + r * np.cos(th), cy + r * np.sin(th)], axis=-1)
        p = np.asarray(self.points, float)
        if self.closed:
            p = np.vstack([p, p[:1]])
        seg = np.linalg.norm(np.diff(p, axis=0), axis=1)
        cum = np.concatenate([[0.0], np.cumsum(seg)])
        k = np.clip(np.searchsorted(cum, s, side="right") - 1, 0, len(seg) - 1)
        u = (s - cum[k]) / np.where(seg[k] > 0, seg[k], 1.0)
        return p[k] + u[:, None] * (p[k + 1] - p[k])

    @property
    def excluded_ends(self) -> int:
        return 0 if self.closed else int(not self.start_free) + int(not self.end_free)


def _letters() -> dict[str, tuple[_Stroke, ...]]:
    pi = np.pi
    return {
        "line": (_Stroke(points=((0.0, 0.5), (1.0, 0.5))),),
        "A": (
            _Stroke(points=((0.0, 0.0), (0.5, 1.0), (1.0, 0.0))),
            _Stroke(points=((0.25, 0.5), (0.75, 0.5)), start_free=False, end_free=False),
        ),
        "M": (
            _Stroke(points=((0.0, 0.0), (0.0, 1.0), (0.5, 0.45), (1.0, 1.0), (1.0, 0.0))),
        ),
        "N": (_Stroke(points=((0.0, 0.0), (0.0, 1.0), (0.8, 0.0), (0.8, 1.0))),),
        # An arc open to the right, from 50 degrees round to 310 degrees.
        "C": (_Stroke(arc=(0.5, 0.5, 0.5, np.radians(50), np.radians(310))),),
        # Lambda: the long stroke from the top left to the bottom right, and
        # the short leg from its middle down to the bottom left.
        "lambda": (
            _Stroke(points=((0.15, 1.0), (0.85, 0.0))),
            _Stroke(points=((0.5, 0.5), (0.0, 0.0)), start_free=False),
        ),
        # Phi: a closed ring crossed by a vertical stem that sticks out above
        # and below; the stem's pieces end on the ring.
        "phi": (
            _Stroke(arc=(0.5, 0.5, 0.3, pi / 2, pi / 2 + 2 * pi), closed=True),
            _Stroke(points=((0.5, 0.8), (0.5, 1.0)), start_free=False),
            _Stroke(points=((0.5, 0.2), (0.5, 0.0)), start_free=False),
            _Stroke(points=((0.5, 0.2), (0.5, 0.8)), start_free=False, end_free=False),
        ),
    }


def _split_at_corners(strokes) -> tuple[_Stroke, ...]:
    """Split open polylines into straight pieces that share their corners.

    Every corner then holds a robot (it is the free end of the piece before
    it and an excluded start of the piece after it), so robots on the two
    arms of a sharp corner never crowd each other.
    """
    out = []
    for st in strokes:
        if st.arc is not None or st.closed or len(st.points) <= 2:
            out.append(st)
            continue
        pts = st.points
        last = len(pts) - 2
        for i in range(len(pts) - 1):
            out.append(
                _Stroke(
                    points=(pts[i], pts[i + 1]),
                    start_free=st.start_free if i == 0 else False,
                    end_free=st.end_free if i == last else True,
                )
            )
    return tuple(out)


_LETTERS = {name: _split_at_corners(strokes) for name, strokes in _letters().items()}


def _allocate(strokes: tuple[_Stroke, ...], m: int) -> list[int]:
    """Robots per stroke so that the spacing along every stroke is about equal.

    With spacing ``d`` an open stroke of length ``l`` holds ``l/d + 1 - e``
    robots (``e`` excluded ends) and a closed one ``l/d``; ``d`` is found by
    bisection so that the counts sum to ``m``, then rounded by largest
    remainder.
    """
    lengths = np.array([s.length for s in strokes])
    base = np.array([0.0 if s.closed else 1.0 - s.excluded_ends for s in strokes])

    def counts(d):
        return np.maximum(lengths / d + base, 0.0)

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
    groups = [np.flatnonzero(remainder == r) for r in sorted(set(remainder.tolist()), reverse=True)]
    for g in groups:
        if 0 < len(g) <= rest:
            k[g] += 1
            rest -= len(g)
    for g in groups:
        take = g[:rest]
        k[take] += 1
        rest -= len(take)
    return [int(v) for v in k]


def _letter_unit_points(name: str, m: int) -> np.ndarray:
    strokes = _LETTERS[name]
    alloc = _allocate(strokes, m)
    out = []
    for stroke, k in zip(strokes, alloc):
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
    pts = np.concatenate(out)
    return pts


def _random_points(m: int, side: float, separation: float, rng: np.random.Generator):
    """``m`` separated points uniform in a square of the given side (grown if crowded)."""
    side = max(side, separation)
    while True:
        pts = np.empty((0, 2))
        for _ in range(50):
            cand = rng.uniform(-side / 2, side / 2, size=(4 * m, 2))
            pts = np.vstack([pts, cand[greedy_separated(cand, separation, pts, m - len(pts))]])
            if len(pts) == m:
                return pts
        side *= 1.15


def formation_shape(
    name: str,
    m: int,
    side: float,
    separation: float,
    rng: np.random.Generator,
) -> np.ndarray:
    """The formation's ``(m, 2)`` points centred on the origin, before rotation.

    ``side`` is the wanted bounding-box side; it is enlarged when robots
    would come closer than ``separation`` (times a 2 % slack).
    """
    if name not in DEFAULT_COUNTS:
        raise ValueError(f"unknown formation {name!r}")
    if m < 2:
        raise ValueError("a formation needs at least 2 robots")
    if name == "random":
        pts = _random_points(m, side, separation * _SPACING_SLACK, rng)
        return pts - (pts.max(axis=0) + pts.min(axis=0)) / 2
    unit = _letter_unit_points(name, m)
    unit = unit - (unit.max(axis=0) + unit.min(axis=0)) / 2
    extent = max(float(np.ptp(unit, axis=0).max()), 1e-12)
    unit = unit / extent
    dmin = float(cKDTree(unit).query(unit, k=2)[0][:, 1].min())
    side = max(side, separation * _SPACING_SLACK / dmin)
    return unit * side


def _rotate(points: np.ndarray, degrees: float) -> np.ndarray:
    th = np.radians(degrees)
    c, s = np.cos(th), np.sin(th)
    return points @ np.array([[c, s], [-s, c]])


def place_formation(
    shape: np.ndarray,
    env: Environment,
    clearance: float,
    *,
    rotation: float | None,
    center: tuple[float, float] | None,
    rng: np.random.Generator,
    field: str,
    tries: int = 4096,
) -> np.ndarray:
    """Rotate ``shape`` (degrees; ``None`` = uniform in [-180, 180)) and shift it.

    With ``center=None`` the centre is drawn uniformly among the positions
    that keep the whole formation inside the walls and resampled until every
    robot is clear of the obstacles; a random rotation is redrawn too when
    no centre works for it.  Raises :class:`ProblemError` naming ``field``
    when the formation cannot fit.
    """
    shape = np.asarray(shape, float)
    if center is not None:
        rot = float(rng.uniform(-180.0, 180.0)) if rotation is None else rotation
        placed = _rotate(shape, rot) + np.asarray(center, float)
        clear, who = env.point_clearance_detail(placed)
        bad = np.flatnonzero(clear < clearance - 1e-9)
        if len(bad):
            i = int(bad[0])
            raise ProblemError(
                f"{field}.center",
                f"robot {i} at ({placed[i, 0]:.3g}, {placed[i, 1]:.3g}) hits "
                f"{describe_obstacle(int(who[i]))}; move the centre or shrink the scale",
            )
        return placed
    batch = 256
    rotations = 16 if rotation is None else 1
    fitted = False
    for _ in range(rotations):
        rot = float(rng.uniform(-180.0, 180.0)) if rotation is None else rotation
        pts = _rotate(shape, rot)
        lo = -pts.min(axis=0) + clearance
        hi = np.array([env.width, env.height]) - pts.max(axis=0) - clearance
        if np.any(hi < lo):
            continue
        fitted = True
        for _ in range(max(1, tries // (batch * rotations))):
            centers = rng.uniform(lo, hi, size=(batch, 2))
            cand = centers[:, None, :] + pts[None]  # (batch, m, 2)
            clear = env.point_clearance(cand.reshape(-1, 2)).reshape(batch, -1)
            ok = np.flatnonzero((clear >= clearance).all(axis=1))
            if len(ok):
                return cand[ok[0]]
    if not fitted:
        size = np.ptp(_rotate(shape, 0.0 if rotation is None else rotation), axis=0) + 2 * clearance
        turned = " at any of 16 random rotations" if rotation is None else ""
        raise ProblemError(
            field,
            f"formation needs {size[0]:.3g} x {size[1]:.3g} with clearance and does not fit "
            f"the {env.width:g} x {env.height:g} workspace{turned}; lower the scale or robots.count",
        )
    raise ProblemError(
        field,
        f"formation does not fit the workspace clear of the obstacles "
        f"(no clear centre in {tries} random tries); lower the scale or move obstacles",
    )
