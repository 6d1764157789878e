"""The packing stage (planner.dense) at any scale."""

from __future__ import annotations

import numpy as np
import pytest

from bench.packing import packing_problem
from planner import Problem
from planner.dense import _box, dense_plan


def _scaled(problem: Problem, s: float) -> Problem:
    """The same problem with every length (and the speed and acceleration) times ``s``:
    the same plans, in the same times."""
    return Problem(problem.width * s, problem.height * s, (), problem.radius * s, problem.margin * s,
                   problem.start * s, problem.target * s, max_speed=problem.max_speed * s,
                   max_accel=problem.max_accel * s)


def test_small_robots_pack_as_well_as_large_ones():
    """Flow steps and pushes scale with the separation: robots of radius 0.2 took 13.0 s
    where robots of radius 1 take 5.8 s in the same packing (the steps were fixed lengths)."""
    problem = packing_problem(50, 0.5, 0)
    big = dense_plan(problem, 10.0, np.random.default_rng(0))
    small = dense_plan(_scaled(problem, 0.2), 10.0, np.random.default_rng(0))
    assert big is not None and small is not None
    assert small.makespan <= 1.1 * big.makespan


@pytest.mark.parametrize("side", [16.9, 17.72, 38.4, 1.3, 12.345])
def test_the_box_of_clear_centres_is_clear_in_floating_point(side):
    problem = Problem(side, side * 1.1, (), 0.5, 0.05, [[side / 2, side / 2]], [[side / 2, side / 2]])
    lo, hi = _box(problem)
    c = problem.clearance
    assert side - hi[0] >= c and side * 1.1 - hi[1] >= c and lo[0] == c
    assert problem.env.points_clear(np.array([hi, lo, [lo[0], hi[1]]]), c).all()


def test_packed_robots_at_the_far_walls_stay_exactly_clear():
    """At 55 % robots end on the right and top walls: ``width - clearance`` rounds 4e-16
    too close to them, and the exact test then refused to join their steps (8.9 s instead
    of 6.6 s)."""
    problem = packing_problem(50, 0.55, 0)
    result = dense_plan(problem, 10.0, np.random.default_rng(0))
    assert result is not None
    w = np.asarray(result.waypoints)
    assert problem.env.points_clear(w.reshape(-1, 2), problem.clearance).all()
    assert (w[..., 0].max() > problem.width - problem.clearance - 1e-6
            or w[..., 1].max() > problem.height - problem.clearance - 1e-6)  # some robot at a far wall
