"""Contacts that begin and end inside one step: both witnesses must see them.

Each case has its negative control: with the swept check (and the speed
guard) off the contact is missed, which is what these tests guard against.
"""

import numpy as np
import pytest

from planner.plan import Plan
from planner.problem import Circle, Polygon, Problem
from sim.execute.guard import SpeedGuard
from sim.execute.monitor import GapMonitor
from sim.execute.physics import execute
from sim.scenario.params import Impulse, SimParams

R = 0.5
DT = 1.0 / 60.0
THIN = Polygon(np.array([[50.0, 40.0], [50.1, 40.0], [50.1, 60.0], [50.0, 60.0]]))


def _problem(start, obstacles=(), size=100.0):
    start = np.asarray(start, float)
    return Problem(size, size, tuple(obstacles), R, 0.1, start, start)


def _observe(problem, p0, p1, swept=True):
    monitor = GapMonitor(problem)
    monitor.swept = swept
    monitor.observe(np.array([0.0, DT]), np.array([p0, p1], float))
    return monitor


def _pass(offset):
    """Two discs passing each other at 1500 units/s relative speed within one sample step."""
    p0 = [[45.0, 50.0], [55.0, 50.0 + offset]]
    p1 = [[57.5, 50.0], [42.5, 50.0 + offset]]
    return _problem(p0), p0, p1


# -- (b), (c): discs passing through each other between samples ------------------------


def test_discs_passing_through_each_other_between_samples_are_caught():
    problem, p0, p1 = _pass(0.3)
    monitor = _observe(problem, p0, p1)
    assert monitor.min_gap > 0  # both samples are clear
    (c,) = monitor.contacts()
    assert (c.kind, c.a, c.b, c.witness, c.swept) == ("robot-robot", 0, 1, "monitor", True)
    assert c.time == pytest.approx(DT * 10.0 / 25.0)  # 45 + 750 t = 55 - 750 t
    assert c.depth == pytest.approx(2 * R - 0.3)
    assert monitor.swept_min_gap == pytest.approx(0.3 - 2 * R)
    assert c.to_dict()["swept"] is True and "between samples" in c.describe()


def test_negative_control_the_sampled_check_alone_misses_it():
    problem, p0, p1 = _pass(0.3)
    assert _observe(problem, p0, p1, swept=False).contacts() == []


def test_a_fast_near_miss_is_no_contact():
    problem, p0, p1 = _pass(2 * R + 0.01)
    monitor = _observe(problem, p0, p1)
    assert monitor.contacts() == [] and monitor.swept_min_gap == float("inf")


def test_sweep_along_substeps_and_its_time():
    # The path of one step given with its substeps (as the loops do when bodies are fast).
    problem, p0, p1 = _pass(0.3)
    s = np.linspace(0.0, 1.0, 5)[:, None, None]
    path = np.asarray(p0)[None] + s * (np.asarray(p1) - np.asarray(p0))[None]
    monitor = GapMonitor(problem)
    monitor.sweep(s[:, 0, 0] * DT, path)
    monitor.observe(np.array([0.0, DT]), path[[0, -1]])  # the step is covered: not swept twice
    (c,) = monitor.contacts()
    assert c.time == pytest.approx(DT * 0.4) and c.depth == pytest.approx(2 * R - 0.3)


def test_slow_moves_touching_at_a_sample_are_the_sampled_checks():
    # Touching at the end sample: an ordinary contact, not a second swept one.
    p0 = [[45.0, 50.0], [55.0, 50.0]]
    p1 = [[49.6, 50.0], [50.4, 50.0]]
    monitor = _observe(_problem(p0), p0, p1)
    assert [c.swept for c in monitor.contacts()] == [False]


# -- (d): a moving disc against a segment and a circle ----------------------------------------


