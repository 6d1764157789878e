"""Worlds of the held-out benchmark (:mod:`bench.heldout`), from a generator of their own.

Every instance draws everything from one generator, ``default_rng([7919, family, m, seed])``
(``family`` 1 = line into letter, 2 = random to random, 3 = door, 4 = map; the door's
width and the map's name enter the seed sequence too), so no instance coincides with
one of :mod:`bench.frontier` or :mod:`bench.maps` (those seed ``default_rng(seed)``).
Robots have radius 1 and margin 0.1 (separation 2.1, clearance 1.1).

* ``letter``: a straight line of ``m`` robots at a drawn angle (at least 10 degrees
  from the axes) and a drawn position, into a glyph drawn from every shape the
  planner names except the line (A, C, M, N, lambda, phi, ring), scaled to a drawn
  0.2 to 0.45 of the shorter side at a drawn rotation and position; the workspace
  aspect is drawn in 1:1 to 3:1 (either way round), 2 to 6 random convex obstacles.
* ``random``: start and target uniform in the main free room of a workspace of drawn
  aspect (1:1 to 3:1) and robot coverage (5 to 14 %), with 0 to 12 convex obstacles
  of drawn diameter (4 to 22 % of the shorter side).
* ``door``: one wall of drawn thickness (1 to 4) at a drawn position (30 to 70 % of
  the width) with one door of width ``w`` at a drawn height (widened by the few ulps, if
  any, that a robot centre needs to be clear on its middle line in floating point);
  robots start on the left of it and end on the right.
* ``map``: a MovingAI map as in :func:`bench.maps.map_problem` (cell 2.4), starts and
  targets two independent draws of distinct free cells of its largest 4-connected
  free region (no ``.scen`` file).
"""

from __future__ import annotations

import math
import zlib

import numpy as np

from planner import Polygon, Problem, ProblemError
from planner.formations import formation_shape, place_formation
from planner.geometry import greedy_separated

__all__ = ["GLYPHS", "RADIUS", "MARGIN", "door_problem", "letter_problem", "letter_world", "map_problem", "random_problem",
           "world_rng"]

RADIUS = 1.0
MARGIN = 0.1
SEP = 2 * RADIUS + MARGIN
GLYPHS = ("A", "C", "M", "N", "lambda", "phi", "ring")
_FAMILY = {"letter": 1, "random": 2, "door": 3, "map": 4}


def world_rng(family: str, m: int, seed: int, extra: str = "") -> np.random.Generator:
    """The one generator of an instance (``extra``: the door width or the map name)."""
    key = [7919, _FAMILY[family], int(m), int(seed)]
    if extra:
        key.append(zlib.crc32(extra.encode()))
    return np.random.default_rng(key)


def _shell(w: float, h: float, obs) -> Problem:
    return Problem(w, h, tuple(obs), RADIUS, MARGIN, np.zeros((0, 2)), np.zeros((0, 2)))


def _aspect_box(rng, area: float) -> tuple[float, float]:
    """Width and height of a box of ``area`` with aspect drawn in 1:1 to 3:1, either way round."""
    a = float(rng.uniform(1.0, 3.0))
    long_, short = math.sqrt(area * a), math.sqrt(area / a)
    return (long_, short) if rng.random() < 0.5 else (short, long_)


def _convex(rng, diameter: float, w: float, h: float) -> Polygon:
    """A convex polygon: 3 to 9 corners at sorted drawn angles on a circle, inside the box."""
    r = diameter / 2
    while True:
        k = int(rng.integers(3, 10))
        ang = np.sort(rng.uniform(0, 2 * np.pi, k))
        c = rng.uniform([r, r], [w - r, h - r])
        v = c + r * np.stack([np.cos(ang), np.sin(ang)], axis=1)
        if 0.5 * abs(float(v[:, 0] @ np.roll(v[:, 1], -1) - np.roll(v[:, 0], -1) @ v[:, 1])) >= 0.1 * diameter**2:
            return Polygon(v)


