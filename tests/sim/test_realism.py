"""Each realism knob acts, with closed-form expectations where the physics allows.

Chipmunk moves a body with the velocity it had at the start of a physics
step and only then adds ``F h / m``.  So under a force held over two control
steps the second difference of the sampled positions is exactly
``a dt^2``, and a body that coasts moves by ``v h`` per physics step.
"""

import math

import numpy as np
import pytest

from planner.plan import Plan
from planner.problem import Problem
from sim.execute.physics import _execute, execute
from sim.execute.real import execute_real as _execute_real
from sim.execute.realism import (
    ControlClock,
    DelayLine,
    Events,
    G,
    Resistance,
    Sensor,
    real_masses,
    resistive_forces,
    streams,
)
from sim.scenario.params import Failure, Impulse, Noise, Pushes, Sensing, SimParams

R = 0.5
MARGIN = 0.1


def _world(waypoints, size=20.0, max_speed=2.0, max_accel=2.0):
    w = np.asarray(waypoints, float)
    if w.ndim == 2:
        w = w[None]
    problem = Problem(size, size, (), R, MARGIN, w[0], w[-1], max_speed, max_accel)
    plan = Plan.from_waypoints(w, R, MARGIN, max_speed, max_accel)
    return problem, plan


def _second_difference(report, robot=0, axis=0):
    x = report.positions[:, robot, axis]
    return x[2:] - 2 * x[1:-1] + x[:-2]


# -- the pieces --------------------------------------------------------------------


def test_streams_are_independent_of_draws_and_reproducible():
    a = np.random.default_rng(7)
    b = np.random.default_rng(7)
    b.random(1000)  # used by something else first (the planner, say)
    sa, sb = streams(a), streams(b)
    for key in ("masses", "noise", "pushes", "replan", "sensing"):
        assert np.array_equal(sa[key].random(5), sb[key].random(5))
    assert not np.array_equal(streams(np.random.default_rng(7))["noise"].random(5),
                              streams(np.random.default_rng(8))["noise"].random(5))


def test_real_masses_are_within_the_error():
    masses = real_masses(2.0, 0.1, 10_000, np.random.default_rng(0))
    assert masses.min() >= 1.8 and masses.max() <= 2.2
    assert masses.mean() == pytest.approx(2.0, abs=0.01)
    assert np.std(masses) == pytest.approx(0.4 / math.sqrt(12), rel=0.05)  # uniform on [1.8, 2.2]
    assert np.array_equal(real_masses(2.0, 0.0, 3, np.random.default_rng(0)), [2.0, 2.0, 2.0])


def test_sensor_noise_has_its_standard_deviation_and_leaves_the_state():
    state = np.tile([1.0, 2.0, 0.5, -0.5], (20_000, 1))
    before = state.copy()
    meas = Sensor(0.02, 0.3, np.random.default_rng(0)).measure(state)
    assert np.array_equal(state, before)
    err = meas - state
    assert err[:, :2].std() == pytest.approx(0.02, rel=0.03)
    assert err[:, 2:].std() == pytest.approx(0.3, rel=0.03)
    assert abs(err.mean(axis=0)).max() < 0.01
    assert np.array_equal(Sensor(0.0, 0.0, None).measure(state), state)


def test_control_clock_updates_at_its_rate_on_physics_steps():
    h = 1 / 240
    clock = ControlClock(50.0, 1 / 60)
    due = [n for n in range(240) if clock.due(n * h)]
    assert len(due) == 50  # 50 updates in one second
    gaps = np.diff(due)
    assert set(gaps.tolist()) <= {4, 5}  # 4.8 steps on average, whole steps each
    assert [n * h for n in due[:3]] == pytest.approx([0.0, 5 * h, 10 * h])
    every = ControlClock(None, 1 / 60)
    assert [n for n in range(16) if every.due(n * h)] == [0, 4, 8, 12]


def test_delay_line_returns_the_newest_due_force():
    line = DelayLine(0.1)
    line.put(0.0, "a")
    line.put(0.05, "b")
    assert line.take(0.09) is None
    assert line.take(0.1) == "a"
    assert line.take(0.2) == "b"
    assert line.take(0.3) is None