def test_jump_through_a_thin_wall_obstacle():
    p0, p1 = [[45.0, 50.0]], [[55.0, 50.0]]
    problem = _problem(p0, (THIN,))
    (c,) = _observe(problem, p0, p1).contacts()
    assert (c.kind, c.a, c.b) == ("robot-obstacle", 0, 0)
    assert c.depth == pytest.approx(R) and 0.0 < c.time < DT
    assert _observe(problem, p0, p1, swept=False).contacts() == []
    # passing beyond the wall's end, farther than the radius: nothing
    assert _observe(problem, [[45.0, 60.6]], [[55.0, 60.6]]).contacts() == []


def test_jump_through_a_circle():
    p0, p1 = [[45.0, 50.5]], [[55.0, 50.5]]
    problem = _problem(p0, (Circle((50.0, 50.0), 1.0),))
    (c,) = _observe(problem, p0, p1).contacts()
    assert (c.kind, c.a, c.b) == ("robot-obstacle", 0, 0)
    assert c.depth == pytest.approx(1.0) and c.time == pytest.approx(0.5 * DT)
    assert _observe(problem, p0, p1, swept=False).contacts() == []
    assert _observe(problem, [[45.0, 51.6]], [[55.0, 51.6]]).contacts() == []  # gap 0.1 at best


# -- (a): the jump-through in the realistic loop ----------------------------------------------

H = DT / 4
KICK = 1680.0  # N s on a mass-1 robot: 7 units in one physics step of 1/240 s


def _jump(monkeypatch, *, swept=True, guard=True, subdivide=True):
    monkeypatch.setattr(GapMonitor, "swept", swept)
    monkeypatch.setattr(SpeedGuard, "enabled", guard)
    monkeypatch.setattr(SpeedGuard, "subdivide", subdivide)
    start = np.array([[10.0, 10.0], [11.2, 10.0]])
    problem = Problem(30.0, 20.0, (), R, 0.1, start, start)
    plan = Plan.from_waypoints(np.array([start, start]), R, 0.1, 2.0, 2.0)
    t = 30 * H
    params = SimParams(kp=0.0, kd=0.0, settle_time=0.5, tolerance=10.0,
                       disturbances=(Impulse(0, t, (KICK, 0.0)), Impulse(0, t + H, (-KICK, 0.0))))
    return execute(problem, plan, params, np.random.default_rng(0))


def test_negative_control_both_witnesses_miss_the_jump_through(monkeypatch):
    report = _jump(monkeypatch, swept=False, guard=False)
    assert report.contacts == () and report.ok  # robot 0 went through robot 1 unseen
    assert report.positions[-1, 0, 0] == pytest.approx(17.0)


def test_the_jump_through_is_caught_and_fails_the_run(monkeypatch):
    report = _jump(monkeypatch)
    assert not report.ok
    assert "pymunk" in {c.witness for c in report.contacts}  # pymunk ran in pieces and saw it
    assert report.speed_warnings == ()


def test_without_pieces_the_monitor_still_sees_it_and_the_verdict_warns(monkeypatch):
    report = _jump(monkeypatch, subdivide=False)
    assert not report.ok
    seen = [(c.witness, c.kind, c.a, c.b, c.swept) for c in report.contacts]
    assert seen == [("monitor", "robot-robot", 0, 1, True)]
    assert report.contacts[0].depth == pytest.approx(2 * R)  # straight through the centre
    assert report.speed_warnings and "tunnelling possible: robot 0" in report.speed_warnings[0]
    d = report.to_dict()
    assert d["speed_warnings"] and "speed warning" in d["verdict"]


def test_ordinary_runs_are_not_watched(monkeypatch):
    calls = []
    monkeypatch.setattr(SpeedGuard, "step", lambda self, t: calls.append(t))
    start = np.array([[2.0, 2.0], [5.0, 2.0]])
    target = np.array([[2.0, 6.0], [5.0, 6.0]])
    problem = Problem(10.0, 10.0, (), R, 0.1, start, target, 2.0, 2.0)
    plan = Plan.from_waypoints(np.array([start, target]), R, 0.1, 2.0, 2.0)
    report = execute(problem, plan, SimParams(settle_time=0.5))
    assert report.ok and calls == []