def _main_room(shell: Problem):
    """A test of points inside the largest component of the clear free space (shapely)."""
    import shapely
    from shapely.geometry import box

    c = shell.clearance
    free = box(c, c, shell.width - c, shell.height - c)
    if shell.obstacles:
        free = free.difference(shapely.union_all([shapely.Polygon(o.vertices).buffer(c) for o in shell.obstacles]))
    main = max(getattr(free, "geoms", [free]), key=lambda g: g.area)
    shapely.prepare(main)
    return lambda p: shapely.contains_xy(main, p[:, 0], p[:, 1])


def _points(shell: Problem, m: int, rng, lo, hi, inside=None, batches: int = 300) -> np.ndarray:
    """``m`` clear, separated points uniform in the box ``[lo, hi]`` (and ``inside``)."""
    pts = np.zeros((0, 2))
    for _ in range(batches):
        cand = rng.uniform(lo, hi, size=(max(512, 6 * m), 2))
        cand = cand[shell.env.points_clear(cand, shell.clearance)]
        if inside is not None:
            cand = cand[inside(cand)]
        pts = np.vstack([pts, cand[greedy_separated(cand, SEP, pts, m - len(pts))]])
        if len(pts) == m:
            return pts
    raise ValueError(f"cannot place {m} robots")


def letter_problem(m: int, seed: int) -> Problem:
    """A line of ``m`` robots into a drawn glyph (see the module)."""
    return letter_world(m, seed)[0]


def letter_world(m: int, seed: int) -> tuple[Problem, str]:
    """:func:`letter_problem` and the name of its glyph."""
    rng = world_rng("letter", m, seed)
    line = formation_shape("line", m, 0.0, SEP, rng)
    length = float(np.ptp(line[:, 0])) + 2 * SEP
    glyph = GLYPHS[int(rng.integers(len(GLYPHS)))]
    w, h = _aspect_box(rng, length**2 * float(rng.uniform(0.45, 0.9)))
    for _ in range(200):
        # the line must fit at its angle: grow the box until it does
        deg = float(rng.uniform(10.0, 80.0)) * (1 if rng.random() < 0.5 else -1) + (180.0 if rng.random() < 0.5 else 0.0)
        th = math.radians(deg)
        need = np.array([length * abs(math.cos(th)), length * abs(math.sin(th))]) + 2 * (RADIUS + MARGIN)
        grow = max(1.0, need[0] / w, need[1] / h)
        w, h = w * grow, h * grow
        short = min(w, h)
        obs = [_convex(rng, float(rng.uniform(0.04, 0.16)) * short, w, h) for _ in range(int(rng.integers(2, 7)))]
        sh = _shell(w, h, obs)
        try:
            start = place_formation(line, sh.env, sh.clearance, rotation=deg, center=None, rng=rng, field="start")
            shape = formation_shape(glyph, m, float(rng.uniform(0.2, 0.45)) * short, SEP, rng)
            target = place_formation(shape, sh.env, sh.clearance, rotation=None, center=None, rng=rng,
                                     field="target")
        except ProblemError:
            continue
        return Problem(w, h, tuple(obs), RADIUS, MARGIN, start, target).validate(), glyph
    raise ValueError(f"letter m={m} seed={seed}: no placement")


def random_problem(m: int, seed: int) -> Problem:
    """Random start to random target among drawn obstacles (see the module)."""
    rng = world_rng("random", m, seed)
    for _ in range(50):
        w, h = _aspect_box(rng, m * math.pi * RADIUS**2 / float(rng.uniform(0.05, 0.14)))
        short = min(w, h)
        obs = [_convex(rng, float(rng.uniform(0.04, 0.22)) * short, w, h) for _ in range(int(rng.integers(0, 13)))]
        sh = _shell(w, h, obs)
        inside = _main_room(sh)
        c = sh.clearance
        try:
            start = _points(sh, m, rng, [c, c], [w - c, h - c], inside, batches=60)
            target = _points(sh, m, rng, [c, c], [w - c, h - c], inside, batches=60)
        except ValueError:
            continue
        return Problem(w, h, tuple(obs), RADIUS, MARGIN, start, target).validate()
    raise ValueError(f"random m={m} seed={seed}: no world holds the robots")


