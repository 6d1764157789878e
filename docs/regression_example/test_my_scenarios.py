"""Collision-verification regression tests for my scenarios, with swarmform's pytest fixture.

Run with ``python -m pytest docs/regression_example/test_my_scenarios.py``; the
``swarmform`` fixture comes with the package (no conftest.py needed).
"""

from pathlib import Path

import numpy as np
import pytest

from planner import Plan
from sim.scenario import build_problem, read_scenario

SCENARIOS = Path(__file__).resolve().parents[2] / "scenarios" / "paper"
FIG5 = SCENARIOS / "fig5-N-to-A.yaml"


def test_fig5_runs_clean(swarmform):
    report = swarmform(FIG5)
    swarmform.assert_ok(report)
    assert report["sim"]["contacts"] == 0
    assert report["plan"]["min_clearance"] >= report["margin"]


def test_fig5_with_a_wider_margin(swarmform):
    report = swarmform(FIG5, set={"robots.margin": 0.2}, seed=5)
    swarmform.assert_ok(report)
    assert report["margin"] == 0.2


def _colliding_plan(scenario: Path, folder: Path) -> Path:
    """A plan in which robots 0 and 1 swap places on straight lines: they meet halfway."""
    sc = read_scenario(scenario)
    problem = build_problem(sc, np.random.default_rng(sc.seed))
    swapped = problem.start.copy()
    swapped[[0, 1]] = problem.start[[1, 0]]
    plan = Plan.from_waypoints(np.array([problem.start, swapped]), problem.radius, problem.margin,
                               max_speed=2.0, max_accel=2.0)
    return plan.save(folder / "swap.json", extra={"seed": sc.seed})


def test_negative_control_a_colliding_plan_fails(swarmform, tmp_path):
    """The check is not blind: a plan made to collide must make assert_ok fail."""
    report = swarmform(FIG5, plan=_colliding_plan(FIG5, tmp_path))
    assert report["sim"]["contacts"] > 0
    with pytest.raises(AssertionError, match="contact"):
        swarmform.assert_ok(report)
