"""The physics run's verdict, report and input checks, pinned (sim/execute/physics.py).

The verdict line, the JSON summary, the refusal of each bad parameter at its exact
boundary, target matching at the tolerance, and the ideal loop's bookkeeping (sample
times, progress, simulated time) are checked against values written out by hand.
These are the tests that mutation testing of ``sim/execute/physics.py`` relies on (see
``tests/mutation/``).
"""

import dataclasses
import math

import numpy as np
import pytest

from planner.plan import Plan
from planner.problem import Problem
from sim.execute.contacts import Contact
from sim.execute.outcome import SimReport
from sim.execute.outcome import assemble as build_report
from sim.execute.outcome import filled as _filled
from sim.execute.outcome import reached as _reached
from sim.execute.physics import _check, execute
from sim.execute.realism import Disturbance, phase_margin
from sim.scenario.params import Failure, Impulse, Noise, SimParams


def _report(**kw):
    base = dict(
        contacts=(), min_clearance=0.5, min_clearance_time=1.0, max_tracking_error=0.01, reached=True,
        final_error=0.001, sim_time_s=4.0, wall_time_s=2.0, times=np.zeros(1), positions=np.zeros((1, 2, 2)),
        reached_robots=np.array([True, True]), phase_margin_deg=60.0, targets_filled=2,
    )
    base.update(kw)
    return SimReport(**base)


C1 = Contact(1.5, "robot-robot", 0, 1, 0.02, "pymunk")
C2 = Contact(1.5, "robot-wall", 1, -1, 0.01, "monitor")


def test_a_clean_run_says_so():
    r = _report()
    assert r.ok and r.first_contact is None
    assert r.verdict == "no contact, every robot on a target"
    assert r.realtime_factor == 2.0
    assert _report(wall_time_s=0.0).realtime_factor == math.inf


def test_contacts_make_the_run_fail_and_lead_the_verdict():
    r = _report(contacts=(C1, C2))
    assert not r.ok and r.first_contact is C1
    assert r.verdict == "2 contacts, the first: robots 0 and 1 touch at t = 1.500 s, depth 0.02 (seen by pymunk)"


def test_a_stopped_run_fails_and_says_why():
    r = _report(stopped="replan found no way on", reached=False)
    assert not r.ok
    assert r.verdict == "stopped: replan found no way on"
    assert not _report(stopped="x").ok


def test_robots_off_target_are_named_up_to_ten():
    flags = np.array([True] * 3 + [False] * 12)
    r = _report(reached=False, reached_robots=flags, final_error=0.1234, targets_filled=15)
    assert not r.ok
    assert r.verdict == "robots 3, 4, 5, 6, 7, 8, 9, 10, 11, 12 ... end off target (worst 0.123)"
    r = _report(reached=False, reached_robots=np.array([True, False]), final_error=2.0, targets_filled=1)
    assert r.verdict == "robots 1 end off target (worst 2); 1 of 2 targets filled"
    flags = np.array([True] * 5 + [False] * 10)
    r = _report(reached=False, reached_robots=flags, final_error=1.0, targets_filled=15)
    assert r.verdict == "robots 5, 6, 7, 8, 9, 10, 11, 12, 13, 14 end off target (worst 1)"


def test_failed_robots_are_named_and_not_counted_as_missing():
    r = _report(failed=(1,), reached_robots=np.array([True, False]), targets_filled=1)
    assert r.ok
    assert r.verdict == (
        "no contact, every working robot on a target; robot 1 failed; 1 of 2 targets filled"
    )
    r = _report(failed=(2, 0), reached=False, reached_robots=np.array([False, False, False, False]),
                targets_filled=0, final_error=3.0)
    assert r.verdict == "robots 1, 3 end off target (worst 3); robots 2, 0 failed; 0 of 4 targets filled"


def test_replans_and_an_unstable_controller_are_reported():
    r = _report(replans=("a", "b"), phase_margin_deg=0.0)
    assert r.verdict == (
        "no contact, every robot on a target; 2 replans; the controller is unstable with its delays "
        "(phase margin 0 deg): lower kp and kd, or the latency"
    )
    assert _report(phase_margin_deg=0.4).verdict == "no contact, every robot on a target"
    assert "unstable" in _report(phase_margin_deg=-12.0).verdict
    assert "unstable" not in _report(phase_margin_deg=float("nan")).verdict