def door_walls(height: float, x0: float, x1: float, y_lo: float, width: float) -> tuple[tuple, float]:
    """The two wall pieces ``x0..x1`` with a door from ``y_lo`` at least ``width`` wide (in floats)."""
    y_hi = y_lo + width
    while y_hi - y_lo < width:  # rounding must not narrow the door below the width asked for
        y_hi = float(np.nextafter(y_hi, math.inf))
    pieces = []
    if y_lo > 0:
        pieces.append(Polygon(np.array([[x0, 0.0], [x1, 0.0], [x1, y_lo], [x0, y_lo]])))
    if y_hi < height:
        pieces.append(Polygon(np.array([[x0, y_hi], [x1, y_hi], [x1, height], [x0, height]])))
    return tuple(pieces), y_hi - y_lo


def _door_shell(w: float, h: float, x0: float, x1: float, y_lo: float, width: float) -> Problem:
    """The door world, its door widened by as few ulps as it takes for a robot centre on its
    middle line to be clear in floating point (``width`` itself can round to a door that none passes)."""
    xs = np.linspace(x0, x1, 9)
    for _ in range(256):
        obs, got = door_walls(h, x0, x1, y_lo, width)
        sh = _shell(w, h, obs)
        mid = y_lo + got / 2
        for y in (mid, float(np.nextafter(mid, -math.inf)), float(np.nextafter(mid, math.inf))):
            if sh.env.point_clearance(np.stack([xs, np.full(len(xs), y)], axis=1)).min() >= sh.clearance:
                return sh
        width = float(np.nextafter(got, math.inf))
    raise ValueError(f"no door {width:g} wide lets a robot through")


def door_problem(width: float, m: int, seed: int) -> Problem:
    """``m`` robots from the left of a wall with one door ``width`` wide to its right (see the module)."""
    rng = world_rng("door", m, seed, f"{width:.6g}")
    frac = float(rng.uniform(0.3, 0.7))
    thick = float(rng.uniform(1.0, 4.0))
    cover = float(rng.uniform(0.06, 0.12))
    aspect = float(rng.uniform(1.0, 2.5))
    # the smaller side holds the m robots at the drawn coverage
    h = math.sqrt(m * math.pi * RADIUS**2 / (cover * aspect * min(frac, 1 - frac)))
    w = aspect * h
    x0, x1 = frac * w - thick / 2, frac * w + thick / 2
    y_lo = float(rng.uniform(0.5, h - width - 0.5))
    sh = _door_shell(w, h, x0, x1, y_lo, width)
    c = sh.clearance
    start = _points(sh, m, rng, [c, c], [x0 - c, h - c])
    target = _points(sh, m, rng, [x1 + c, c], [w - c, h - c])
    return Problem(w, h, sh.obstacles, RADIUS, MARGIN, start, target).validate()


def _largest_region(blocked: np.ndarray) -> np.ndarray:
    from scipy import ndimage

    labels, _ = ndimage.label(~blocked)  # 4-connected
    big = int(np.argmax(np.bincount(labels.ravel())[1:])) + 1
    return np.argwhere(labels == big)


def map_problem(name: str, m: int, seed: int) -> Problem:
    """The map world of :mod:`bench.maps` with ``m`` robots on cells drawn here (see the module)."""
    from .maps import CELL, load_map

    rng = world_rng("map", m, seed, name)
    blocked, obstacles = load_map(name)
    rows, cols = blocked.shape
    region = _largest_region(blocked)
    if len(region) < m:
        raise ValueError(f"{name}: {len(region)} free cells in the largest region, fewer than {m}")

    def centres(cells):
        return np.stack([(cells[:, 1] + 0.5) * CELL, (rows - cells[:, 0] - 0.5) * CELL], axis=1)

    start = centres(region[rng.choice(len(region), m, replace=False)].astype(float))
    target = centres(region[rng.choice(len(region), m, replace=False)].astype(float))
    return Problem(cols * CELL, rows * CELL, tuple(obstacles), RADIUS, MARGIN, start, target).validate()
