"""Physics execution: tracking, contact witnesses, targets and determinism.

Every negative control is a plan built to touch something; both witnesses
(pymunk's begin callbacks and the geometric monitor) must report it with
the right kind, indices and time.
"""

import json
import math

import numpy as np
import pytest

from planner.plan import Plan, min_jerk
from planner.problem import Circle, Polygon, Problem
from planner.validate import check_plan, min_clearance
from sim.execute.physics import Contact, SimReport, execute
from sim.scenario.params import SimParams

R = 0.5
MARGIN = 0.1
PARAMS = SimParams(settle_time=1.0)


def _setup(waypoints, obstacles=(), target=None, size=10.0):
    w = np.asarray(waypoints, float)
    problem = Problem(size, size, tuple(obstacles), R, MARGIN, w[0], w[-1] if target is None else target)
    plan = Plan.from_waypoints(w, R, MARGIN, problem.max_speed, problem.max_accel)
    return problem, plan


def _time_at(plan: Plan, step: int, s: float) -> float:
    """Plan time at which step ``step`` has covered the fraction ``s`` of its path."""
    lo, hi = 0.0, 1.0
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if min_jerk(mid)[0] < s else (lo, mid)
    return float(plan.times[step] + 0.5 * (lo + hi) * plan.durations[step])


def _by(report: SimReport, witness: str) -> list[Contact]:
    return [c for c in report.contacts if c.witness == witness]


def _assert_seen(report, kind, a, b, time, tol=0.05):
    """Both witnesses report (kind, a, b), first near ``time``."""
    for witness in ("pymunk", "monitor"):
        hits = [c for c in _by(report, witness) if (c.kind, c.a, c.b) == (kind, a, b)]
        assert hits, f"{witness} missed {kind} {a}-{b}: {report.contacts}"
        assert hits[0].time == pytest.approx(time, abs=tol), (witness, hits[0])
        assert hits[0].depth > 0.0


# -- valid plans ------------------------------------------------------------------


def _valid_case():
    """Three robots, four steps, a polygon and a circle; exact clearance about 0.2."""
    start = np.array([[1.0, 1.0], [1.0, 3.0], [9.0, 1.0]])
    w = [
        start,
        start + [[3, 0], [0, 0], [0, 0]],
        start + [[3, 0], [1.8, 0], [0, 4]],
        start + [[3, 5], [1.8, 0], [-1, 4]],
        start + [[3, 5], [1.6, 5.5], [-1, 4]],
    ]
    obstacles = (Polygon(np.array([[6.0, 6.0], [8.0, 6.5], [7.0, 8.5]])), Circle((6.5, 2.5), 0.6))
    return _setup(w, obstacles)


def test_tracking_valid_plan_is_clean_and_matches_exact_clearance():
    problem, plan = _valid_case()
    exact = check_plan(problem, plan).value
    report = execute(problem, plan, PARAMS)
    assert report.contacts == ()
    assert report.reached and report.ok
    assert report.max_tracking_error < MARGIN / 2
    assert report.max_tracking_error < 0.005
    assert report.final_error < PARAMS.tolerance
    # Sampled minimum of the executed run vs the exact plan minimum: apart
    # by at most the tracking error of both bodies (plus sampling slack).
    assert report.min_clearance == pytest.approx(exact, abs=2 * report.max_tracking_error + 1e-3)
    c = min_clearance(problem, plan)
    assert report.min_clearance_time == pytest.approx(c.time, abs=0.1)
    assert report.min_clearance_kind == c.kind
    assert report.sim_time_s == pytest.approx(plan.makespan + PARAMS.settle_time, abs=PARAMS.dt)
    n = len(report.times)
    assert report.positions.shape == (n, problem.m, 2)
    assert report.times[0] == 0.0 and np.allclose(np.diff(report.times), PARAMS.dt)
    assert np.allclose(report.positions[0], plan.start)


