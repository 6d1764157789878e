"""Failures are always answered, an exhausted replan budget is named and fails the run, and the
verdict's accept rule (``sim.accept``): each with its negative control.
"""

from __future__ import annotations

import time

import numpy as np
import pytest

from planner import PlannerParams, Problem
from planner.plan import Plan
from sim.execute.physics import execute
from sim.scenario import ScenarioError
from sim.scenario.params import Failure, Impulse, Noise, Pushes, Recovery, SimParams

R, MARGIN = 0.5, 0.1


def _row(m=3, spacing=3.0, rise=5.0):
    start = np.stack([np.arange(m) * spacing + 2.0, np.full(m, 2.0)], axis=1)
    target = start + [0.0, rise]
    problem = Problem(m * spacing + 2.0, 10.0, (), R, MARGIN, start, target)
    return problem, Plan.from_waypoints(np.stack([start, target]), R, MARGIN, problem.max_speed, problem.max_accel)


def _budget_case(**recovery):
    """Two hard knocks (the second after the one-replan budget is spent), then a failure."""
    problem, plan = _row()
    t = plan.makespan
    params = SimParams(
        disturbances=(Impulse(2, 0.2 * t, (5.0, 0.0)), Impulse(2, 0.4 * t, (5.0, 0.0))),
        failures=(Failure(0, 0.6 * t),), accept="working",
        recovery=Recovery(replan=True, max_replans=1, **recovery))
    report = execute(problem, plan, params, np.random.default_rng(0), planner_params=PlannerParams())
    return report, t


def test_a_failure_after_the_budget_is_still_answered():
    report, t = _budget_case()
    reasons = [r.reason for r in report.replans]
    assert reasons[0].startswith("tracking error") and reasons[-1] == "robot 0 failed", reasons
    failure_replan = report.replans[-1]
    assert failure_replan.time == pytest.approx(0.6 * t, abs=2 * SimParams().dt)
    assert failure_replan.failed == (0,) and failure_replan.found
    # negative control: the old gate (replans so far < max_replans) was closed at the failure
    before = [r for r in report.replans if r.time < failure_replan.time]
    assert len(before) >= 1 == Recovery(max_replans=1).max_replans
    assert report.contacts == ()


def test_an_exhausted_budget_fails_the_run_and_is_named():
    report, t = _budget_case()
    assert report.budget_exhausted_at is not None and 0.4 * t <= report.budget_exhausted_at < 0.6 * t
    assert not report.ok and report.reached and not report.contacts
    assert f"replan budget exhausted at t = {report.budget_exhausted_at:.3f} s" in report.verdict
    d = report.to_dict()
    assert d["budget_exhausted_at"] == report.budget_exhausted_at and d["ok"] is False


def test_on_budget_continue_goes_on():
    report, _ = _budget_case(on_budget="continue")
    assert report.budget_exhausted_at is not None
    assert report.ok, report.verdict
    assert "(sim.recovery.on_budget: continue)" in report.verdict


def test_a_budget_left_over_is_not_named():
    problem, plan = _row()
    params = SimParams(disturbances=(Impulse(2, 0.2 * plan.makespan, (5.0, 0.0)),),
                       recovery=Recovery(replan=True, max_replans=1))
    report = execute(problem, plan, params, np.random.default_rng(0), planner_params=PlannerParams())
    assert len(report.replans) == 1 and report.budget_exhausted_at is None and report.ok
    assert report.to_dict()["budget_exhausted_at"] is None and "budget" not in report.verdict


# -- the accept rule -------------------------------------------------------------------------


def _empty_target(accept=None, fail=True):
    problem, plan = _row(m=2, spacing=4.0)
    extra = {} if accept is None else {"accept": accept}
    failures = (Failure(1, 0.5 * plan.makespan),) if fail else ()
    return execute(problem, plan, SimParams(failures=failures, **extra), np.random.default_rng(0))


