"""The square lattice of the lattice stage (:mod:`planner.lattice`): clear
points at a spacing of about ``sqrt(2) * separation`` and the clear segments
between 4-neighbours (both exact), with the connected components."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .problem import Problem

__all__ = ["Lattice", "build_lattice", "grid_graph", "lattice_spacing"]


_SLACK = 1.0 + 1e-6  # spacing over sqrt(2) * separation
_MAX_VERTICES = 60_000
_FIELD_ENTRIES = 10_000_000  # robots x vertices in the distance fields


@dataclass(frozen=True, eq=False)
class Lattice:
    """Clear lattice points ``points (V, 2)``, their 4-neighbours ``nbr (V, 4)``
    (-1 where there is none or the edge is blocked), the spacing and the
    connected component of every vertex."""

    points: np.ndarray
    nbr: np.ndarray
    spacing: float
    component: np.ndarray

    @property
    def n(self) -> int:
        return len(self.points)


def lattice_spacing(problem: Problem) -> float:
    """``sqrt(2) * separation`` (plus a hair), larger when the lattice would be too big."""
    a = math.sqrt(2.0) * problem.separation * _SLACK
    cap = min(_MAX_VERTICES, _FIELD_ENTRIES // max(problem.m, 1))
    return max(a, math.sqrt(problem.width * problem.height / cap))


def build_lattice(problem: Problem, spacing: float, shift: tuple[float, float] = (0.0, 0.0)) -> Lattice:
    """The lattice of clear points and clear 4-neighbour edges (both exact); ``shift``
    moves it by that fraction of the spacing."""
    c = problem.clearance
    nx = int(math.floor((problem.width - 2 * c) / spacing - shift[0])) + 1
    ny = int(math.floor((problem.height - 2 * c) / spacing - shift[1])) + 1
    # centred between the walls' margins, then shifted
    ox = c + 0.5 * (problem.width - 2 * c - (nx - 1 + shift[0]) * spacing) + shift[0] * spacing
    oy = c + 0.5 * (problem.height - 2 * c - (ny - 1 + shift[1]) * spacing) + shift[1] * spacing
    gx, gy = np.meshgrid(ox + spacing * np.arange(nx), oy + spacing * np.arange(ny), indexing="ij")
    return grid_graph(problem, np.stack([gx.ravel(), gy.ravel()], axis=1), nx, ny, spacing)[0]


def grid_graph(problem: Problem, pts: np.ndarray, nx: int, ny: int,
               spacing: float, clearance: float | None = None) -> tuple[Lattice, np.ndarray, np.ndarray]:
    """The clear points of the ``(nx, ny)`` grid ``pts`` (x-major) and their clear
    4-neighbour edges (both exact) as a :class:`Lattice`, with the mask of clear grid
    points and the ``(nx, ny)`` table of vertex ids (-1: not a vertex).  ``clearance``:
    the least distance to the obstacles and walls (default: radius + margin)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    c = problem.clearance if clearance is None else clearance
    env = problem.env
    skip = _cell_rectangles(problem, pts, nx, ny, spacing, c)
    if skip is not None and skip.any():  # a map's cells: only the other obstacles need the exact tests
        from .geometry import Environment

        env = Environment.build(problem.width, problem.height,
                                [ob for k, ob in enumerate(problem.obstacles) if not skip[k]])
    ok = ~_in_rectangles(problem, pts, nx, ny)
    ok[ok] = env.points_clear(pts[ok], c)
    vid = np.full(nx * ny, -1)
    vid[ok] = np.arange(int(ok.sum()))
    vid = vid.reshape(nx, ny)
    pts = pts[ok]
    nbr = np.full((len(pts), 4), -1)
    rows, cols = [], []
    for k, (dx, dy) in enumerate(((1, 0), (0, 1))):
        a = vid[: nx - dx, : ny - dy].ravel()
        b = vid[dx:, dy:].ravel()
        both = (a >= 0) & (b >= 0)
        a, b = a[both], b[both]
        if len(a):
            clear = env.segments_clear(pts[a], pts[b], c)
            a, b = a[clear], b[clear]
        nbr[a, k] = b  # right / up
        nbr[b, k + 2] = a  # left / down
        rows.append(a)
        cols.append(b)
    r, cc = np.concatenate(rows), np.concatenate(cols)
    g = coo_matrix((np.ones(len(r)), (r, cc)), shape=(len(pts), len(pts)))
    _, comp = connected_components(g, directed=False)
    return Lattice(pts, nbr, float(spacing), comp), ok, vid


