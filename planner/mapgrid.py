"""The cell grid of a map: the grid the grid stage (:mod:`planner.gridstage`) routes on
when the starts or targets lie off every grid.

A map's obstacles are rectangles on its cell lines (:func:`sim.scenario.maps.cover`):
:func:`map_grid` reads the cell from them, and the grid is the cell centres every
``mult`` cells (``mult`` cells make a separation), or, on a fine occupancy grid,
uneven lines through its doorways (:class:`Lines`, :func:`door_lines`).
"""

from __future__ import annotations

import math

import numpy as np

from .grid import Lattice, _in_rectangles, grid_graph
from .problem import Problem

__all__ = ["Lines", "build_grid", "detect_grid", "door_lines", "find_grid", "map_cell", "map_grid", "robot_cells"]

_TOL = 1e-9
_MAX_VERTICES = 1_100_000  # grid points the grid stage builds at most


def map_cell(problem: Problem) -> tuple[np.ndarray, float] | None:
    """``(origin, s)``: the cell lines ``origin + s * integers`` on which every side of a
    map's rectangles lies (see :func:`map_grid`), or ``None`` when the obstacles are not
    a map of cells."""
    obs = problem.obstacles
    rects = []
    for o in obs:
        v = getattr(o, "vertices", None)
        if v is None or len(v) != 4:
            continue
        xs, ys = np.unique(v[:, 0]), np.unique(v[:, 1])
        if len(xs) == 2 and len(ys) == 2:
            rects.append((xs, ys))
    if len(rects) < 4 or len(rects) < 0.9 * len(obs):
        return None
    tol = _TOL * max(problem.width, problem.height, 1.0)
    coords = [np.unique(np.concatenate([r[axis] for r in rects])) for axis in range(2)]
    gaps = [d[d > tol].min() for d in (np.diff(u) for u in coords) if (d > tol).any()]
    if not gaps:
        return None
    base = min(gaps)
    origin = np.array([coords[0][0], coords[1][0]])
    for k in range(1, 5):
        s = base / k
        if all(np.abs(u - o - s * np.round((u - o) / s)).max() <= tol for u, o in zip(coords, origin)):
            break
    else:
        return None
    return origin, s


def robot_cells(problem: Problem) -> bool:
    """Whether the obstacles are a map of cells that each hold one robot and no more
    (a side from one separation to twice it, as in the MovingAI benchmark): there the
    grid stage routes robots cell by cell; an occupancy grid of finer cells, or of cells
    several robots wide, is free space like any other."""
    cell = map_cell(problem)
    sep = problem.separation
    return cell is not None and sep * (1 - 1e-9) <= cell[1] < 2 * sep


def map_grid(problem: Problem) -> tuple[np.ndarray, float] | Lines | None:
    """``(offset, spacing c)`` of the cell centres of a map of cells, from its obstacles, or ``None``.

    A map's obstacles are axis-aligned rectangles whose sides lie on the cell
    lines ``o + s * integers`` (:func:`sim.scenario.maps.cover`).  The cell
    ``s`` is found as in :func:`detect_grid` from the sides' coordinates; every
    rectangle side must lie on those lines, and at least 9 in 10 obstacles must be such
    rectangles.  The grid is the cell centres ``o + s / 2 + c * integers`` with
    ``c`` the smallest multiple of ``s`` at least the separation (``c = s`` for
    cells a robot fills, as in the MovingAI benchmark).  It is what
    :func:`grid_waypoints` routes on when the starts or targets lie off every
    grid (scattered over the free space): they are first snapped onto it.  Cells finer
    than the separation (an occupancy grid) on a map of at most :data:`_LINE_CELLS`
    cells give uneven grid lines instead (:class:`Lines`, :func:`door_lines`).
    """
    cell = map_cell(problem)
    if cell is None:
        return None
    origin, s = cell
    mult = max(1, math.ceil(problem.separation / s - 1e-9))
    c = s * mult
    if not (problem.width / c) * (problem.height / c) <= _MAX_VERTICES:
        return None
    if mult > 1 and problem.width * problem.height / s**2 <= _LINE_CELLS:
        cached = problem.__dict__.get("_map_lines")
        if cached is None:
            cached = problem.__dict__["_map_lines"] = door_lines(problem, origin, s, mult)
        return cached
    return np.mod(origin + s / 2, c), float(c)


#: Maps of at most this many cells, cells finer than the separation, get uneven grid lines
_LINE_CELLS = 150_000  # about 0.4 s of exact tests (360 000 cells: 1.0 s)


class Lines:
    """A grid whose lines are unevenly spaced: vertical lines at ``xs``, horizontal ones at
    ``ys`` (increasing, consecutive lines at least ``gap`` apart, at most ``reach``)."""

    def __init__(self, xs: np.ndarray, ys: np.ndarray):
        self.xs, self.ys = np.asarray(xs, float), np.asarray(ys, float)
        gaps = np.concatenate([np.diff(self.xs), np.diff(self.ys)])
        self.gap = float(gaps.min(initial=math.inf))
        self.reach = float(gaps.max(initial=0.0))


