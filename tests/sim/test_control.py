"""PD control with feed-forward: closed-form checks and tracking in pymunk."""

import numpy as np
import pymunk
import pytest

from planner.plan import Plan
from planner.problem import Problem
from sim.execute.control import pd_acceleration, reference_chunk
from sim.execute.physics import execute
from sim.scenario.params import SimParams


def test_pd_acceleration_closed_form():
    pos = np.array([[0.0, 0.0], [1.0, 1.0]])
    vel = np.array([[0.0, 0.0], [0.5, 0.0]])
    ref_pos = np.array([[0.01, 0.0], [1.0, 1.0]])
    ref_vel = np.array([[0.0, 0.0], [0.5, 0.0]])
    acc_ff = np.array([[0.0, 0.0], [0.3, -0.4]])
    a = pd_acceleration(pos, vel, ref_pos, ref_vel, acc_ff, kp=400.0, kd=40.0, limit=200.0)
    assert a == pytest.approx(np.array([[4.0, 0.0], [0.3, -0.4]]))


def test_pd_acceleration_is_limited_in_magnitude_not_direction():
    pos = np.zeros((1, 2))
    a = pd_acceleration(pos, pos, np.array([[3.0, 4.0]]), pos, pos, kp=400.0, kd=40.0, limit=10.0)
    assert np.linalg.norm(a) == pytest.approx(10.0)
    assert a[0] == pytest.approx([6.0, 8.0])


def test_reference_holds_the_end_after_the_makespan():
    plan = Plan.from_waypoints([[[0.0, 0.0]], [[2.0, 0.0]]], 0.5, 0.1, 2.0, 2.0)
    dt = 0.05
    k0 = int(plan.makespan / dt) - 2
    ref = reference_chunk(plan, k0, 10, dt)
    assert ref.pos.shape == (11, 1, 2) and ref.acc_ff.shape == (10, 1, 2)
    assert np.allclose(ref.pos[-1], [[2.0, 0.0]])
    assert np.all(ref.vel[-5:] == 0) and np.all(ref.acc_ff[-5:] == 0)
    # The feed-forward is the reference acceleration mid-step.
    mid = plan.sample((k0 + np.arange(10) + 0.5) * dt)[2]
    assert np.array_equal(ref.acc_ff, mid)


def test_chipmunk_moves_before_it_accelerates():
    # The timing the controller is designed around: a force set before a
    # step changes that step's velocity, and the position only from the next.
    space = pymunk.Space()
    body = pymunk.Body(2.0, 1.0)
    space.add(body, pymunk.Circle(body, 0.5))
    body.force = (4.0, 0.0)
    space.step(0.1)
    assert tuple(body.position) == (0.0, 0.0)
    assert body.velocity.x == pytest.approx(0.2)
    assert tuple(body.force) == (0.0, 0.0)  # cleared after every step
    space.step(0.1)
    assert body.position.x == pytest.approx(0.02)


@pytest.mark.parametrize("dt, substeps", [(1 / 60, 4), (1 / 30, 4), (1 / 120, 2)])
def test_tracking_at_the_speed_and_acceleration_limits(dt, substeps):
    # Long moves reach max_speed, short ones max_accel; corners in between.
    w = np.array([[[1.0, 1.0]], [[19.0, 1.0]], [[19.0, 1.5]], [[2.0, 15.0]], [[2.3, 15.0]]])
    problem = Problem(20.0, 20.0, (), 0.5, 0.1, w[0], w[-1])
    plan = Plan.from_waypoints(w, 0.5, 0.1, problem.max_speed, problem.max_accel)
    _, v, a = plan.sample(np.linspace(0, plan.makespan, 4001))
    assert np.linalg.norm(v, axis=2).max() == pytest.approx(2.0, rel=1e-3)
    assert np.linalg.norm(a, axis=2).max() == pytest.approx(2.0, rel=1e-2)
    report = execute(problem, plan, SimParams(dt=dt, substeps=substeps, settle_time=0.5))
    assert report.ok
    assert report.max_tracking_error < 2e-3
    assert report.final_error < 1e-4
