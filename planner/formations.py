"""Formations: the paper's letters, a line, a ring and random placements (Algorithm 1).

A letter is a drawing (polylines and circular arcs in a unit box, see
:mod:`planner.strokes`).  Robots are spread evenly along its strokes by arc
length; where two strokes meet, only one of them puts a robot on the
junction.  The shape is then scaled so that its bounding-box side is
``scale * min(W, H)``, enlarged when two robots would come closer than the
separation, rotated about its centre and shifted to a centre that keeps
every robot clear (Algorithm 1: ROTATE, SHIFT; the centre is resampled until
the placement is clear).
"""

from __future__ import annotations

import numpy as np

from .geometry import Environment, greedy_separated
from .problem import ProblemError, describe_obstacle
from .strokes import SPACING_SLACK, Arc, bounds, drawing, scaled_shape, stroke_points

__all__ = [
    "DEFAULT_COUNTS",
    "FORMATIONS",
    "LETTERS",
    "formation_box",
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
    "ring": None,
}
FORMATIONS = tuple(DEFAULT_COUNTS)

_PI = np.pi

#: The named drawings in a unit box: polylines ``[(x, y), ...]`` and arcs.
LETTERS: dict[str, tuple] = {
    "line": (((0.0, 0.5), (1.0, 0.5)),),
    "A": (((0.0, 0.0), (0.5, 1.0), (1.0, 0.0)), ((0.25, 0.5), (0.75, 0.5))),
    "M": (((0.0, 0.0), (0.0, 1.0), (0.5, 0.45), (1.0, 1.0), (1.0, 0.0)),),
    "N": (((0.0, 0.0), (0.0, 1.0), (0.8, 0.0), (0.8, 1.0)),),
    # An arc open to the right, from 50 degrees round to 310 degrees.
    "C": (Arc(0.5, 0.5, 0.5, np.radians(50), np.radians(310)),),
    # Lambda: the long stroke from the top left to the bottom right, and
    # the short leg from its middle down to the bottom left.
    "lambda": (((0.15, 1.0), (0.85, 0.0)), ((0.5, 0.5), (0.0, 0.0))),
    # Phi: a closed ring crossed by a vertical stem that sticks out above
    # and below; the stem's pieces end on the ring.
    "phi": (
        Arc(0.5, 0.5, 0.3, _PI / 2, _PI / 2 + 2 * _PI),
        ((0.5, 0.8), (0.5, 1.0)),
        ((0.5, 0.2), (0.5, 0.0)),
        ((0.5, 0.2), (0.5, 0.8)),
    ),
    # A circle, its robots evenly spaced from half a step past the top.
    "ring": (Arc(0.5, 0.5, 0.5, _PI / 2, _PI / 2 + 2 * _PI),),
}
_STROKES = {name: drawing(items) for name, items in LETTERS.items()}


def formation_box(name: str) -> tuple[float, float]:
    """Width and height of a named formation's bounding box, its longer side 1 (at rotation 0)."""
    if name not in DEFAULT_COUNTS:
        raise ValueError(f"unknown formation {name!r}")
    if name == "random":
        return 1.0, 1.0
    w, h = np.ptp(bounds(_STROKES[name]), axis=0)
    return float(w / max(w, h)), float(h / max(w, h))


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
        pts = _random_points(m, side, separation * SPACING_SLACK, rng)
        return pts - (pts.max(axis=0) + pts.min(axis=0)) / 2
    return scaled_shape(stroke_points(_STROKES[name], m), side, separation)


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
        f"(no clear centre in {tries} random tries); lower the scale, move obstacles, "
        f"or use formation: scatter to spread the robots over the free space",
    )