def door_lines(problem: Problem, origin: np.ndarray, s: float, mult: int) -> Lines | None:
    """Grid lines through the cell centres of a map of fine cells, chosen so that narrow
    openings get a line through them (``None`` when no line fits).

    With ``mult`` cells per separation, a grid of every ``mult``-th cell line misses a
    doorway whose free band (the cell centres a robot's centre may take there) is fewer
    than ``mult`` cells wide, unless its phase happens to fit.  Here each axis is chosen
    on its own: a cell centre that keeps the clearance (exact) and lies in a run of
    clear centres across the line shorter than ``2 mult - 1`` cells (a narrow opening:
    an even grid with that largest gap could pass it by) weighs 1, every other clear
    centre a small amount; a dynamic program picks the lines, consecutive ones ``mult``
    to ``2 mult - 1`` cells apart (at least the separation), of the largest total
    weight.  The per-step exact check of :func:`grid_waypoints` covers the uneven gaps
    (every TSWAP rule of the module holds gap by gap).
    """
    origin = np.mod(origin, s)  # the first cell line in the workspace (the map's may lie above)
    kx = int(math.floor((problem.width - origin[0]) / s + 1e-9))
    ky = int(math.floor((problem.height - origin[1]) / s + 1e-9))
    if kx < 1 or ky < 1:
        return None
    cx = origin[0] + s * (np.arange(kx) + 0.5)
    cy = origin[1] + s * (np.arange(ky) + 0.5)
    gx, gy = np.meshgrid(cx, cy, indexing="ij")
    pts = np.stack([gx.ravel(), gy.ravel()], axis=1)
    clear = ~_in_rectangles(problem, pts, kx, ky)
    clear[clear] = problem.env.points_clear(pts[clear], problem.clearance)
    clear = clear.reshape(kx, ky)
    wide = 2 * mult - 1
    # each axis in turn, its edge scores counted on the other axis' lines only
    xs = _pick(clear, mult, wide)  # vertical lines
    ys = _pick(clear.T, mult, wide, on=xs)
    for _ in range(2):
        if len(xs) == 0 or len(ys) == 0:
            return None
        xs = _pick(clear, mult, wide, on=ys)
        ys = _pick(clear.T, mult, wide, on=xs)
    if len(xs) == 0 or len(ys) == 0:
        return None
    return Lines(_apart(cx[xs], problem.separation), _apart(cy[ys], problem.separation))


def _apart(lines: np.ndarray, sep: float) -> np.ndarray:
    """The lines, each moved up by the few ulps that make its difference from the one
    before at least ``sep`` in floating point (cell centres ``mult`` cells apart are a
    separation apart only up to rounding: 0.4499999999999886 for 9 cells of 0.05, which
    the exact checks would count as robots too close)."""
    out = np.array(lines, float)
    for k in range(1, len(out)):
        while out[k] - out[k - 1] < sep:
            out[k] = np.nextafter(out[k], math.inf)
    return out


def _runs(clear: np.ndarray) -> np.ndarray:
    """For every cell, the length of its run of clear cells down axis 0 (0 where blocked)."""
    n, m = clear.shape
    c = np.concatenate([np.zeros((1, m), np.int8), clear.astype(np.int8), np.zeros((1, m), np.int8)])
    d = np.diff(c, axis=0)  # +1 where a run starts, -1 one past its end (per column)
    run = np.zeros((n, m), np.int64)
    for j in np.flatnonzero(clear.any(axis=0)):
        a = np.flatnonzero(d[:, j] == 1)
        b = np.flatnonzero(d[:, j] == -1)
        lengths = np.repeat(b - a, b - a)
        run[np.concatenate([np.arange(x, y) for x, y in zip(a, b)]), j] = lengths
    return run