def test_targets_filled_is_reported_only_when_short():
    assert "targets filled" not in _report(targets_filled=-1).verdict
    assert "targets filled" not in _report(targets_filled=2).verdict
    assert _report(targets_filled=0).verdict.endswith("; 0 of 2 targets filled")
    assert "targets filled" not in _report(reached_robots=None, targets_filled=0).verdict


def test_report_dict():
    dist = (Disturbance("impulse", 0, 0.5, (1.0, 2.0)), Disturbance("push", 1, 0.7, (0.0, 1.0)),
            Disturbance("failure", 1, 0.9), Disturbance("push", 0, 1.1, (1.0, 0.0)))
    r = _report(contacts=(C1, C2, C1), min_clearance=-0.02, min_clearance_kind="robot-robot", min_clearance_pair=(0, 1),
                max_tracking_error_time=0.25, max_tracking_error_robot=1, masses=np.array([0.9, 1.1]),
                failed=(1,), disturbances=dist, stopped="", targets_filled=2, phase_margin_deg=float("inf"),
                min_clearance_time=float("nan"))
    d = r.to_dict()
    assert d["ok"] is False
    # contacts counts events (C1 twice at one time is one touch), the witnesses' counts are sightings
    assert (d["contacts"], d["contacts_pymunk"], d["contacts_monitor"]) == (2, 2, 1)
    assert [e["witnesses"] for e in d["contact_events"]] == [["pymunk"], ["monitor"]]
    assert d["min_clearance"] == -0.02 and d["min_clearance_time"] is None
    assert d["min_clearance_kind"] == "robot-robot" and d["min_clearance_pair"] == [0, 1]
    assert d["max_tracking_error"] == 0.01 and d["reached"] is True and d["final_error"] == 0.001
    assert (d["sim_time_s"], d["wall_time_s"], d["realtime_factor"]) == (4.0, 2.0, 2.0)
    assert d["contact_list"] == [C1.to_dict(), C2.to_dict(), C1.to_dict()]
    assert "contact_list_truncated" not in d
    assert d["first_contact"] == C1.to_dict()
    assert (d["max_tracking_error_time"], d["max_tracking_error_robot"]) == (0.25, 1)
    assert d["reached_robots"] == [True, True]
    assert d["mass_range"] == [0.9, 1.1]
    assert d["failed"] == [1]
    assert d["disturbances"] == {
        "impulses": 1, "pushes": 2, "failures": 1, "list": [x.to_dict() for x in dist],
    }
    assert d["replans"] == [] and d["stopped"] is None and d["targets_filled"] == 2
    assert d["phase_margin_deg"] is None
    assert d["verdict"] == r.verdict
    clean = _report(masses=np.zeros(0), reached_robots=None, stopped="why").to_dict()
    assert clean["first_contact"] is None and "mass_range" not in clean and "reached_robots" not in clean
    assert clean["stopped"] == "why" and clean["realtime_factor"] == 2.0
    assert _report(wall_time_s=0.0).to_dict()["realtime_factor"] is None
    assert _report(phase_margin_deg=42.5).to_dict()["phase_margin_deg"] == 42.5


def test_long_lists_are_cut_at_a_thousand():
    many = tuple(Contact(0.2 * k, "robot-wall", 0, -1, 0.1, "monitor") for k in range(1001))  # 1001 events
    pushes = tuple(Disturbance("push", 0, 0.01 * k, (1.0, 0.0)) for k in range(1001))
    d = _report(contacts=many, disturbances=pushes).to_dict()
    assert len(d["contact_list"]) == 1000 and d["contact_list_truncated"] is True
    assert len(d["disturbances"]["list"]) == 1000 and d["disturbances"]["list_truncated"] is True
    assert d["contacts"] == 1001 and d["disturbances"]["pushes"] == 1001
    assert len(d["contact_events"]) == 1000 and d["contact_events_truncated"] is True
    d = _report(contacts=many[:1000], disturbances=pushes[:1000]).to_dict()
    assert "contact_list_truncated" not in d and "list_truncated" not in d["disturbances"]
    assert "contact_events_truncated" not in d


