"""One generator per run: made by Scenario.generator, passed down, never a silent default seed."""

import numpy as np
import pytest

from planner import Plan, Problem
from sim.execute.physics import execute
from sim.scenario import read_scenario
from sim.scenario.params import Noise, SimParams

FIG2 = "scenarios/paper/fig2-random-to-C.yaml"


def _two():
    problem = Problem(20.0, 10.0, (), radius=0.5, margin=0.1, start=[[2, 3], [2, 7]], target=[[18, 3], [18, 7]])
    plan = Plan.from_waypoints(np.array([problem.start, problem.target]), 0.5, 0.1, max_speed=2.0, max_accel=2.0)
    return problem, plan


def test_a_realistic_run_without_the_run_generator_is_refused():
    problem, plan = _two()
    noisy = SimParams(noise=Noise(position=0.01), settle_time=0.5)
    with pytest.raises(ValueError, match="rng"):
        execute(problem, plan, noisy)
    # with the generator it runs, and the same seed repeats
    a = execute(problem, plan, noisy, np.random.default_rng(3))
    b = execute(problem, plan, noisy, np.random.default_rng(3))
    assert np.array_equal(a.positions, b.positions)


def test_an_ideal_run_draws_nothing_and_needs_no_generator():
    problem, plan = _two()
    assert execute(problem, plan, SimParams(settle_time=0.5)).ok


def test_the_scenario_makes_the_run_generator_from_its_seed():
    sc = read_scenario(FIG2)
    assert sc.generator().integers(1 << 30) == np.random.default_rng(sc.seed).integers(1 << 30)
    assert sc.generator(7).integers(1 << 30) == np.random.default_rng(7).integers(1 << 30)
    assert sc.generator(7).integers(1 << 30) != sc.generator(8).integers(1 << 30)  # the seed matters


def test_the_planner_needs_the_run_generator_too():
    from planner import PlannerParams, plan

    problem, _ = _two()
    with pytest.raises(ValueError, match="rng"):
        plan(problem, PlannerParams(time_limit=5))
    found, stats = plan(problem, PlannerParams(time_limit=5), np.random.default_rng(0))
    assert stats.found and found.m == 2
