"""Estimated state (:mod:`sim.execute.estimate`): the filter's equations, the sensor's
dropouts, jitter and bias, what the controller sees, and the failure detection delay.

Every effect is checked against its negative control: the same case without it.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from planner import PlannerParams, Problem
from planner.plan import Plan
from sim.execute.estimate import DEFAULT_FAILURE_DELAY, Estimator, PositionSensor, alpha_beta_gains
from sim.execute.physics import execute
from sim.execute.realism import ControlClock, streams
from sim.scenario import ScenarioError
from sim.scenario.params import Failure, Noise, Recovery, Sensing, SimParams

T = 1.0 / 60.0
V = np.array([1.0, -0.5])  # [units/s]


def _filter(m=200, sigma=0.1, dropout=0.0, jitter=0.0, drift=0.0, q=100.0, kind="kalman", seed=0):
    sensor = PositionSensor(m, sigma, dropout, jitter, drift, np.random.default_rng(seed),
                            np.random.default_rng(seed + 1))
    return Estimator(sensor, ControlClock(1 / T, T), np.zeros((m, 2)), q, kind)


def _track(est, steps=600, sample=lambda k: True):
    """Constant-velocity robots from the origin; returns (times, estimates, truths)."""
    m = len(est.x)
    out = []
    for k in range(steps):
        t = k * T
        truth = np.tile(V * t, (m, 1))
        if sample(k):
            est.sample(t, truth)
        out.append((t, est.update(t), truth))
    return out


# -- the filter's equations ----------------------------------------------------------------


@pytest.mark.parametrize("kind", ["kalman", "alpha_beta"])
def test_a_constant_velocity_track_converges(kind):
    out = _track(_filter(sigma=0.0, kind=kind), steps=240)
    _, x, truth = out[-1]
    assert np.abs(x[:, :2] - truth).max() < 1e-3
    assert np.abs(x[:, 2:] - V).max() < 1e-2
    # negative control: it started at rest, 1 unit/s off
    assert np.abs(out[0][1][:, 2:] - V).max() > 0.5


def test_velocity_under_noise_is_far_better_than_differencing():
    sigma = 0.1
    out = _track(_filter(sigma=sigma))
    est = np.array([x[:, 2:] - V for _, x, _ in out[300:]])
    rms = float(np.sqrt((est ** 2).mean()))
    # negative control: differencing two noisy positions 1/60 s apart
    rng = np.random.default_rng(3)
    z = np.array([np.tile(V * t, (200, 1)) for t, _, _ in out]) + rng.standard_normal((600, 200, 2)) * sigma
    diff = float(np.sqrt((((z[1:] - z[:-1]) / T - V) ** 2).mean()))
    assert diff == pytest.approx(math.sqrt(2) * sigma / T, rel=0.02)  # 8.5 units/s
    assert rms < diff / 5, (rms, diff)
    pos = np.array([x[:, :2] - truth for _, x, truth in out[300:]])
    assert float(np.sqrt((pos ** 2).mean())) < sigma  # the position is filtered too


def test_a_dropped_measurement_keeps_predicting():
    est = _filter(sigma=0.0)
    out = _track(est, steps=240, sample=lambda k: k < 200)  # no measurement after 200
    _, x, truth = out[-1]
    assert np.abs(x[:, :2] - truth).max() < 1e-3  # predicted along the velocity
    frozen = out[199][1][:, :2]  # negative control: holding the last estimate
    assert np.abs(frozen - truth).max() > 0.5
    assert est.pp[0] > 1e-6  # the uncertainty grew meanwhile


def test_alpha_beta_gains_are_the_steady_state_of_a_stable_filter():
    alpha, beta = alpha_beta_gains(100.0, T, 0.1)
    assert 0 < alpha < 1 and 0 < beta < 2 and beta < 4 - 2 * alpha  # Bar-Shalom's stability region


def test_a_delayed_measurement_is_used_at_its_own_time():
    # Measurements reach the filter up to 0.1 s late; with H = [1, -d] the estimate does not lag.
    est = _filter(sigma=0.0, jitter=0.1)
    _, x, truth = _track(est, steps=300)[-1]
    assert np.abs(x[:, :2] - truth).max() < 2e-3
    # negative control: the lag of taking each measurement as current is speed * mean delay
    assert np.linalg.norm(V) * 0.05 > 0.05


def test_an_out_of_order_measurement_is_discarded():
    est = _filter(m=1, sigma=0.0)
    est.sensor.sample(0.10, np.array([[1.0, 0.0]]))
    est.sensor._pending[-1][2][:] = 0.30  # arrives late
    est.sensor.sample(0.20, np.array([[2.0, 0.0]]))
    est.update(0.25)
    used = est.last_taken.copy()
    est.update(0.30)
    assert used[0] == pytest.approx(0.20) and est.last_taken[0] == pytest.approx(0.20)


# -- the sensor --------------------------------------------------------------------------------


def test_dropout_loses_its_share_of_measurements():
    sensor = PositionSensor(100, 0.0, 0.3, 0.0, 0.0, None, np.random.default_rng(0))
    for k in range(200):
        sensor.sample(k * T, np.zeros((100, 2)))
    kept = sum(item[3].sum() for item in sensor._pending) / (100 * 200)
    assert kept == pytest.approx(0.7, abs=0.01)
    control = PositionSensor(100, 0.0, 0.0, 0.0, 0.0, None, np.random.default_rng(0))
    control.sample(0.0, np.zeros((100, 2)))
    assert control._pending[0][3].all()


def test_bias_drift_is_a_random_walk_of_its_size():
    sensor = PositionSensor(2000, 0.0, 0.0, 0.0, 0.5, None, np.random.default_rng(0))
    for k in range(241):
        sensor.sample(k * T, np.zeros((2000, 2)))
    assert sensor.bias.std() == pytest.approx(0.5 * math.sqrt(4.0), rel=0.05)
    assert not PositionSensor(2, 0.0, 0.0, 0.0, 0.0, None, None).bias.any()


def test_new_streams_leave_the_old_ones_alone():
    gens = streams(np.random.default_rng(11))
    old = np.random.default_rng(11).spawn(4)
    for name, child in zip(("masses", "noise", "pushes", "replan"), old):
        assert np.array_equal(gens[name].random(4), child.random(4))
    assert "sensing" in gens


# -- in the loop ---------------------------------------------------------------------------------


def _one_robot(settle=2.0):
    start, target = np.array([[2.0, 2.0], [2.0, 6.0]]), np.array([[8.0, 5.0], [8.0, 8.0]])
    problem = Problem(10.0, 10.0, (), 0.5, 0.1, start, target)
    return problem, Plan.from_waypoints(np.stack([start, target]), 0.5, 0.1, problem.max_speed, problem.max_accel)


def test_when_the_filter_is_on():
    assert not SimParams().estimating and not SimParams().realistic  # default runs: unchanged
    assert not SimParams(noise=Noise(0.0, 0.1)).estimating  # velocity noise only: the old sensor
    assert SimParams(noise=Noise(0.01, 0.0)).estimating
    assert SimParams(sensing=Sensing()).estimating and SimParams(sensing=Sensing()).realistic
    assert not SimParams(noise=Noise(0.01, 0.0), sensing=Sensing(estimator="oracle")).estimating


def test_the_controller_never_sees_the_true_velocity():
    problem, plan = _one_robot()
    runs = [execute(problem, plan, SimParams(noise=Noise(0.02, vel)), np.random.default_rng(0)) for vel in (0.0, 5.0)]
    assert np.array_equal(runs[0].positions, runs[1].positions)  # velocity is estimated, never measured
    oracle = [execute(problem, plan, SimParams(noise=Noise(0.02, vel), sensing=Sensing(estimator="oracle")),
                      np.random.default_rng(0)) for vel in (0.0, 5.0)]
    assert not np.array_equal(oracle[0].positions, oracle[1].positions)  # negative control


def test_dropout_and_bias_make_tracking_worse():
    problem, plan = _one_robot()

    def final(**kw):
        return execute(problem, plan, SimParams(noise=Noise(0.01, 0.0), sensing=Sensing(**kw)),
                       np.random.default_rng(1)).final_error

    base = final()
    assert final(bias_drift=0.05) > 2 * base  # the filter cannot see a bias
    assert final(dropout=0.9, rate=60.0) > base
    assert final(latency_jitter=0.05) < 0.05  # jitter is handled by the delayed update


def _failure_run(**sensing):
    # trigger 100: only the failure itself starts a replan (not the tracking error it causes)
    problem, plan = _one_robot()
    t_fail = 0.4 * plan.makespan
    params = SimParams(failures=(Failure(0, t_fail),), recovery=Recovery(replan=True, trigger=100.0), accept="working",
                       noise=Noise(0.005, 0.0), sensing=Sensing(**sensing))
    report = execute(problem, plan, params, np.random.default_rng(2), planner_params=PlannerParams())
    told = [r for r in report.replans if r.reason == "robot 0 failed"]
    assert told, report.verdict
    return told[0].time - t_fail


def test_a_failure_is_told_after_the_detection_delay():
    assert _failure_run() == pytest.approx(DEFAULT_FAILURE_DELAY, abs=2 * T)
    assert _failure_run(failure_delay=0.2) == pytest.approx(0.2, abs=2 * T)
    assert _failure_run(estimator="oracle") == pytest.approx(0.0, abs=2 * T)  # negative control


# -- settings ----------------------------------------------------------------------------------



def test_sensing_is_read(tmp_path, read_case):
    sc = read_case("""
        sim:
          sensing: {rate: 30, dropout: 0.1, latency_jitter: 0.02, bias_drift: 0.01, estimator: alpha_beta,
                    process_noise: 50, failure_delay: 0.3}
    """)
    assert sc.sim.sensing == Sensing(30.0, 0.1, 0.02, 0.01, "alpha_beta", 50.0, 0.3)
    assert read_case("").sim.sensing is None


@pytest.mark.parametrize("body, field, words", [
    ("sim: {sensing: {dropout: 1}}", "sim.sensing.dropout", "in [0, 1)"),
    ("sim: {sensing: {rate: 0}}", "sim.sensing.rate", "in (0, 10000]"),
    ("sim: {sensing: {latency_jitter: 2}}", "sim.sensing.latency_jitter", "in [0, 1]"),
    ("sim: {sensing: {bias_drift: -1}}", "sim.sensing.bias_drift", "in [0, 10]"),
    ("sim: {sensing: {estimator: ekf}}", "sim.sensing.estimator", "kalman, alpha_beta, oracle"),
    ("sim: {sensing: {failure_delay: 100}}", "sim.sensing.failure_delay", "in [0, 60]"),
    ("sim: {sensing: {process_noise: 0}}", "sim.sensing.process_noise", "in (0, 1e+08]"),
    ("sim: {sensing: {dropuot: 0.1}}", "sim.sensing.dropuot", "unknown key"),
])
def test_bad_sensing_names_the_field(tmp_path, body, field, words, read_case):
    with pytest.raises(ScenarioError) as info:
        read_case(body + "\n")
    assert info.value.field == field
    assert words in info.value.reason, info.value.reason
