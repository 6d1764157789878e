"""The grid stage: worlds whose starts and targets sit on one square grid.

Maps of cells (MovingAI benchmarks, occupancy grids) put every start and
target at a cell centre: on a grid ``offset + c * integers`` with
``separation <= c``, often below ``sqrt(2) * separation`` (cells of 2.4 for
robots of radius 1 and margin 0.1: separation 2.1), too fine for the
lattice stage's lattice (:mod:`planner.lattice`) but the natural graph.

1. **Detection** (:func:`detect_grid`): the spacing is the smallest gap
   between distinct coordinates of the starts and targets (or an integer
   fraction of it no smaller than the separation), and every coordinate
   must be ``offset + c * integer`` within ``1e-9`` (relative to the size
   of the workspace).
2. **Graph** (:func:`build_grid`): the grid points with exact clearance at
   least ``radius + margin``, and the 4-neighbour segments that are exactly
   clear.
3. **Routing**: TSWAP (:func:`planner.tswap.tswap`; Okumura and Defago,
   AIJ 2023), synchronous: each time step robots move to distinct
   neighbour vertices, no two swap, and a robot enters a vertex vacated in
   the same step only if the robot leaving it moves in the same direction.
   That rule is what the spacing needs.  In units of ``c`` the relative
   position of two robots moves on a segment between two non-zero integer
   vectors, by a difference of moves in ``{0, unit, unit + perpendicular
   unit, 2 unit}``: a unit or zero difference keeps it at least 1 (the
   segment lies on a grid line away from the origin, or along an axis
   from 1 to 2); a difference of two opposite units passes the origin only
   in a swap; a diagonal difference comes within ``1 / sqrt(2)`` of the
   origin only between two unit vectors, i.e. when one robot enters the
   vertex the other leaves in a perpendicular direction: following with a
   turn, ``c / sqrt(2) < separation``.  Every step is still checked with
   the exact closest-approach kernel over the pairs that can meet
   (:func:`step_separated`), and the stage gives up on a step that fails.
4. **Steps**: each time step is one plan step; consecutive steps are then
   merged where the straight joined step is exactly clear
   (:func:`planner.merge.merge_steps`), which cuts stops.  A few routings
   with ties broken at random are tried and the shortest kept
   (:func:`grid_plan`).
5. **Fewer steps**: TSWAP needs up to twice the shortest routing's steps
   when about half the vertices are taken.  Where the time-expanded graph
   is small enough, the routing with the fewest steps under the same rules
   is then sought as an integer program (:func:`planner.gridflow.flow_route`)
   below TSWAP's count (from :data:`FLOW_MIN_ROBOTS` robots on), within :data:`FLOW_BUDGET_S`, a third of the time
   left and ``0.5 + 1e-4 m^2`` seconds (1.5 s at 100 robots, 16.5 s at 400: TSWAP is
   close to the shortest routing when few vertices are taken), and kept when its plan
   is shorter.
"""

from __future__ import annotations

import math
import time

import numpy as np

from .geometry import closest_approach
from .grid import Lattice, grid_graph
from .lattice import snap
from .problem import Problem
from .tswap import tswap

__all__ = ["FLOW_BUDGET_S", "FLOW_MIN_ROBOTS", "GRID_BUDGET_S", "GRID_TRIES", "build_grid", "detect_grid", "find_grid",
           "grid_plan", "grid_waypoints", "map_grid", "step_separated"]

_TOL = 1e-9
_MAX_VERTICES = 1_100_000


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


def map_grid(problem: Problem) -> tuple[np.ndarray, float] | None:
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
    clear = ~_in_rectangles_of(problem, pts, kx, ky)
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
    return Lines(cx[xs], cy[ys])


def _in_rectangles_of(problem: Problem, pts: np.ndarray, nx: int, ny: int) -> np.ndarray:
    from .grid import _in_rectangles

    return _in_rectangles(problem, pts, nx, ny)


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


def step_separated(problem: Problem, a: np.ndarray, b: np.ndarray, reach: float) -> bool:
    """Whether the step ``a -> b`` (no move longer than ``reach``) keeps every pair of
    robots the separation apart, by the exact closest approach over the pairs whose
    starts are within ``separation + 2 reach``."""
    from scipy.spatial import cKDTree

    pairs = cKDTree(a).query_pairs(problem.separation + 2 * reach + 1e-9, output_type="ndarray")
    if len(pairs) == 0:
        return True
    i, j = pairs[:, 0], pairs[:, 1]
    d = closest_approach(a[i], b[i], a[j], b[j])
    return bool(d.min() >= problem.separation - 1e-9)


#: Routings tried by :func:`grid_plan` at most (the first breaks ties by distance only,
#: the others also at random), within :data:`GRID_BUDGET_S` seconds.
GRID_TRIES = 8
GRID_BUDGET_S = 1.5
#: Seconds the shortest-routing search (:mod:`planner.gridflow`) may take at most.
FLOW_BUDGET_S = 20.0
#: Fewer robots than this leave TSWAP's routing as it is (within a step or two of the shortest).
FLOW_MIN_ROBOTS = 40