def test_series_needs_both_arrays():
    assert _report().series() is None
    assert _report(min_gap=np.zeros(1)).series() is None
    s = _report(times=np.arange(3.0), min_gap=np.ones(3), tracking_error=np.zeros((3, 2))).series()
    assert s["times"] == pytest.approx([0, 1, 2]) and s["min_gap"] == pytest.approx([1, 1, 1])
    long = _report(times=np.arange(3000.0), min_gap=np.ones(3000), tracking_error=np.zeros((3000, 2)))
    assert 1000 < len(long.series()["times"]) <= 2000
    assert len(long.series(max_samples=10)["times"]) <= 11
    edge = _report(times=np.arange(2001.0), min_gap=np.ones(2001), tracking_error=np.zeros((2001, 2)))
    assert len(edge.series()["times"]) <= 2000


# -- input checks ---------------------------------------------------------------------------


def _problem(m=2):
    start = np.array([[2.0, 2.0], [6.0, 6.0], [2.0, 8.0]])[:m]
    return Problem(10, 10, (), 0.5, 0.1, start, start)


def _plan(problem):
    return Plan(problem.radius, problem.margin, np.zeros(0), problem.start[None])


@pytest.mark.parametrize(
    "field, bad, ok, message",
    [
        ("mass", 0.0, 1e-9, "sim.mass: must be a number in the range (0, inf), got 0.0"),
        ("kp", -1.0, 0.0, "sim.kp: must be a number in the range [0, inf), got -1.0"),
        ("kd", -1e-9, 0.0, "sim.kd: must be a number in the range [0, inf), got -1e-09"),
        ("dt", 0.0, 0.01, "sim.dt: must be a number in the range (0, inf), got 0.0"),
        ("force_limit", 0.0, 1.0, "sim.force_limit: must be a number in the range (0, inf), got 0.0"),
        ("settle_time", -0.5, 0.0, "sim.settle_time: must be a number in the range [0, inf), got -0.5"),
        ("tolerance", -0.1, 0.0, "sim.tolerance: must be a number in the range [0, inf), got -0.1"),
        ("latency", -0.1, 0.0, "sim.latency: must be a number in the range [0, inf), got -0.1"),
        ("mass_error", -0.1, 0.0, "sim.mass_error: must be a number in the range [0, inf), got -0.1"),
        ("friction", -0.1, 0.0, "sim.friction: must be a number in the range [0, inf), got -0.1"),
        ("mass", float("inf"), 1.0, "sim.mass: must be a number in the range (0, inf), got inf"),
        ("kp", float("nan"), 1.0, "sim.kp: must be a number in the range [0, inf), got nan"),
        ("kd", True, 1.0, "sim.kd: must be a number in the range [0, inf), got True"),
        ("dt", "0.1", 0.1, "sim.dt: must be a number in the range (0, inf), got '0.1'"),
        ("substeps", 0, 1, "sim.substeps: must be an int in the range [1, inf), got 0"),
        ("substeps", 2.0, 3, "sim.substeps: must be an int in the range [1, inf), got 2.0"),
        ("mass_error", 1.0, 0.999, "sim.mass_error: must be a number in the range [0, 1), got 1.0"),
        ("control_rate", -1.0, 0.0, "sim.control_rate: must be a number >= 0 or None, got -1.0"),
        ("control_rate", float("inf"), None, "sim.control_rate: must be a number >= 0 or None, got inf"),
        ("control_rate", "30", 30.0, "sim.control_rate: must be a number >= 0 or None, got '30'"),
    ],
)
def test_each_parameter_is_refused_past_its_boundary(field, bad, ok, message):
    problem = _problem()
    _check(problem, _plan(problem), dataclasses.replace(SimParams(), **{field: ok}))
    with pytest.raises(ValueError) as e:
        _check(problem, _plan(problem), dataclasses.replace(SimParams(), **{field: bad}))
    assert str(e.value) == message