def test_by_default_an_empty_target_fails_the_run():
    report = _empty_target()
    assert report.reached and not report.contacts and report.targets_working == 1
    assert not report.ok
    assert "accept: targets (1 of 2 targets hold a working robot)" in report.verdict
    assert report.to_dict()["accept"] == "targets"


def test_accept_working_passes_it():
    report = _empty_target("working")
    assert report.ok, report.verdict
    assert "accept: working" in report.verdict and report.to_dict()["accept"] == "working"


def test_without_a_failure_both_rules_pass():
    for accept in ("targets", "working"):
        report = _empty_target(accept, fail=False)
        assert report.ok and report.targets_working == 2 and "accept" not in report.verdict


# -- settings ----------------------------------------------------------------------------------



def test_the_new_keys_are_read(tmp_path, read_case):
    s = read_case("sim: {accept: working, recovery: {replan_time_limit: 3, on_budget: continue}}").sim
    assert s.accept == "working" and s.recovery.replan_time_limit == 3.0 and s.recovery.on_budget == "continue"
    old = read_case("sim: {recovery: {time_limit: 4}}").sim.recovery
    assert old.replan_time_limit == 4.0 == old.time_limit  # the old name is an alias
    d = read_case("").sim
    assert d.accept == "targets" and d.recovery.on_budget == "fail"


@pytest.mark.parametrize("body, field, words", [
    ("sim: {recovery: {time_limit: 3, replan_time_limit: 3}}", "sim.recovery.time_limit", "give only one"),
    ("sim: {recovery: {replan_time_limit: 0}}", "sim.recovery.replan_time_limit", "in (0, 600]"),
    ("sim: {recovery: {on_budget: ignore}}", "sim.recovery.on_budget", "fail, continue"),
    ("sim: {accept: all}", "sim.accept", "targets, working"),
])
def test_bad_values_name_the_field(tmp_path, body, field, words, read_case):
    with pytest.raises(ScenarioError) as info:
        read_case(body + "\n")
    assert info.value.field == field and words in info.value.reason, info.value.reason


# -- recovery never makes contacts worse ------------------------------------------------------


def _crowd(seed):
    """100 robots in a 10 x 10 grid 1.3 apart, each moving 4 places along its row: a failed robot
    is in the way of those behind it.  It fails late (60 % of the plan), after about 60 pushes."""
    s = 1.3
    xs, ys = np.meshgrid(np.arange(10) * s + 1.0, np.arange(10) * s + 1.0)
    start = np.stack([xs.ravel(), ys.ravel()], axis=1)
    target = start + [4 * s, 0.0]
    problem = Problem(20.0, 14.0, (), R, MARGIN, start, target)
    plan = Plan.from_waypoints(np.stack([start, target]), R, MARGIN, problem.max_speed, problem.max_accel)
    robot = int(np.random.default_rng(seed).integers(0, 100))
    return problem, plan, Failure(robot, 0.6 * plan.makespan)


@pytest.mark.slow
def test_recovery_never_makes_contacts_worse_with_100_robots():
    t0 = time.perf_counter()
    rows = []
    for seed in range(5):
        problem, plan, failure = _crowd(seed)
        base = dict(failures=(failure,), pushes=Pushes(0.2, 0.4), noise=Noise(0.005, 0.0), settle_time=1.0)
        without = execute(problem, plan, SimParams(**base), np.random.default_rng(seed))
        with_ = execute(problem, plan, SimParams(**base, recovery=Recovery(replan=True)),
                        np.random.default_rng(seed), planner_params=PlannerParams(time_limit=10.0))
        pushes = sum(d.kind == "push" and d.time < failure.time for d in with_.disturbances)
        assert pushes > 30, pushes  # the failure comes after many pushes
        assert any(failure.robot in r.failed for r in with_.replans), seed  # the failure was answered
        rows.append((seed, len(without.contacts), len(with_.contacts)))
    for _seed, n_without, n_with in rows:
        assert n_with <= n_without, rows
    # negative control: without recovery the failed robot is hit in most seeds
    assert sum(n > 0 for _, n, _ in rows) >= 3, rows
    print(rows, f"{time.perf_counter() - t0:.1f} s")