def test_resistance_decelerates_at_its_limit_and_stops_without_reversing():
    h = 0.01
    masses = np.array([2.0, 2.0, 2.0])
    limit = np.array([4.0, 4.0, 4.0])  # 2 units/s^2
    vel = np.array([[1.0, 0.0], [0.01, 0.0], [0.0, 0.0]])
    force = np.array([[0.0, 0.0], [0.0, 0.0], [3.0, 0.0]])
    f = resistive_forces(vel, force, masses, limit, h)
    assert f[0] == pytest.approx([-4.0, 0.0])  # sliding: the full limit against the motion
    assert f[1] == pytest.approx([-2.0, 0.0])  # stops within the step: exactly what stops it
    assert f[2] == pytest.approx([-3.0, 0.0])  # at rest, pushed by less than the limit: holds
    r = Resistance(masses, h, limit)
    assert np.array_equal(r(vel, force), f)
    # The velocity each would reach: decelerated by 2 h, zero, zero.
    v1 = vel + (force + f) * h / masses[:, None]
    assert v1[:, 0] == pytest.approx([1.0 - 2 * h, 0.0, 0.0], abs=1e-15)


def test_pushes_are_a_poisson_process_of_the_rate():
    params = SimParams(pushes=Pushes(rate=0.5, impulse=2.0))
    events = Events(params, 20, np.random.default_rng(3))
    got = []
    h = 1 / 240
    for n in range(int(100 / h)):
        got += events.due(n * h)
    assert len(got) == pytest.approx(0.5 * 20 * 100, rel=0.1)  # 1000 expected, sd 32
    imp = np.array([e.impulse for e in got])
    assert np.linalg.norm(imp, axis=1) == pytest.approx(2.0)
    assert abs(imp.mean(axis=0)).max() < 0.15  # uniform directions
    robots = np.bincount([e.robot for e in got], minlength=20)
    assert robots.min() > 20  # spread over all robots (50 each expected)
    assert all(e.kind == "push" for e in got)
    # The same generator gives the same pushes; how far one looks ahead does not matter.
    again = Events(params, 20, np.random.default_rng(3))
    first = [again.due(n * h) for n in range(int(10 / h))]
    assert [e for es in first for e in es] == [e for e in got if e.time < 10 - 1e-9]


def test_scheduled_events_fall_due_in_time_order():
    params = SimParams(disturbances=(Impulse(1, 0.5, (1.0, 0.0)), Impulse(0, 0.2, (0.0, 2.0))),
                       failures=(Failure(2, 0.3),))
    events = Events(params, 3, None)
    h = 0.1
    seen = [(round(n * h, 6), e.kind, e.robot) for n in range(8) for e in events.due(n * h)]
    assert seen == [(0.2, "impulse", 0), (0.3, "failure", 2), (0.5, "impulse", 1)]


# -- in the physics world ------------------------------------------------------------


def test_realistic_loop_with_nothing_on_is_the_ideal_loop():
    problem, plan = _world([[[2.0, 2.0], [2.0, 5.0]], [[8.0, 3.0], [6.0, 9.0]], [[3.0, 3.0], [9.0, 9.0]]])
    params = SimParams(settle_time=0.5)
    a = _execute(problem, plan, params, None)
    b = _execute_real(problem, plan, params, np.random.default_rng(0), None, None)
    for key in ("times", "positions", "tracking_error", "min_gap"):
        assert np.array_equal(getattr(a, key), getattr(b, key)), key
    assert a.to_dict() | {"wall_time_s": 0, "realtime_factor": 0} == b.to_dict() | {"wall_time_s": 0,
                                                                                    "realtime_factor": 0}


@pytest.mark.parametrize("real", [False, True], ids=["ideal-loop", "realistic-loop"])
def test_saturation_lowers_the_acceleration_to_force_over_mass(real):
    # A plan that asks for about 1000 units/s^2; 5 N on a mass of 2 gives 2.5.
    problem, plan = _world([[[2.0, 10.0]], [[12.0, 10.0]]], max_speed=1000.0, max_accel=1000.0)
    free = execute(problem, plan, SimParams(mass=2.0, force_limit=1e6, settle_time=0.0))
    params = SimParams(mass=2.0, force_limit=5.0, settle_time=0.0)
    if real:
        limited = _execute_real(problem, plan, params, np.random.default_rng(0), None, None)
    else:
        limited = execute(problem, plan, params)
    dt = params.dt
    acc_free = np.abs(_second_difference(free)).max() / dt**2
    acc = _second_difference(limited)[3:10] / dt**2  # saturated, speeding up
    assert acc == pytest.approx(np.full(7, 2.5), rel=1e-9)
    assert acc_free > 100 * 2.5