def test_robot_indices_of_events_are_checked():
    problem = _problem(2)
    plan = _plan(problem)
    _check(problem, plan, SimParams(disturbances=(Impulse(1, 0.5, (1.0, 0.0)), Impulse(0, 0.5, (1.0, 0.0)))))
    with pytest.raises(ValueError, match=r"^sim\.disturbances\[1\]\.robot: must be in the range \[0, 2\), got 2$"):
        _check(problem, plan, SimParams(disturbances=(Impulse(0, 0.5, (1.0, 0.0)), Impulse(2, 0.5, (1.0, 0.0)))))
    with pytest.raises(ValueError, match=r"^sim\.disturbances\[0\]\.robot: must be in the range \[0, 2\), got -1$"):
        _check(problem, plan, SimParams(disturbances=(Impulse(-1, 0.5, (1.0, 0.0)),)))
    _check(problem, plan, SimParams(failures=(Failure(0, 1.0), Failure(1, 1.0))))
    with pytest.raises(ValueError, match=r"^sim\.failures\[1\]\.robot: must be in the range \[0, 2\), got 2$"):
        _check(problem, plan, SimParams(failures=(Failure(0, 1.0), Failure(2, 1.0))))
    with pytest.raises(ValueError, match=r"^sim\.failures\[0\]\.robot: must be in the range \[0, 2\), got -1$"):
        _check(problem, plan, SimParams(failures=(Failure(-1, 1.0),)))
    with pytest.raises(ValueError, match=r"^plan: moves 3 robots, the problem has 2$"):
        _check(problem, _plan(_problem(3)), SimParams())


# -- targets ---------------------------------------------------------------------------------


def test_reached_matches_robots_to_targets_within_the_tolerance_inclusive():
    final = np.array([[0.0, 0.0], [4.0, 0.0], [9.0, 9.0]])
    target = np.array([[4.0, 0.5], [0.0, 0.25], [9.0, 9.0]])
    ok, worst, per = _reached(final, target, 0.5, np.ones(3, bool))
    assert (ok, worst, per.tolist()) == (True, 0.5, [True, True, True])
    assert per.dtype == bool
    ok, worst, per = _reached(final, target, 0.3, np.ones(3, bool))
    assert (ok, worst, per.tolist()) == (False, 0.5, [True, False, True])
    # a failed robot is neither matched nor counted
    ok, worst, per = _reached(final, target[1:], 0.3, np.array([True, False, True]))
    assert (ok, worst, per.tolist()) == (True, 0.25, [True, False, True])
    # no working robot: trivially reached
    ok, worst, per = _reached(final, target, 0.3, np.zeros(3, bool))
    assert (ok, worst, per.tolist()) == (True, 0.0, [False, False, False])
    # fewer targets than working robots
    ok, worst, per = _reached(final, target[:2], 0.3, np.ones(3, bool))
    assert (ok, worst, per.tolist()) == (False, math.inf, [False, False, False])


def test_filled_counts_targets_with_a_robot_within_the_tolerance():
    final = np.array([[0.0, 0.0], [4.0, 0.0], [9.0, 9.0]])
    target = np.array([[4.0, 0.5], [0.0, 0.25], [5.0, 5.0]])
    assert _filled(final, target, 0.5) == 2
    assert _filled(final, target, 0.25) == 1
    assert _filled(final, target, 0.2) == 0
    assert _filled(final, target.ravel(), 0.5) == 2
    # one robot near two targets fills only one
    assert _filled(np.array([[0.0, 0.0], [9.0, 9.0]]), np.array([[0.0, 0.1], [0.1, 0.0]]), 0.5) == 1


# -- the ideal loop -------------------------------------------------------------------------


