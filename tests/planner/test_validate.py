"""The exact plan validator against dense brute-force sampling, including colliding plans."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from planner import Plan, PlanInvalid, check_plan, min_clearance
from planner.problem import Circle, Polygon, Problem


def _problem(start, target=None):
    obstacles = (
        Polygon(np.array([[14, 14], [22, 14], [22, 17], [17, 17], [17, 24], [14, 24]])),
        Circle((30, 8), 3.0),
    )
    start = np.asarray(start, float)
    return Problem(40, 40, obstacles, 1.0, 0.1, start, start if target is None else target)


def _brute_force(problem: Problem, plan: Plan, samples_per_step=4000) -> float:
    """Smallest gap over densely sampled plan times (robots, obstacles, walls)."""
    best = np.inf
    for k in range(plan.steps):
        ts = plan.times[k] + np.linspace(0, 1, samples_per_step) * plan.durations[k]
        pos, _, _ = plan.sample(ts)
        flat = pos.reshape(-1, 2)
        best = min(best, problem.env.point_clearance(flat).min() - problem.radius)
        if plan.m > 1:
            d = np.linalg.norm(pos[:, :, None] - pos[:, None, :], axis=3)
            d[:, np.arange(plan.m), np.arange(plan.m)] = np.inf
            best = min(best, d.min() - 2 * problem.radius)
    return best


def _max_step_motion(plan: Plan, samples_per_step=4000) -> float:
    """How far any robot can move between two samples (the sampling's blind spot)."""
    worst = 0.0
    for k in range(plan.steps):
        ts = plan.times[k] + np.linspace(0, 1, samples_per_step) * plan.durations[k]
        pos, _, _ = plan.sample(ts)
        worst = max(worst, np.linalg.norm(np.diff(pos, axis=0), axis=2).max())
    return worst


@st.composite
def random_plans(draw):
    seed = draw(st.integers(0, 2**31))
    rng = np.random.default_rng(seed)
    m = draw(st.integers(1, 4))
    k = draw(st.integers(1, 4))
    w = rng.uniform(2, 38, size=(k + 1, m, 2))
    # Some robots stay put in some steps, as in pebble moves.
    still = rng.random((k, m)) < 0.4
    for s in range(k):
        w[s + 1][still[s]] = w[s][still[s]]
    return w


@settings(max_examples=150, deadline=None)
@given(random_plans())
def test_min_clearance_matches_brute_force(w):
    """Random plans, colliding or not: exact value within the sampling's blind spot."""
    problem = _problem(w[0])
    plan = Plan.from_waypoints(w, 1.0, 0.1, 2.0, 2.0)
    exact = min_clearance(problem, plan).value
    brute = _brute_force(problem, plan)
    assert exact <= brute + 1e-9  # the exact minimum is never above a sampled value
    assert brute <= exact + _max_step_motion(plan) + 1e-9


def test_crossing_robots_collide_mid_step():
    """Endpoints are fine but the robots meet halfway: only a continuous check sees it."""
    start = np.array([[5.0, 30.0], [5.0, 35.0]])
    end = np.array([[10.0, 35.0], [10.0, 30.0]])
    problem = _problem(start, end)
    plan = Plan.from_waypoints([start, end], 1.0, 0.1, 2.0, 2.0)
    c = min_clearance(problem, plan)
    assert c.kind == "robot-robot" and c.robots == (0, 1)
    assert c.value == pytest.approx(-2.0)  # centres coincide at theta = 1/2
    assert c.time == pytest.approx(plan.makespan / 2, rel=1e-6)
    with pytest.raises(PlanInvalid):
        check_plan(problem, plan)
    # Waypoint-only checking would have passed this plan:
    for w in plan.waypoints:
        assert np.linalg.norm(w[0] - w[1]) >= problem.separation


def test_robot_through_obstacle_is_caught():
    start = np.array([[10.0, 20.0]])
    end = np.array([[26.0, 20.0]])  # straight through the L-shaped obstacle
    problem = _problem(start, end)
    plan = Plan.from_waypoints([start, end], 1.0, 0.1, 2.0, 2.0)
    c = min_clearance(problem, plan)
    assert c.kind == "robot-obstacle" and c.obstacle == 0
    assert c.value < 0
    with pytest.raises(PlanInvalid, match="obstacle 0"):
        check_plan(problem, plan)


def test_near_miss_passes():
    """Two robots passing with a gap of exactly the margin are valid."""
    start = np.array([[5.0, 30.0], [15.0, 32.1 + 0.0]])
    end = np.array([[15.0, 30.0], [5.0, 32.1]])
    problem = _problem(start, end)
    plan = Plan.from_waypoints([start, end], 1.0, 0.1, 2.0, 2.0)
    c = check_plan(problem, plan)
    assert c.value == pytest.approx(0.1)


def test_wrong_end_or_start_is_rejected():
    start = np.array([[5.0, 30.0]])
    problem = _problem(start, np.array([[8.0, 30.0]]))
    plan = Plan.from_waypoints([start, [[7.0, 30.0]]], 1.0, 0.1, 2.0, 2.0)
    with pytest.raises(PlanInvalid, match="target"):
        check_plan(problem, plan)
    plan = Plan.from_waypoints([[[6.0, 30.0]], [[8.0, 30.0]]], 1.0, 0.1, 2.0, 2.0)
    with pytest.raises(PlanInvalid, match="start"):
        check_plan(problem, plan)


def test_minimum_jerk_limits_respected():
    w = np.array([[[5.0, 5.0]], [[25.0, 5.0]], [[25.0, 6.0]]])
    plan = Plan.from_waypoints(w, 1.0, 0.1, 2.0, 2.0)
    ts = np.linspace(0, plan.makespan, 20001)
    pos, vel, acc = plan.sample(ts)
    assert np.linalg.norm(vel, axis=2).max() <= 2.0 + 1e-9
    assert np.linalg.norm(acc, axis=2).max() <= 2.0 + 1e-6
    assert np.allclose(pos[0], w[0]) and np.allclose(pos[-1], w[-1])
    # velocity is the derivative of position
    dt = ts[1] - ts[0]
    assert np.allclose(np.gradient(pos[:, 0, 0], dt), vel[:, 0, 0], atol=1e-3)


@pytest.mark.parametrize("case", ["robot-robot", "robot-obstacle", "robot-wall"])
def test_gap_between_zero_and_the_margin_is_invalid(case):
    """Nothing touches, but the gap 0.05 is below the margin 0.1: the plan must be refused."""
    if case == "robot-robot":  # they pass each other on lanes 2.05 apart
        start = np.array([[5.0, 30.0], [15.0, 32.05]])
        end = np.array([[15.0, 30.0], [5.0, 32.05]])
    elif case == "robot-obstacle":  # along the circle (30, 8) r 3, 4.05 from its centre
        start, end = np.array([[25.0, 3.95]]), np.array([[35.0, 3.95]])
    else:  # along the left wall, 1.05 from it
        start, end = np.array([[1.05, 30.0]]), np.array([[1.05, 36.0]])
    problem = _problem(start, end)
    plan = Plan.from_waypoints([start, end], 1.0, 0.1, 2.0, 2.0)
    c = min_clearance(problem, plan)
    assert c.kind == case
    assert c.value == pytest.approx(0.05, abs=1e-9)
    assert 0 < c.value < problem.margin
    with pytest.raises(PlanInvalid, match="margin 0.1") as info:
        check_plan(problem, plan)
    assert info.value.clearance.value == pytest.approx(0.05, abs=1e-9)
    # a brute-force sample agrees that nothing touches
    assert 0 < _brute_force(problem, plan, 2000) < problem.margin


def _reference(problem: Problem, plan: Plan):
    """min_clearance's obstacle part without leaving any move out: every move's exact
    clearance (``segment_clearance_detail``), the start placement's, the earliest minimum."""
    w, r, env = plan.waypoints, problem.radius, problem.env
    c0, who0 = env.point_clearance_detail(w[0])
    best = (float(c0.min() - r), -1, int(who0[np.argmin(c0)]))
    step, robot = np.nonzero(np.any(w[1:] != w[:-1], axis=2))
    if len(step):
        cl, who = env.segment_clearance_detail(w[step, robot], w[step + 1, robot])
        n = int(np.argmin(cl))
        if cl[n] - r < best[0]:
            best = (float(cl[n] - r), int(step[n]), int(who[n]))
    return best


@settings(max_examples=150, deadline=None)
@given(random_plans(), st.floats(0.0, 6.0))
def test_min_clearance_leaves_out_only_moves_that_cannot_lower_it(w, lift):
    """The moves kept away from obstacles are left out of the exact distances; the minimum,
    its step and its obstacle are those of taking every move (single robots, so no
    robot pair intervenes), also when the start placement sits far from everything
    (``lift``: the start moved away, so nearly every move is a candidate) or close."""
    w = w[:, :1].copy()
    w[0] = np.clip(w[0] + lift, 2, 38)
    problem = _problem(w[0])
    plan = Plan.from_waypoints(w, 1.0, 0.1, 2.0, 2.0)
    c = min_clearance(problem, plan)
    value, step, who = _reference(problem, plan)
    assert c.value == value
    assert c.step == step
    assert (c.obstacle if c.obstacle is not None else -1) == who