def test_saturation_uses_the_real_mass():
    problem, plan = _world([[[2.0, 10.0]], [[12.0, 10.0]]], max_speed=1000.0, max_accel=1000.0)
    params = SimParams(mass=2.0, force_limit=5.0, mass_error=0.3, settle_time=0.0)
    report = execute(problem, plan, params, np.random.default_rng(4))
    m_real = float(report.masses[0])
    assert m_real != 2.0 and 1.4 <= m_real <= 2.6
    acc = _second_difference(report)[3:10] / params.dt**2
    assert acc == pytest.approx(np.full(7, 5.0 / m_real), rel=1e-9)


def _coast(params, impulse=(2.0, 0.0), settle=3.0, rng=0):
    problem, plan = _world([[10.0, 10.0]])
    params = SimParams(**{"settle_time": settle, "kp": 0.0, "kd": 0.0,
                          "disturbances": (Impulse(0, 0.0, impulse),), **params})
    return execute(problem, plan, params, np.random.default_rng(rng))


def test_an_impulse_changes_the_velocity_by_impulse_over_mass():
    report = _coast({"mass_error": 0.2, "mass": 1.5}, impulse=(0.9, -0.6), settle=1.0)
    m_real = float(report.masses[0])
    assert m_real != 1.5
    v = np.diff(report.positions[:, 0], axis=0) / SimParams().dt
    assert v == pytest.approx(np.tile(np.array([0.9, -0.6]) / m_real, (len(v), 1)), rel=1e-9)
    d = report.to_dict()["disturbances"]
    assert d["impulses"] == 1 and d["list"] == [{"kind": "impulse", "robot": 0, "time": 0.0,
                                                  "impulse": [0.9, -0.6]}]


def test_friction_decelerates_a_coasting_body_at_mu_g_and_holds_it_at_rest():
    mu = 0.2
    report = _coast({"friction": mu})
    dt = SimParams().dt
    a = _second_difference(report)[:20] / dt**2
    assert a == pytest.approx(np.full(20, -mu * G), rel=1e-9)
    x = report.positions[:, 0, 0] - 10.0
    v0 = 2.0
    stop = v0 / (mu * G)  # 1.02 s
    assert x[-1] == pytest.approx(v0**2 / (2 * mu * G), abs=v0 * dt)
    after = report.times > stop + dt
    assert np.all(x[after] == x[-1])  # at rest, no creeping or chatter
    assert np.all(report.positions[:, 0, 1] == 10.0)


def test_a_failed_robot_brakes_at_the_force_limit_and_stays():
    problem, plan = _world([[[2.0, 10.0]], [[18.0, 10.0]]])
    params = SimParams(force_limit=1.0, failures=(Failure(0, 4.0),), settle_time=0.0)
    report = execute(problem, plan, params, np.random.default_rng(0))
    dt = params.dt
    k = int(round(4.0 / dt))
    a = _second_difference(report)[k + 1 : k + 20] / dt**2
    assert a == pytest.approx(np.full(19, -1.0), rel=1e-9)  # 1 N on a mass of 1
    x = report.positions[:, 0, 0]
    assert np.all(x[-30:] == x[-1])
    assert not report.reached_robots[0] and report.failed == (0,)
    assert np.all(np.isnan(report.tracking_error[k + 1 :, 0]))
    assert report.to_dict()["disturbances"]["failures"] == 1


def _delay(latency: float) -> float:
    """Time from an impulse until the robot's path first leaves the straight coasting line."""
    problem, plan = _world([[10.0, 10.0]])
    t0 = 0.5
    params = SimParams(settle_time=1.5, latency=latency, disturbances=(Impulse(0, t0, (0.5, 0.0)),))
    report = execute(problem, plan, params, np.random.default_rng(0))
    x = report.positions[:, 0, 0]
    after = report.times >= t0 - 1e-9
    line = 10.0 + 0.5 * (report.times - t0)
    off = np.flatnonzero(after & (np.abs(x - line) > 1e-12))
    return float(report.times[off[0]] - t0)