def test_ideal_run_bookkeeping():
    start = np.array([[2.0, 2.0], [8.0, 8.0]])
    target = np.array([[3.0, 2.0], [8.0, 8.0]])
    problem = Problem(10, 10, (), 0.5, 0.1, start, target)
    plan = Plan(0.5, 0.1, np.array([1.0]), np.array([start, target]))
    params = SimParams(dt=0.1, substeps=2, settle_time=0.25, kp=100.0, kd=20.0)
    seen = []
    r = execute(problem, plan, params, progress=seen.append)
    n = math.ceil(1.25 / 0.1)
    assert n == 13 and r.times == pytest.approx(np.arange(n + 1) * 0.1)
    assert r.positions.shape == (n + 1, 2, 2) and r.positions[0] == pytest.approx(start)
    assert r.sim_time_s == pytest.approx(1.3)
    assert seen == [1.0]  # one chunk of 64 control steps
    assert r.masses == pytest.approx([1.0, 1.0])
    assert r.phase_margin_deg == pytest.approx(phase_margin(100.0, 20.0, 0.05))
    assert r.tracking_error.shape == (n + 1, 2) and r.tracking_error[0] == pytest.approx([0, 0])
    assert r.max_tracking_error == pytest.approx(r.tracking_error.max())
    assert r.max_tracking_error_robot == 0
    k = int(np.argmax(r.tracking_error[:, 0]))
    assert r.max_tracking_error_time == pytest.approx(k * 0.1)
    assert r.min_gap.shape == (n + 1,)
    assert r.reached and r.targets_filled == 2 and r.ok
    assert r.positions[-1, 0] == pytest.approx([3.0, 2.0], abs=0.05)
    assert r.positions[-1, 1] == pytest.approx([8.0, 8.0], abs=1e-9)
    assert (r.min_clearance_kind, r.min_clearance_pair) == ("robot-wall", (0, -1))
    assert r.min_clearance == pytest.approx(1.5, abs=1e-9) and r.min_clearance_time == 0.0
    for a in (r.times, r.positions, r.tracking_error, r.min_gap, r.reached_robots, r.masses):
        assert not a.flags.writeable
    assert r.step_time_s > 0 and r.wall_time_s >= r.step_time_s


def test_ideal_run_progress_over_several_chunks_and_an_exact_end():
    start = np.array([[2.0, 2.0]])
    problem = Problem(10, 10, (), 0.5, 0.1, start, start)
    plan = Plan(0.5, 0.1, np.zeros(0), start[None])
    seen = []
    r = execute(problem, plan, SimParams(dt=0.01, substeps=1, settle_time=1.3), progress=seen.append)
    assert len(r.times) == 131  # 1.3 / 0.01 is 130 steps, not 131, despite rounding
    assert seen == pytest.approx([64 / 130, 128 / 130, 1.0])
    seen = []
    r = execute(problem, plan, SimParams(settle_time=0.0), progress=seen.append)
    assert seen == [1.0] and len(r.times) == 1 and r.sim_time_s == 0.0
    assert r.max_tracking_error == 0.0 and r.max_tracking_error_robot == 0


def test_a_push_moves_only_the_pushed_robot_until_its_controller_pulls_it_back():
    start = np.array([[3.0, 5.0], [7.0, 5.0]])
    problem = Problem(10, 10, (), 0.5, 0.1, start, start)
    plan = Plan(0.5, 0.1, np.zeros(0), start[None])
    params = SimParams(settle_time=1.0, disturbances=(Impulse(1, 0.2, (0.0, 0.5)),))
    r = execute(problem, plan, params, np.random.default_rng(0))
    assert [(d.kind, d.robot) for d in r.disturbances] == [("impulse", 1)]
    assert r.disturbances[0].time == pytest.approx(0.2, abs=1 / 240 + 1e-9)
    assert r.tracking_error[:, 0].max() == pytest.approx(0.0, abs=1e-9)
    assert r.max_tracking_error_robot == 1 and r.tracking_error[:, 1].max() > 0.005
    assert r.max_tracking_error_time > 0.2
    assert r.to_dict()["disturbances"]["impulses"] == 1


class _Fake:
    def __init__(self, contacts, **kw):
        self._contacts = contacts
        self.__dict__.update(kw)

    def contacts(self):
        return list(self._contacts)