def test_near_miss_has_no_contact():
    # Robot 0 runs right on y = 5, robot 1 left on y = 6.2: boundaries pass 0.2 apart.
    w = [[[1.0, 5.0], [9.0, 6.2]], [[9.0, 5.0], [1.0, 6.2]]]
    problem, plan = _setup(w)
    assert check_plan(problem, plan).value == pytest.approx(0.2)
    report = execute(problem, plan, PARAMS)
    assert report.contacts == () and report.ok
    assert report.min_clearance == pytest.approx(0.2, abs=2 * report.max_tracking_error + 1e-6)
    assert report.min_clearance_kind == "robot-robot"
    assert report.min_clearance_pair == (0, 1)
    assert report.min_clearance_time == pytest.approx(plan.makespan / 2, abs=0.05)


def test_plan_ending_off_target_is_not_reached():
    w = [[[2.0, 2.0]], [[3.0, 3.0]]]
    problem, plan = _setup(w, target=[[7.0, 7.0]])
    report = execute(problem, plan, PARAMS)
    assert report.contacts == ()
    assert not report.reached and not report.ok
    assert report.final_error == pytest.approx(math.hypot(4.0, 4.0), abs=1e-3)


def test_unlabeled_targets_are_matched():
    # Robots end on each other's targets: reached, since any matching counts.
    w = [[[2.0, 2.0], [8.0, 8.0]], [[2.0, 8.0], [8.0, 2.0]]]
    problem, plan = _setup(w, target=[[8.0, 2.0], [2.0, 8.0]])
    report = execute(problem, plan, PARAMS)
    assert report.ok
    assert report.final_error < 1e-3


def test_deterministic():
    problem, plan = _valid_case()
    a = execute(problem, plan, PARAMS)
    b = execute(problem, plan, PARAMS)
    assert np.array_equal(a.positions, b.positions)
    assert a.min_clearance == b.min_clearance and a.contacts == b.contacts


_RUN = """
import hashlib, sys
import numpy as np
sys.path.insert(0, {here!r})
from test_execute import PARAMS, _valid_case
from sim.execute.physics import execute
problem, plan = _valid_case()
r = execute(problem, plan, PARAMS)
print(hashlib.sha256(r.positions.tobytes()).hexdigest(), len(r.contacts), repr(r.min_clearance))
"""


def test_deterministic_across_hash_seeds():
    import os
    import subprocess
    import sys
    from pathlib import Path

    code = _RUN.format(here=str(Path(__file__).parent))
    out = []
    for seed in ("0", "12345"):
        env = dict(os.environ, PYTHONHASHSEED=seed)
        res = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
        out.append(res.stdout)
    assert out[0] == out[1] and out[0]


def test_empty_plan():
    w = [[[2.0, 2.0], [5.0, 5.0]]]
    problem, plan = _setup(w)
    report = execute(problem, plan, SimParams(settle_time=0.0))
    assert report.times.tolist() == [0.0] and report.ok
    assert report.min_clearance == pytest.approx(1.5)
    assert report.max_tracking_error == 0.0


def test_progress_and_report_dict():
    problem, plan = _valid_case()
    seen = []
    report = execute(problem, plan, PARAMS, progress=seen.append)
    assert seen and seen[-1] == 1.0
    assert all(0.0 <= f <= 1.0 for f in seen) and seen == sorted(seen)
    d = json.loads(json.dumps(report.to_dict()))
    for key in ("contacts", "min_clearance", "max_tracking_error", "reached", "final_error",
                "sim_time_s", "wall_time_s", "contact_list"):
        assert key in d
    assert d["contacts"] == 0 and d["contact_list"] == []


# -- negative controls -------------------------------------------------------------


def test_crossing_robots_collide():
    # Both reach the centre (5, 5) at the same time.
    w = [[[2.0, 5.0], [5.0, 2.0]], [[8.0, 5.0], [5.0, 8.0]]]
    problem, plan = _setup(w)
    report = execute(problem, plan, PARAMS)
    assert len(report.contacts) > 0 and not report.ok
    # Centres are sqrt(2) |6 s - 3| apart: they touch when that is 2 r.
    s = 0.5 - 2 * R / (6 * math.sqrt(2))
    _assert_seen(report, "robot-robot", 0, 1, _time_at(plan, 0, s))
    assert report.min_clearance < 0
    d = report.to_dict()
    # one touch, seen by both witnesses: one contact event, two sightings listed
    assert d["contacts"] == len(report.events) == 1 and len(d["contact_list"]) == len(report.contacts) == 2