def _pick(clear: np.ndarray, lo: int, hi: int, on: np.ndarray | None = None) -> np.ndarray:
    """Line positions (indices along axis 0 of ``clear``, lines running along axis 1),
    consecutive ones ``lo`` to ``hi`` apart, the first within ``hi`` of the start and the
    last within ``hi`` of the end, of the largest score.

    A line at ``k`` scores the clear cells it passes whose run across it (down axis 0) is
    shorter than ``hi`` (an opening an even grid could miss; 1 where the line runs on clear
    for ``2 hi`` cells through it, else 0.1); two consecutive lines ``a <
    b`` score the cells ``(t, j)`` between them, ``a < t < b``, whose run along axis 1 is
    shorter than ``hi`` (a gap in a wall across the lines) where the cells ``a..b`` of
    that row are all clear (the edge between the lines' vertices through the gap can be
    clear), counted on the rows ``on`` only when given (the other axis' lines); every clear
    cell on a line scores 1e-3 more."""
    n, m = clear.shape
    narrow_across = clear & (_runs(clear) < hi)
    along = _runs(clear.T).T  # run along axis 1
    # an opening counts fully where the line through it runs on clear for 2 hi cells at least
    # (room for vertices on both sides), a tenth where something blocks it near
    w = (narrow_across * np.where(along >= 2 * hi, 1.0, 0.1)).sum(axis=1) + 1e-3 * clear.sum(axis=1)
    narrow_along = (clear & (along < hi)).astype(np.int64)
    if on is not None:
        rows = np.zeros(m, bool)
        rows[np.asarray(on, int)] = True
        narrow_along[:, ~rows] = 0
    blocked = np.concatenate([np.zeros((1, m), np.int64), np.cumsum(~clear, axis=0)])  # prefix over axis 0
    gate = np.concatenate([np.zeros((1, m), np.int64), np.cumsum(narrow_along, axis=0)])

    def pair(a: np.ndarray, b: int) -> np.ndarray:
        """Scores of the line pairs (a[i], b)."""
        ok = (blocked[b + 1] - blocked[a]) == 0  # (len(a), m): rows a..b all clear
        through = (gate[b] - gate[a + 1]) > 0  # a narrow cell strictly between
        return (ok & through).sum(axis=1).astype(float)

    best = np.full(n, -np.inf)
    prev = np.full(n, -1)
    for k in range(n):
        if k < hi:
            best[k] = w[k]
        a = np.arange(max(0, k - hi), k - lo + 1)
        if len(a):
            cand = best[a] + pair(a, k) + w[k]
            j = int(np.argmax(cand))
            if cand[j] > best[k]:
                best[k], prev[k] = cand[j], a[j]
    tail = np.arange(max(0, n - hi), n)
    if not len(tail) or not np.isfinite(best[tail]).any():
        return np.zeros(0, int)
    k = int(tail[np.argmax(best[tail])])
    out = []
    while k >= 0:
        out.append(k)
        k = int(prev[k])
    return np.asarray(out[::-1], int)


def detect_grid(problem: Problem) -> tuple[np.ndarray, float] | None:
    """``(offset (2,), spacing c)`` of a square grid holding every start and target with
    ``c >= separation``, or ``None``."""
    pts = np.concatenate([problem.start, problem.target])
    if len(pts) < 2:
        return None
    tol = _TOL * max(problem.width, problem.height, 1.0)
    gaps = []
    for axis in range(2):
        u = np.unique(pts[:, axis])
        d = np.diff(u)
        d = d[d > tol]
        if len(d):
            gaps.append(d.min())
    if not gaps:
        return None
    base = min(gaps)
    sep = problem.separation
    for k in range(1, 5):
        c = base / k
        if c < sep - tol:
            return None
        origin = pts.min(axis=0)
        idx = np.round((pts - origin) / c)
        if np.abs(origin + c * idx - pts).max() <= tol:
            return np.mod(origin, c), float(c)
    return None


def find_grid(problem: Problem) -> tuple[tuple[np.ndarray, float], bool] | None:
    """``(grid, snapped)``: the grid holding every start and target (:func:`detect_grid`,
    ``snapped`` false), else the cell centres of a map (:func:`map_grid`, ``snapped``
    true: the placements are snapped onto it), else ``None``."""
    grid = detect_grid(problem)
    if grid is not None:
        return grid, False
    grid = map_grid(problem)
    return None if grid is None else (grid, True)


def build_grid(problem: Problem, offset, c: float | None = None) -> tuple[Lattice, np.ndarray, np.ndarray] | None:
    """The grid graph as a :class:`planner.grid.Lattice` (neighbour slots: right, up,
    left, down), with the grid index ``(i, j)`` of every vertex and the ``(nx, ny)``
    table of vertex ids (-1: not a vertex); ``None`` when the grid is too big.
    ``offset`` may be :class:`Lines` (``c`` unused)."""
    if isinstance(offset, Lines):
        nx, ny = len(offset.xs), len(offset.ys)
        if nx * ny > _MAX_VERTICES:
            return None
        gi, gj = np.meshgrid(np.arange(nx), np.arange(ny), indexing="ij")
        pts = np.stack([offset.xs[gi.ravel()], offset.ys[gj.ravel()]], axis=1)
        lattice, ok, vid = grid_graph(problem, pts, nx, ny, offset.gap)
        return lattice, np.stack([gi.ravel(), gj.ravel()], axis=1)[ok], vid
    ox, oy = float(offset[0]), float(offset[1])
    i0, i1 = math.ceil(-ox / c - _TOL), math.floor((problem.width - ox) / c + _TOL)
    j0, j1 = math.ceil(-oy / c - _TOL), math.floor((problem.height - oy) / c + _TOL)
    nx, ny = i1 - i0 + 1, j1 - j0 + 1
    if nx <= 0 or ny <= 0 or nx * ny > _MAX_VERTICES:
        return None
    gi, gj = np.meshgrid(np.arange(i0, i1 + 1), np.arange(j0, j1 + 1), indexing="ij")
    pts = np.stack([ox + c * gi.ravel(), oy + c * gj.ravel()], axis=1)
    lattice, ok, vid = grid_graph(problem, pts, nx, ny, c)
    ij = np.stack([gi.ravel(), gj.ravel()], axis=1)[ok]
    return lattice, ij - np.array([i0, j0]), vid