def grid_plan(problem: Problem, deadline: float, grid=None, rng=None):
    """``(merged waypoints, raw time steps)`` of the shortest of a few grid routings, or
    ``None``.  Each try is routed (:func:`grid_waypoints`), merged
    (:func:`planner.merge.merge_steps`) and timed; tries go on while they fit in
    :data:`GRID_BUDGET_S` and before ``deadline``."""
    from .merge import merge_steps
    from .timing import _drop_idle, _makespan

    grid = detect_grid(problem) if grid is None else grid
    if grid is None:
        return None
    t0 = time.perf_counter()
    if rng is None:
        raise ValueError("rng: the grid stage draws its tie-breaks from the run's generator; pass it")
    best = None
    for k in range(GRID_TRIES):
        now = time.perf_counter()
        if k and (now > deadline or (now - t0) * (k + 1) / k > GRID_BUDGET_S):
            break
        raw = grid_waypoints(problem, deadline, grid, None if k == 0 else rng)
        if raw is None:
            if k == 0:
                return None
            continue
        w = merge_steps(problem, _drop_idle(raw), deadline)
        span = _makespan(problem, w)
        if best is None or span < best[2]:
            best = (w, len(raw) - 1, span)
    if best is not None and best[1] > 1 and problem.m >= FLOW_MIN_ROBOTS:
        left = deadline - time.perf_counter()
        budget = min(FLOW_BUDGET_S, left / 3, 0.5 + 1e-4 * problem.m**2)
        raw = grid_waypoints(problem, deadline, grid, flow=(best[1], budget))
        if raw is not None:
            w = merge_steps(problem, _drop_idle(raw), deadline)
            span = _makespan(problem, w)
            if span < best[2]:
                best = (w, len(raw) - 1, span)
    return None if best is None else best[:2]


def grid_waypoints(problem: Problem, deadline: float, grid=None, rng=None,
                   flow: tuple[int, float] | None = None) -> list[np.ndarray] | None:
    """Raw waypoints (one per time step) of the grid stage, or ``None`` (no grid, a start
    or target off the graph, routing stalled, or the deadline).  ``rng``: ties among
    equally far robots broken at random (another try).  ``flow = (steps, budget)``:
    route by :func:`planner.gridflow.flow_route` in fewer than ``steps`` instead."""
    grid = detect_grid(problem) if grid is None else grid
    if grid is None:
        return None
    lines = grid if isinstance(grid, Lines) else None
    if lines is not None:
        key: tuple = ("_grid_graph", id(lines))
        c, offset = lines.reach, None
    else:
        offset, c = grid
        key = ("_grid_graph", tuple(np.asarray(offset, float)), float(c))
    if key not in problem.__dict__:  # every try and the shortest-routing search use the same graph
        problem.__dict__[key] = build_grid(problem, lines) if lines is not None else build_grid(problem, offset, c)
    built = problem.__dict__[key]
    if built is None or built[0].n == 0:
        return None
    lat, _, vid = built

    def vertex(p: np.ndarray) -> np.ndarray:
        if lines is not None:  # the nearest vertex (the placement is on it only if _on says so)
            from scipy.spatial import cKDTree

            return np.asarray(cKDTree(lat.points).query(p)[1], int)
        i0 = math.ceil(-float(offset[0]) / c - _TOL)
        j0 = math.ceil(-float(offset[1]) / c - _TOL)
        ij = np.round((p - offset) / c).astype(int) - np.array([i0, j0])
        if (ij < 0).any() or (ij[:, 0] >= vid.shape[0]).any() or (ij[:, 1] >= vid.shape[1]).any():
            return np.full(len(p), -1)
        return vid[ij[:, 0], ij[:, 1]]

    sv, gv = vertex(problem.start), vertex(problem.target)
    entry = leave = None  # snapping rounds onto the grid (placements off it)
    if not _on(lat, sv, problem.start):
        got = snap(problem, lat, problem.start, deadline)
        if got is None:
            return None
        entry, sv = got
    if not _on(lat, gv, problem.target):
        got = snap(problem, lat, problem.target, deadline)
        if got is None:
            return None
        leave, gv = got
    # sqrt(2) * separation or more: following with a turn is safe too
    turns = (lines.gap if lines is not None else c) >= math.sqrt(2.0) * problem.separation
    if flow is not None:
        from .gridflow import flow_route

        steps = flow_route(lat, sv, gv, deadline, turns=turns, below=flow[0], budget=flow[1])
    else:
        steps = tswap(lat, sv, gv, deadline, turns=turns, rng=rng)
    if steps is None:
        return None
    raw = [np.asarray(problem.start, float), *(entry or [])]
    for where in steps:
        if time.perf_counter() > deadline:
            return None
        nxt = lat.points[where]
        if not step_separated(problem, raw[-1], nxt, c * (1 + 1e-9)):
            return None  # never expected: the rule above keeps every step separated
        raw.append(nxt)
    if leave is None:
        # the robots end on the very target points (grid points equal them within 1e-9)
        raw[-1] = _exact_targets(problem, raw[-1])
        return raw
    # the target's snapping rounds played backwards: the robot on vertex gv[j] ends on target j
    at = np.full(lat.n, -1)
    at[steps[-1] if steps else sv] = np.arange(problem.m)
    robot = at[gv]
    if (robot < 0).any():
        return None
    inv = np.empty(problem.m, int)
    inv[robot] = np.arange(problem.m)
    back = [np.asarray(problem.target, float), *leave][::-1]  # target j's robot in row j
    raw += [cfg[inv] for cfg in back[1:]]
    return raw


def _on(lat: Lattice, v: np.ndarray, pts: np.ndarray) -> bool:
    """Whether every point sits on its grid vertex ``v`` (-1: none) within 1e-9 of the workspace."""
    if (v < 0).any():
        return False
    return bool(np.abs(lat.points[v] - pts).max(initial=0.0) <= 1e-9 * max(1.0, float(np.abs(pts).max(initial=1.0))))


def _exact_targets(problem: Problem, end: np.ndarray) -> np.ndarray:
    """Each final grid point replaced by the target it stands for."""
    from scipy.spatial import cKDTree

    _, k = cKDTree(problem.target).query(end)
    out = np.asarray(problem.target, float)[k]
    return out if len(np.unique(k)) == len(k) else end