def test_robots_driven_through_obstacles_collide():
    square = Polygon(np.array([[4.0, 6.0], [6.0, 6.0], [6.0, 8.0], [4.0, 8.0]]))
    disc = Circle((5.0, 3.0), 1.0)
    # Robot 0 runs through the circle (obstacle 1), robot 1 through the square (obstacle 0).
    w = [[[1.0, 3.0], [1.0, 7.0]], [[9.0, 3.0], [9.0, 7.0]]]
    problem, plan = _setup(w, obstacles=(square, disc))
    report = execute(problem, plan, PARAMS)
    assert not report.ok
    # Both start at x = 1 and move 8 units: they touch at x = 3.5 (s = 2.5 / 8).
    t = _time_at(plan, 0, 2.5 / 8)
    _assert_seen(report, "robot-obstacle", 0, 1, t)
    _assert_seen(report, "robot-obstacle", 1, 0, t)
    assert not any(c.kind == "robot-robot" for c in report.contacts)


def test_robot_driven_into_wall_collides():
    w = [[[5.0, 5.0]], [[0.2, 5.0]]]
    problem, plan = _setup(w)
    report = execute(problem, plan, PARAMS)
    assert not report.ok and not report.reached
    _assert_seen(report, "robot-wall", 0, -1, _time_at(plan, 0, 4.5 / 4.8))


def test_u_shape_is_exact():
    # A U opening upwards: arms x in [3, 4.2] and [5.8, 7], notch floor at y = 4.
    u = Polygon(np.array([[3.0, 3.0], [7.0, 3.0], [7.0, 7.0], [5.8, 7.0], [5.8, 4.0],
                          [4.2, 4.0], [4.2, 7.0], [3.0, 7.0]]))
    # Robot 0 goes down into the notch (0.3 from both arms, 0.5 above the floor).
    w = [[[5.0, 9.0]], [[5.0, 5.0]]]
    problem, plan = _setup(w, obstacles=(u,))
    assert check_plan(problem, plan).value == pytest.approx(0.3)
    report = execute(problem, plan, PARAMS)
    assert report.ok, report.contacts
    assert report.min_clearance == pytest.approx(0.3, abs=report.max_tracking_error + 1e-6)
    # Robot 0 goes down onto the left arm: touches when its centre is at y = 7.5.
    w = [[[3.6, 9.0]], [[3.6, 5.0]]]
    problem, plan = _setup(w, obstacles=(u,))
    report = execute(problem, plan, PARAMS)
    assert not report.ok
    _assert_seen(report, "robot-obstacle", 0, 0, _time_at(plan, 0, 1.5 / 4))


def test_clockwise_polygon_is_represented_too():
    # The same U given clockwise: the world must not depend on the winding.
    ccw = np.array([[3.0, 3.0], [7.0, 3.0], [7.0, 7.0], [5.8, 7.0], [5.8, 4.0],
                    [4.2, 4.0], [4.2, 7.0], [3.0, 7.0]])
    u = Polygon(ccw)
    object.__setattr__(u, "vertices", ccw[::-1].copy())
    w = [[[5.0, 9.0], [1.0, 1.0]], [[5.0, 5.0], [1.0, 1.0]]]
    problem, plan = _setup(w, obstacles=(u,))
    assert execute(problem, plan, PARAMS).ok


def test_rejects_mismatched_inputs():
    problem, plan = _valid_case()
    other = Plan.from_waypoints(plan.waypoints[:, :2], R, MARGIN, 2.0, 2.0)
    with pytest.raises(ValueError, match="plan"):
        execute(problem, other, PARAMS)
    with pytest.raises(ValueError, match=r"sim\.dt"):
        execute(problem, plan, SimParams(dt=0.0))
    with pytest.raises(ValueError, match=r"sim\.substeps"):
        execute(problem, plan, SimParams(substeps=0))
