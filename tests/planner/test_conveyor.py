"""The door stage (planner/conveyor.py): trains through a door one robot wide."""

from __future__ import annotations

import math
import time

import numpy as np
import pytest

from bench.frontier import CASES, _free, _shell, case_problem
from planner import PlannerParams, plan
from planner.conveyor import door_plan, door_waypoints
from planner.cutbound import cut_lower_bound
from planner.gridstage import step_separated
from planner.plan import Plan
from planner.problem import Polygon, Problem
from planner.validate import check_plan


def _door(m: int = 200, width: float = 2.2, seed: int = 0) -> Problem:
    case = next(c for c in CASES if c.name == f"door-{width:g}-m200")
    p = case_problem(case, seed)
    if m == p.m:
        return p
    return Problem(p.width, p.height, p.obstacles, p.radius, p.margin, p.start[:m], p.target[:m]).validate()


def _slanted(theta_deg: float, m: int, width: float = 2.2, side: float = 60.0, seed: int = 0) -> Problem:
    """A wall 2 thick through the middle at ``theta_deg``, one door ``width`` wide in it."""
    import shapely.geometry as sg

    th = math.radians(theta_deg)
    d = np.array([math.cos(th), math.sin(th)])
    n = np.array([-d[1], d[0]])
    mid = np.array([side / 2, side / 2])
    box = sg.box(0, 0, side, side)
    obs = []
    for a, b in ((-side, -width / 2), (width / 2, side)):
        piece = sg.Polygon([mid - d + n * a, mid + d + n * a, mid + d + n * b, mid - d + n * b]).intersection(box)
        obs.append(Polygon(np.array(piece.exterior.coords)[:-1]))
    shell = _shell(side, side, tuple(obs))
    rng = np.random.default_rng(seed)
    start = _free(shell, m, rng, avoid=lambda p: (p - mid) @ d > -2.1)
    target = _free(shell, m, rng, avoid=lambda p: (p - mid) @ d < 2.1)
    return Problem(side, side, tuple(obs), 1.0, 0.1, start, target).validate()


def _check(p: Problem, found) -> float:
    w, _ = found
    result = Plan.from_waypoints(w, p.radius, p.margin, p.max_speed, p.max_accel)
    check_plan(p, result)  # raises on any contact
    return result.makespan / cut_lower_bound(p)


def test_door_at_the_limit_within_3x_the_cut_bound():
    p = _door(200, 2.2)
    found = door_plan(p, time.perf_counter() + 60)
    assert found is not None
    assert _check(p, found) <= 3.0


@pytest.mark.parametrize("theta", [90.0, 30.0, 45.0])
def test_slanted_doors(theta):
    """The grid lives in the cut's frame: walls at any angle, rounding at the limit."""
    p = _slanted(theta, 120)
    found = door_plan(p, time.perf_counter() + 60)
    assert found is not None
    assert _check(p, found) <= 3.2


def test_plan_uses_the_door_stage():
    p = _door(80, 2.2)
    result, stats = plan(p, PlannerParams(time_limit=30), np.random.default_rng(0))
    assert stats.extra["direct"] == "door"
    assert result.makespan <= 3.2 * stats.makespan_lower_bound_cut_s


def test_no_door_no_stage():
    """Negative control: a door two robots wide is no single-file cut."""
    p = _door(60, 2.2)
    wide = Problem(p.width, p.height, (Polygon([[29, 0], [31, 0], [31, 27.0], [29, 27.0]]),
                                       Polygon([[29, 33.0], [31, 33.0], [31, 60], [29, 60]])),
                   p.radius, p.margin, p.start, p.target).validate()
    assert door_waypoints(wide, time.perf_counter() + 30) is None


def test_trains_too_tight_are_refused():
    """Negative control of the step check: on a grid finer than the separation the stage
    gives up (its exact step test catches the train), and the test itself flags a train
    whose robots are closer than the separation."""
    p = _door(60, 2.2)
    assert door_waypoints(p, time.perf_counter() + 30, c=0.97 * p.separation) is None
    a = np.array([[10.0, 30.0], [10.0 + 0.97 * p.separation, 30.0]])
    assert step_separated(p, a, a + [5.0, 0.0], 5.0 + 1e-9) is False
    ok = np.array([[10.0, 30.0], [10.0 + p.separation, 30.0]])
    assert step_separated(p, ok, ok + [5.0, 0.0], 5.0 + 1e-9) is True
