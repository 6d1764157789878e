"""Grid points inside rectangle obstacles are dropped before the exact test, and on a map's
cell centres the blocked cells are left out of the exact tests, with the same graph as the
exact tests alone."""

import numpy as np
import pytest

import planner.grid as grid
from planner.problem import Circle, Polygon, Problem


def _world(seed: int) -> Problem:
    rng = np.random.default_rng(seed)
    obstacles: list = []
    for i, j in np.argwhere(rng.random((25, 20)) < 0.35):  # map cells of 2.4, shared edges
        x, y = 2.4 * i, 2.4 * j
        obstacles.append(Polygon(np.array([[x, y], [x + 2.4, y], [x + 2.4, y + 2.4], [x, y + 2.4]])))
    obstacles.append(Polygon(np.array([[3.3, 3.3], [9.1, 4.0], [6.0, 9.7]])))  # not a rectangle
    obstacles.append(Polygon(np.array([[30, 30], [34, 31], [33, 35], [29, 34]], float)))  # a tilted square
    obstacles.append(Circle((50.0, 20.0), 2.0))
    return Problem(60, 48, tuple(obstacles), 1.0, 0.1, np.zeros((0, 2)), np.zeros((0, 2)))


def _graphs(problem, pts, nx, ny, spacing):
    fast = grid.grid_graph(problem, pts, nx, ny, spacing)
    keep, cells = grid._in_rectangles, grid._cell_rectangles
    grid._in_rectangles = lambda p, q, a, b: np.zeros(a * b, bool)
    grid._cell_rectangles = lambda *args: None
    try:
        exact = grid.grid_graph(problem, pts, nx, ny, spacing)
    finally:
        grid._in_rectangles, grid._cell_rectangles = keep, cells
    return fast, exact


def _grid(p, spacing, offset):
    nx, ny = int((p.width - offset) / spacing) + 1, int((p.height - offset) / spacing) + 1
    gx, gy = np.meshgrid(offset + spacing * np.arange(nx), offset + spacing * np.arange(ny), indexing="ij")
    return np.stack([gx.ravel(), gy.ravel()], axis=1), nx, ny


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("spacing, offset", [(2.4, 1.2), (2.4, 0.0), (1.7, 0.35), (3.1, 2.2)])
def test_prefilter_keeps_the_exact_graph(seed, spacing, offset):
    p = _world(seed)
    pts, nx, ny = _grid(p, spacing, offset)
    skip = grid._cell_rectangles(p, pts, nx, ny, spacing, p.clearance)
    if (spacing, offset) == (2.4, 1.2):  # the cell centres: the blocked cells skip the exact tests
        assert skip.sum() == len(p.obstacles) - 3  # all but the triangle, the tilted square, the circle
    else:
        assert skip is None or not skip.any()
    (l1, ok1, v1), (l2, ok2, v2) = _graphs(p, pts, nx, ny, spacing)
    assert np.array_equal(ok1, ok2) and np.array_equal(v1, v2) and np.array_equal(l1.nbr, l2.nbr)
    marked = grid._in_rectangles(p, pts, nx, ny)
    assert marked.sum() > 0.2 * len(pts)  # it does drop points: most blocked ones
    assert not (marked & ok2).any()  # and never a clear one


def test_points_on_a_rectangle_boundary_are_dropped_and_a_rotated_grid_is_left_alone():
    square = Polygon(np.array([[2.0, 2.0], [4.0, 2.0], [4.0, 4.0], [2.0, 4.0]]))
    p = Problem(10, 10, (square,), 0.5, 0.1, np.zeros((0, 2)), np.zeros((0, 2)))
    gx, gy = np.meshgrid(np.arange(11.0), np.arange(11.0), indexing="ij")
    pts = np.stack([gx.ravel(), gy.ravel()], axis=1)
    marked = grid._in_rectangles(p, pts, 11, 11).reshape(11, 11)
    assert marked[2:5, 2:5].all() and marked.sum() == 9
    rot = pts @ np.array([[np.cos(0.3), np.sin(0.3)], [-np.sin(0.3), np.cos(0.3)]])
    assert not grid._in_rectangles(p, rot, 11, 11).any()


@pytest.mark.parametrize("seed", [0, 1])
def test_cells_are_tested_exactly_when_half_a_cell_is_below_the_clearance(seed):
    """With the clearance above half a cell, a robot between two blocked cells does not fit:
    the shortcut is refused, and forcing it would keep points and edges the exact test drops."""
    base = _world(seed)
    p = Problem(base.width, base.height, base.obstacles, 1.15, 0.1, np.zeros((0, 2)), np.zeros((0, 2)))
    pts, nx, ny = _grid(p, 2.4, 1.2)
    assert grid._cell_rectangles(p, pts, nx, ny, 2.4, p.clearance) is None
    (l1, ok1, _), (l2, ok2, _) = _graphs(p, pts, nx, ny, 2.4)
    assert np.array_equal(ok1, ok2) and np.array_equal(l1.nbr, l2.nbr)
    keep = grid._cell_rectangles
    grid._cell_rectangles = lambda problem, q, a, b, c, cl: keep(problem, q, a, b, c, 1.1)
    try:
        forced, ok3, _ = grid.grid_graph(p, pts, nx, ny, 2.4)
    finally:
        grid._cell_rectangles = keep
    assert ok3.sum() > ok2.sum()  # the negative control: points the exact test drops
