"""The packing stage (planner.dense) among obstacles, and its lattice meeting (planner.packmeet)."""

from __future__ import annotations

import time

import numpy as np

from bench.maps import scatter_problem
from bench.packing import packing_problem
from planner import PlannerParams, Polygon, Problem, check_plan, plan
from planner.dense import _better, dense, flow
from planner.mapgrid import robot_cells
from planner.packmeet import meet_lattices, meet_waypoints
from planner.scatter import scatter


def _pillars(m: int, seed: int) -> Problem:
    """A 10 x 10 hall with six pillars, robots of radius 0.2 scattered in it."""
    pillars = [Polygon(np.array([[x, y], [x + w, y], [x + w, y + h], [x, y + h]], float))
               for x, y, w, h in ((2, 2, 0.5, 0.5), (5, 2, 0.3, 1.5), (7.5, 3, 0.5, 0.5),
                                  (2, 6, 1.5, 0.3), (5, 6.5, 0.5, 0.5), (7.5, 7, 0.4, 1.2))]
    shell = Problem(10.0, 10.0, tuple(pillars), 0.2, 0.05, [[0.5, 0.5]], [[0.5, 0.5]])
    rng = np.random.default_rng(seed)
    start = scatter(shell.env, m, shell.separation, shell.clearance, rng)
    target = scatter(shell.env, m, shell.separation, shell.clearance, rng)
    return Problem(10.0, 10.0, tuple(pillars), 0.2, 0.05, start, target).validate()


def test_a_packing_among_pillars_is_planned_by_the_packing_stage():
    problem = _pillars(250, 1)
    assert dense(problem, 0.3)
    result, stats = plan(problem, PlannerParams(time_limit=12), np.random.default_rng(0))
    assert stats.extra["direct"] == "dense"
    assert check_plan(problem, result).value >= problem.margin - 1e-9


def test_both_placements_meet_on_a_roomy_lattice():
    """250 robots among pillars: both placements flowed onto one square lattice and the grid
    stage between them plan 5.2 s; the target-first flow onto the sites the start took
    plans 9.3 s at best (its second flow stalls on most lattices)."""
    problem = _pillars(250, 1)
    lattices = meet_lattices(problem)
    assert lattices
    for offset, c, pts in lattices:
        assert c >= problem.separation and len(pts) >= 1.1 * problem.m
        assert problem.env.points_clear(pts, problem.clearance).all()
        assert np.allclose(np.mod(pts - offset + 0.5 * c, c), 0.5 * c)  # on the grid
    w = meet_waypoints(problem, lattices[0], time.perf_counter() + 20, np.random.default_rng(0), 0.15, 0.1)
    assert w is not None
    assert np.array_equal(w[0], problem.start)
    found = _better(problem, w, None, time.perf_counter() + 20)
    assert found is not None and check_plan(problem, found).value >= problem.margin - 1e-9
    assert found.makespan < 7.0


def test_a_flow_never_jumps_an_obstacle():
    """One robot, its site behind a thin wall, steps long enough to jump it (``h`` of 20 at
    the separation 2.1: 4.3 here): every step that would cross the wall is refused, so
    the robot never lands beyond it in one step (without that test it does, at once)."""
    wall = Polygon(np.array([[4.0, 1.0], [4.2, 1.0], [4.2, 9.0], [4.0, 9.0]]))
    problem = Problem(10.0, 10.0, (wall,), 0.2, 0.05, [[2.0, 5.0]], [[6.0, 5.0]])
    way = flow(problem, problem.start, np.array([[6.0, 5.0]]), time.perf_counter() + 2.0,
               np.random.default_rng(0), h=20.0)
    steps = way if way is not None else []
    for a, b in zip(steps, steps[1:]):
        assert problem.env.segments_clear(a, b, problem.clearance).all()
    assert way is None or np.allclose(way[-1], [[6.0, 5.0]])


def test_dense_counts_the_area_outside_overlapping_obstacles_once():
    box = Polygon(np.array([[0.0, 0.0], [6.0, 0.0], [6.0, 10.0], [0.0, 10.0]]))
    again = Polygon(np.array([[-2.0, 0.0], [6.0, 0.0], [6.0, 10.0], [-2.0, 10.0]]))  # overlaps, sticks out
    pts = [[7.0 + 0.5 * (k % 5), 1.0 + 0.5 * (k // 5)] for k in range(30)]
    problem = Problem(10.0, 10.0, (box, again), 0.2, 0.05, pts, pts)
    covered = 30 * np.pi * 0.04 / 40.0  # 40 square units outside the obstacles
    assert dense(problem, covered * 0.999) and not dense(problem, covered * 1.001)


def test_maps_of_cells_a_robot_fills_are_told_apart():
    movingai = scatter_problem("room-32-32-4", 50, 0)  # cells of 2.4, separation 2.1
    assert robot_cells(movingai)
    fine = Problem(movingai.width / 6, movingai.height / 6, tuple(
        Polygon(o.vertices / 6) for o in movingai.obstacles), 0.2, 0.05, [[1.0, 1.0]], [[1.0, 1.0]])
    assert not robot_cells(fine)  # cells of 0.4 for a separation of 0.45: an occupancy grid
    coarse = Problem(movingai.width, movingai.height, movingai.obstacles, 0.2, 0.05, [[1.0, 1.0]], [[1.0, 1.0]])
    assert not robot_cells(coarse)  # cells of 2.4 hold many robots of separation 0.45
    assert not robot_cells(packing_problem(20, 0.5, 0))  # no map