def _rectangles(problem: Problem) -> tuple[np.ndarray, np.ndarray]:
    """``(boxes (k, 4) as lo_x, lo_y, hi_x, hi_y, their obstacle indices (k,))`` of the
    obstacles that are axis-aligned rectangles (every vertex a corner of its bounding box)."""
    cached = problem.__dict__.get("_axis_rectangles")
    if cached is not None:
        return cached
    box, idx = [], []
    for k, ob in enumerate(problem.obstacles):
        v = np.asarray(getattr(ob, "vertices", np.zeros((0, 2))), float)
        if len(v) != 4:
            continue
        lo, hi = v.min(axis=0), v.max(axis=0)
        if all(((p == lo) | (p == hi)).all() for p in v) and (hi > lo).all():
            box.append(np.concatenate([lo, hi]))
            idx.append(k)
    out = problem.__dict__["_axis_rectangles"] = (np.asarray(box, float).reshape(-1, 4), np.asarray(idx, int))
    return out


def _axis_lines(pts: np.ndarray, nx: int, ny: int) -> tuple[np.ndarray, np.ndarray] | None:
    """The x and y lines of an axis-aligned ``(nx, ny)`` grid of points (x-major), or ``None``."""
    if nx < 2 or ny < 2:
        return None
    g = pts.reshape(nx, ny, 2)
    xs, ys = g[:, 0, 0], g[0, :, 1]
    if (g[:, :, 0] != xs[:, None]).any() or (g[:, :, 1] != ys[None, :]).any() \
            or (np.diff(xs) <= 0).any() or (np.diff(ys) <= 0).any():
        return None
    return xs, ys


def _cell_rectangles(problem: Problem, pts: np.ndarray, nx: int, ny: int, spacing: float,
                     clearance: float) -> np.ndarray | None:
    """Which obstacles no edge between two clear grid points can come near, or ``None``.

    On an evenly spaced axis-aligned grid whose points are the centres of square
    cells of side ``spacing``, take a rectangle obstacle whose sides lie on the cell
    lines (midway between grid lines): a map's blocked cells.  A clear point is not
    in it, so it is a union of whole cells other than the two cells an edge joins;
    the edge lies in those two closed cells, so every point of the rectangle is at
    least ``spacing / 2`` from it (a row above or below, or a cell beyond either end
    of the row).  With ``spacing / 2`` at least ``clearance``, such an edge is
    clear of it, and only the other obstacles need the exact test; so does a grid
    point outside it (its own cell is free, every other cell ``spacing / 2`` away).
    """
    lines = _axis_lines(pts, nx, ny)
    if lines is None or not problem.obstacles:
        return None
    xs, ys = lines
    tol = 1e-9 * max(problem.width, problem.height, 1.0)
    if np.abs(np.diff(xs) - spacing).max() > tol or np.abs(np.diff(ys) - spacing).max() > tol \
            or spacing / 2 - 4 * tol < clearance:
        return None
    b, idx = _rectangles(problem)
    out = np.zeros(len(problem.obstacles), bool)
    if not len(b):
        return out

    def on_cell_lines(v: np.ndarray, first: float) -> np.ndarray:
        k = (v - first) / spacing - 0.5
        return np.abs(k - np.round(k)) * spacing <= tol

    ok = on_cell_lines(b[:, 0], xs[0]) & on_cell_lines(b[:, 2], xs[0]) \
        & on_cell_lines(b[:, 1], ys[0]) & on_cell_lines(b[:, 3], ys[0])
    out[idx[ok]] = True
    return out


def _in_rectangles(problem: Problem, pts: np.ndarray, nx: int, ny: int) -> np.ndarray:
    """Grid points in a closed axis-aligned rectangle obstacle (a map's blocked cells):
    at distance 0 from it, so never clear.  Marked by index ranges on the regular
    grid in time linear in rectangles plus points, so that the exact test only sees
    the rest (on a map of a million cells, most of them are blocked)."""
    out = np.zeros(nx * ny, bool)
    # only an axis-aligned grid, its lines evenly spaced or not (a rotated one, as the door
    # stage's, is left to the exact test)
    lines = _axis_lines(pts, nx, ny)
    if lines is None or not problem.obstacles:
        return out
    xs, ys = lines
    b, _ = _rectangles(problem)
    if not len(b):
        return out
    # the closed range of grid lines inside each box, by the lines' exact coordinates:
    # points ia..ib-1, ja..jb-1 lie in the closed box
    ia, ib = np.searchsorted(xs, b[:, 0], side="left"), np.searchsorted(xs, b[:, 2], side="right")
    ja, jb = np.searchsorted(ys, b[:, 1], side="left"), np.searchsorted(ys, b[:, 3], side="right")
    mark = np.zeros((nx + 1, ny + 1), np.int64)
    for k in np.flatnonzero((ib > ia) & (jb > ja)):
        mark[ia[k], ja[k]] += 1
        mark[ib[k], ja[k]] -= 1
        mark[ia[k], jb[k]] -= 1
        mark[ib[k], jb[k]] += 1
    inside = np.cumsum(np.cumsum(mark, axis=0), axis=1)[:nx, :ny] > 0
    return inside.ravel()