def _built(contacts_pymunk=(), contacts_monitor=(), tracking=None, **kw):
    times = np.arange(3) * 0.5
    pos = np.zeros((3, 2, 2))
    tracking = np.array([[0.0, 0.1], [0.3, 0.2], [0.1, 0.0]]) if tracking is None else tracking
    monitor = _Fake(contacts_monitor, series=np.zeros(3), min_gap=0.25, min_time=0.5, min_kind="robot-wall",
                    min_pair=(1, -1))
    args = dict(sim_time=1.0, wall0=0.0, step_time=0.0, masses=np.ones(2), failed=(), disturbances=(),
                replans=(), stopped="", targets_filled=2, phase_margin_deg=50.0)
    args.update(kw)
    return build_report(_Fake(contacts_pymunk), monitor, times, pos, tracking, True, 0.0, np.ones(2, bool), **args)


def test_the_report_sorts_contacts_pymunk_first_at_equal_times():
    p = Contact(1.0, "robot-wall", 1, -1, 0.1, "pymunk")
    q = Contact(1.0, "robot-obstacle", 1, 0, 0.1, "monitor")
    e = Contact(0.5, "robot-robot", 0, 1, 0.1, "monitor")
    r = _built([p], [q, e])
    assert [c.witness for c in r.contacts] == ["monitor", "pymunk", "monitor"]
    assert r.contacts[0] is e


def test_the_report_carries_the_monitor_and_the_worst_tracking():
    r = _built(stopped="why", replans=("one",), failed=(1,))
    got = (r.min_clearance, r.min_clearance_time, r.min_clearance_kind, r.min_clearance_pair)
    assert got == (0.25, 0.5, "robot-wall", (1, -1))
    assert (r.max_tracking_error, r.max_tracking_error_time, r.max_tracking_error_robot) == (0.3, 0.5, 0)
    assert r.stopped == "why" and r.replans == ("one",) and r.failed == (1,)
    # every robot failed: no tracking error at all
    r = _built(tracking=np.full((3, 2), np.nan))
    assert r.max_tracking_error == 0.0 and math.isnan(r.max_tracking_error_time) and r.max_tracking_error_robot == -1


def test_wall_and_step_times_are_measured(monkeypatch):
    import time

    clock = iter(1000.0 + np.arange(1_000_000))
    monkeypatch.setattr(time, "perf_counter", lambda: float(next(clock)))
    start = np.array([[2.0, 2.0]])
    problem = Problem(10, 10, (), 0.5, 0.1, start, start)
    plan = Plan(0.5, 0.1, np.zeros(0), start[None])
    r = execute(problem, plan, SimParams(dt=0.1, substeps=3, settle_time=0.5))
    # one clock tick inside each of the 5 x 3 physics steps
    assert r.step_time_s == 15.0
    assert 15.0 < r.wall_time_s < 100.0


def test_the_realistic_loop_reports_progress_and_uses_the_runs_generator():
    start = np.array([[3.0, 5.0], [7.0, 5.0]])
    problem = Problem(10, 10, (), 0.5, 0.1, start, start)
    plan = Plan(0.5, 0.1, np.zeros(0), start[None])
    params = SimParams(settle_time=0.5, noise=Noise(position=0.01))
    seen = []
    a = execute(problem, plan, params, np.random.default_rng(0), progress=seen.append)
    assert seen and seen[-1] == 1.0 and seen == sorted(seen)
    b = execute(problem, plan, params, np.random.default_rng(0))  # the same seed repeats
    c = execute(problem, plan, params, np.random.default_rng(1))
    assert np.array_equal(a.positions, b.positions)
    assert not np.array_equal(b.positions, c.positions)


def test_pymunk_stamps_a_contact_within_the_control_step_that_shows_it():
    start = np.array([[5.0, 5.0]])
    target = np.array([[9.7, 5.0]])
    problem = Problem(10, 10, (), 0.5, 0.1, start, target)
    plan = Plan(0.5, 0.1, np.array([1.0]), np.array([start, target]))
    r = execute(problem, plan, SimParams(settle_time=0.2))
    first = {w: min(c.time for c in r.contacts if c.witness == w) for w in ("pymunk", "monitor")}
    dt = SimParams().dt
    assert first["monitor"] - dt - 1e-9 <= first["pymunk"] <= first["monitor"] + 1e-9
