"""The dense-packing stage (planner.dense) on small and full-size random packings."""

from __future__ import annotations

import time

import numpy as np
import pytest
from scipy.spatial import cKDTree

from bench.packing import packing_problem
from planner import Plan, Problem, check_plan
from planner.dense import dense_plan, flow, packing_sites, step_ok
from planner.validate import PlanInvalid, min_clearance


@pytest.mark.parametrize(("m", "coverage", "seed"), [(8, 0.5, 0), (20, 0.5, 2), (50, 0.55, 3), (50, 0.5, 4)])
def test_dense_packings_are_planned_and_exact(m, coverage, seed):
    problem = packing_problem(m, coverage, seed)
    result = dense_plan(problem, 10.0, np.random.default_rng(seed))
    assert result is not None
    clearance = check_plan(problem, result)
    assert clearance.value >= problem.margin - 1e-9
    assert np.array_equal(result.start, problem.start)
    # every row is a valid placement: separated and clear
    for row in result.waypoints:
        problem.__class__(problem.width, problem.height, (), problem.radius, problem.margin, row, row).validate()


def test_a_tampered_plan_is_rejected():
    problem = packing_problem(20, 0.5, 5)
    result = dense_plan(problem, 10.0, np.random.default_rng(5))
    assert result is not None and result.steps >= 2
    w = np.array(result.waypoints)
    k = result.steps // 2
    i, j = 0, int(cKDTree(w[k]).query(w[k][0], 2)[1][1])
    w[k, i] = w[k, j] + 0.5 * problem.radius  # robot 0 half a radius from its neighbour
    tampered = Plan.from_waypoints(w, problem.radius, problem.margin, problem.max_speed, problem.max_accel)
    with pytest.raises(PlanInvalid):
        check_plan(problem, tampered)
    assert min_clearance(problem, tampered).value < 0


def test_step_ok_finds_a_crossing_and_passes_a_shift():
    sep = 2.1
    problem = Problem(20, 20, (), 1.0, 0.1, [[5, 10], [10, 10]], [[5, 10], [10, 10]])
    a = np.array([[5.0, 10.0], [10.0, 10.0]])
    assert len(step_ok(problem, a, a[::-1].copy())) == 1  # a swap meets in the middle
    assert len(step_ok(problem, a, a + [0.0, 3.0])) == 0  # both shifted together
    b = a + [[sep, 0.0], [0.0, 0.0]]  # robot 0 stops short of touching robot 1 ...
    b[0, 0] = 10.0 - sep - 1e-9
    assert len(step_ok(problem, a, b)) == 0
    b[0, 0] += 1e-6 + 1e-9  # ... and a hair further it does not
    assert len(step_ok(problem, a, b)) == 1


def test_sites_are_separated_and_clear():
    for coverage in (0.5, 0.55):
        problem = packing_problem(50, coverage, 0)
        lattices = packing_sites(problem)
        assert lattices
        for s in lattices:
            assert len(s) >= problem.m
            assert cKDTree(s).query(s, 2)[0][:, 1].min() >= problem.separation
            assert problem.env.points_clear(s, problem.clearance).all()


def test_gives_up_fast():
    problem = packing_problem(20, 0.5, 6)
    sites = packing_sites(problem)[0]
    assert flow(problem, problem.start, sites, time.perf_counter() - 1.0, np.random.default_rng(0)) is None


def test_a_flow_settles_on_sites_closer_than_separation_plus_the_push():
    """200 robots scattered over an empty box of side 38.4 (43 % covered): the square grid
    of 18 x 18 sites is 2.13 apart, under the separation 2.1 plus the push's 0.1, so a push
    to 2.2 kept every robot off its site (no plan in 60 s)."""
    from planner.geometry import Environment
    from planner.scatter import scatter

    rng = np.random.default_rng(0)
    pts = scatter(Environment.build(38.4, 38.4, ()), 200, 2.1, 1.1, rng)
    problem = Problem(38.4, 38.4, (), 1.0, 0.1, pts, pts)
    sites = packing_sites(problem)[0]
    assert len(sites) == 324 and cKDTree(sites).query(sites, 2)[0][:, 1].min() < problem.separation + 0.1
    way = flow(problem, pts, sites, time.perf_counter() + 30, rng, 0.15, 0.1)
    assert way is not None
    end = way[-1]
    assert cKDTree(sites).query(end)[0].max() == 0.0  # every robot on a site
    for a, b in zip(way, way[1:]):
        assert len(step_ok(problem, a, b)) == 0