def test_latency_delays_the_response_by_the_latency():
    base = _delay(0.0)
    dt = SimParams().dt
    assert base == pytest.approx(dt)  # the reaction shows in the next sample
    for latency in (0.05, 0.1, 0.25):
        assert _delay(latency) - base == pytest.approx(latency, abs=dt / 2)


def test_noise_moves_the_measurement_not_the_body():
    problem, plan = _world([[[5.0, 5.0], [9.0, 9.0]]])
    still = execute(problem, plan, SimParams(kp=0.0, kd=0.0, noise=Noise(0.1, 0.1), settle_time=2.0),
                    np.random.default_rng(0))
    assert np.all(still.positions == plan.start)  # no controller reaction: never moved
    driven = execute(problem, plan, SimParams(noise=Noise(0.02, 0.0), settle_time=2.0, kp=50.0, kd=14.0,
                                              sensing=Sensing(estimator="oracle")),  # measured true velocity
                     np.random.default_rng(0))
    moved = np.linalg.norm(driven.positions - plan.start, axis=2)
    # The controller reacts to noisy measurements, so the bodies move, far
    # less than the noise itself (the loop filters it).
    assert 1e-5 < moved.max() < 0.02
    assert driven.max_tracking_error == pytest.approx(moved.max())


def test_control_rate_holds_the_force_between_updates():
    problem, plan = _world([[[2.0, 10.0]], [[8.0, 10.0]]])
    ideal = execute(problem, plan, SimParams(settle_time=0.0))
    held = execute(problem, plan, SimParams(settle_time=0.0, control_rate=10.0), np.random.default_rng(0))
    d = _second_difference(held)  # d[i] belongs to sample i + 1
    per = 6  # 0.1 s of samples of 1/60 s
    windows = [d[per * j : per * j + per - 1] for j in range(1, len(d) // per - 1)]
    for w in windows:  # samples 6j+1 .. 6j+5: the force held since the update at 6j
        assert np.ptp(w) <= 1e-12 * max(1.0, np.abs(w).max())
    firsts = [w[0] for w in windows]
    assert np.ptp(firsts) > 1e-3  # and it changes from one update to the next
    di = _second_difference(ideal)
    assert all(np.ptp(di[per * j : per * j + per - 1]) > 1e-9 for j in range(1, 5))  # every step


def test_tracking_error_is_measured_while_settling_too():
    problem, plan = _world([[[2.0, 10.0]], [[6.0, 10.0]]])
    t_kick = plan.makespan + 0.5
    params = SimParams(settle_time=2.0, disturbances=(Impulse(0, t_kick, (0.0, 1.0)),))
    report = execute(problem, plan, params, np.random.default_rng(0))
    assert report.max_tracking_error_time > plan.makespan
    assert report.max_tracking_error_time == pytest.approx(t_kick, abs=0.1)
    assert report.max_tracking_error > 0.01
    assert report.tracking_error.shape == (len(report.times), 1)
    # Negative control: the same plan without the kick tracks to within 1e-3 throughout.
    calm = execute(problem, plan, SimParams(settle_time=2.0))
    assert calm.max_tracking_error < 1e-3


def test_phase_margin_flags_gains_too_high_for_the_latency():
    from sim.execute.realism import phase_margin

    # kp = 400, kd = 40 cross over at 41 rad/s: 40 ms of latency and 10 ms of
    # hold cost 118 degrees, more than the 76 the derivative gives.
    assert phase_margin(400.0, 40.0, 0.05) == pytest.approx(-41.6, abs=0.1)
    assert phase_margin(50.0, 14.0, 0.05) == pytest.approx(34.8, abs=0.1)
    problem, plan = _world([[[2.0, 10.0]], [[6.0, 10.0]]])
    shaky = execute(problem, plan, SimParams(latency=0.04, control_rate=50.0), np.random.default_rng(0))
    assert shaky.phase_margin_deg < 0 and "unstable" in shaky.verdict
    assert shaky.max_tracking_error > 0.01  # it rings
    steady = execute(problem, plan, SimParams(latency=0.04, control_rate=50.0, kp=50.0, kd=14.0),
                     np.random.default_rng(0))
    assert steady.phase_margin_deg > 30 and "unstable" not in steady.verdict
    assert steady.ok
