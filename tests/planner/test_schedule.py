"""Concurrent plans: valid, never longer than the sequential plan, order kept."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from planner import Plan, PlanInvalid, PlannerParams, check_plan
from planner.pebble import sample_free_points
from planner.problem import Circle, Polygon, Problem
from planner.schedule import merge_steps, schedule, shortcut, split_moves, steps_of
from planner.timing import _drop_idle, _timed
from planner.upump import build_roadmap, retrieve


def _random_problem(seed: int, m: int) -> tuple[Problem, np.random.Generator]:
    rng = np.random.default_rng(seed)
    obstacles = (
        Polygon(np.array([[14, 14], [22, 14], [22, 17], [17, 17], [17, 24], [14, 24]])),
        Circle((30, 8), 3.0),
    )
    shell = Problem(40, 40, obstacles, 1.0, 0.1, np.zeros((0, 2)), np.zeros((0, 2)))
    start = sample_free_points(shell, m, rng)
    target = sample_free_points(shell, m, rng)
    return Problem(40, 40, obstacles, 1.0, 0.1, start, target), rng


def _timed_plan(problem, waypoints) -> Plan:
    return Plan.from_waypoints(waypoints, problem.radius, problem.margin, problem.max_speed, problem.max_accel)


def _route_plans(seed: int, m: int):
    """A random problem and the sequential waypoints of its roadmap's best routes."""
    problem, rng = _random_problem(seed, m)
    roadmap, source, goal, _ = build_roadmap(problem, PlannerParams(time_limit=20), rng, float("inf"))
    return problem, [retrieve(problem, roadmap, route) for route in roadmap.routes(source, goal, 3)]


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 2**31), st.integers(2, 12))
def test_concurrent_plan_is_valid_and_never_longer(seed, m):
    """Every candidate route: the concurrent plan passes the validator and is no longer;
    the scheduler's table of pairwise tests gives the same layers as layer-by-layer checks."""
    import planner.schedule as sched

    problem, routes = _route_plans(seed, m)
    for raw in routes:
        w = split_moves(problem, _drop_idle(raw))
        steps = [(k, r) for k, r in enumerate(steps_of(w)) if len(r)]
        layered = sched._schedule_by_layer(problem, w, steps)
        assert np.array_equal(schedule(problem, w), layered)
        dense, sched._DENSE = sched._DENSE, 0  # the indexed table of pairs whose swept boxes meet
        try:
            assert np.array_equal(schedule(problem, w), layered)
        finally:
            sched._DENSE = dense
        sequential = _timed_plan(problem, _drop_idle(raw))
        check_plan(problem, sequential)
        waypoints, _, makespan = _timed(problem, PlannerParams(), raw)
        waypoints = shortcut(problem, waypoints)
        concurrent = _timed_plan(problem, waypoints)
        check_plan(problem, concurrent)
        assert concurrent.makespan <= sequential.makespan + 1e-6
        assert makespan <= sequential.makespan + 1e-6


def _swap_problem():
    """Robot 0 leaves spot P, then robot 1 moves into P: an order dependency."""
    start = np.array([[10.0, 10.0], [12.5, 10.0]])
    mid = np.array([[10.0, 12.5], [12.5, 10.0]])  # 0 steps up out of the way
    end = np.array([[10.0, 12.5], [10.0, 10.0]])  # then 1 takes 0's old spot
    # at once, the two would come within 1.77 of each other (need 2.1)
    problem = Problem(40, 40, (), 1.0, 0.1, start, end)
    return problem, np.array([start, mid, end])


def test_scheduler_keeps_the_order_dependency():
    problem, w = _swap_problem()
    out = schedule(problem, w)
    plan = _timed_plan(problem, out)
    check_plan(problem, plan)
    # robot 1 cannot arrive while robot 0 is still near the spot: two steps
    assert plan.steps == 2


def test_schedule_that_breaks_an_order_dependency_is_rejected():
    """Negative control: both moves in one step collide, and the validator says so."""
    problem, w = _swap_problem()
    broken = np.array([w[0], w[2]])  # robot 1 enters while robot 0 leaves
    with pytest.raises(PlanInvalid):
        check_plan(problem, _timed_plan(problem, broken))
    # merging the two steps is refused for the same reason
    assert len(merge_steps(problem, w)) == 3


def test_independent_moves_run_together():
    start = np.array([[5.0, 5.0], [35.0, 35.0]])
    mid = np.array([[5.0, 15.0], [35.0, 35.0]])
    end = np.array([[5.0, 15.0], [35.0, 25.0]])
    problem = Problem(40, 40, (), 1.0, 0.1, start, end)
    out = schedule(problem, np.array([start, mid, end]))
    assert len(out) == 2  # one step: both robots move at once
    check_plan(problem, _timed_plan(problem, out))


def test_split_moves_costs_no_time():
    start = np.array([[5.0, 5.0], [30.0, 30.0]])
    end = np.array([[35.0, 5.0], [30.0, 30.0]])
    problem = Problem(40, 40, (), 1.0, 0.1, start, end)
    w = np.array([start, end])
    pieces = split_moves(problem, w)
    assert len(pieces) > 2
    assert _timed_plan(problem, pieces).makespan == pytest.approx(_timed_plan(problem, w).makespan, rel=1e-9)
    assert all(len(s) == 1 for s in steps_of(pieces))


def test_shortcut_removes_a_detour():
    start = np.array([[5.0, 5.0]])
    via = np.array([[20.0, 35.0]])
    end = np.array([[35.0, 5.0]])
    problem = Problem(40, 40, (), 1.0, 0.1, start, end)
    w = np.array([start, via, end])
    out = shortcut(problem, w)
    assert _timed_plan(problem, out).makespan < _timed_plan(problem, w).makespan
    check_plan(problem, _timed_plan(problem, out))


def test_scheduler_falls_back_to_layer_by_layer_for_long_plans(monkeypatch):
    import planner.schedule as sched

    problem, w = _swap_problem()
    expected = schedule(problem, w)
    calls = []
    original = sched._schedule_by_layer
    monkeypatch.setattr(sched, "_PAIRS_LIMIT", 0)
    monkeypatch.setattr(sched, "_schedule_by_layer", lambda *a: calls.append(1) or original(*a))
    assert np.array_equal(sched.schedule(problem, w), expected) and calls


def test_a_move_never_joins_a_layer_through_a_robot_parked_there():
    """Robot 1 stays parked at X during layer 0 (its move would cross robot 2's);
    robot 0 passes X after robot 1 left, so it must not join layer 0."""
    w0 = np.array([[2.0, 10.0], [10.0, 10.0], [20.0, 20.0]])
    w1 = w0.copy()
    w1[2] = [2.0, 20.0]  # robot 2 crosses robot 1's path
    w2 = w1.copy()
    w2[1] = [10.0, 30.0]  # robot 1 leaves X
    w3 = w2.copy()
    w3[0] = [18.0, 10.0]  # robot 0 passes X
    problem = Problem(40, 40, (), 1.0, 0.1, w0, w3)
    out = schedule(problem, np.array([w0, w1, w2, w3]))
    assert np.array_equal(out, np.array([w0, w1, w3]))  # layers: {2}, {1, 0}
    check_plan(problem, _timed_plan(problem, out))


@settings(max_examples=20, deadline=None)
@given(st.integers(0, 2**31), st.integers(1, 9))
def test_steps_clear_is_step_clear_for_every_step(seed, m):
    """The batched test agrees with the one-step test, on steps that are and are not clear."""
    from planner.schedule import step_clear, steps_clear

    problem, rng = _random_problem(seed, m)
    k = 12
    a = np.repeat(problem.start[None], k, axis=0)
    b = a.copy()
    for j in range(k):  # a few robots each jump somewhere, some through obstacles or each other
        movers = rng.choice(m, size=rng.integers(0, m + 1), replace=False)
        b[j, movers] = problem.target[rng.permutation(m)[: len(movers)]]
    fast = steps_clear(problem, a, b)
    assert fast.tolist() == [step_clear(problem, a[j], b[j]) for j in range(k)]


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2**31), st.integers(1, 9))
def test_steps_clear_through_a_clear_middle_point(seed, m):
    """Joined steps tested with their middle waypoints (``via``) give what testing every move
    gives, where the two pieces are clear: moves along an axis through, short of or back from
    the middle, moves that turn there (which may cut a corner through an obstacle) and moves
    in one piece only."""
    from planner.schedule import steps_clear

    problem, rng = _random_problem(seed, m)
    k = 16
    a = np.repeat(problem.start[None], k, axis=0)
    mid, b = a.copy(), a.copy()
    for j in range(k):
        for r in range(m):
            kind = rng.integers(4)
            d = rng.normal(size=2) * rng.uniform(0.5, 6.0)
            if kind == 0:  # along an axis: the middle before, on or past the end
                d[rng.integers(2)] = 0.0
                mid[j, r], b[j, r] = a[j, r] + rng.uniform(-1, 2) * d, a[j, r] + d
            elif kind == 1:  # a turn at the middle
                mid[j, r], b[j, r] = a[j, r] + d, a[j, r] + d + rng.normal(size=2) * 3.0
            elif kind == 2:  # only the second piece moves
                b[j, r] = a[j, r] + d
    ok1 = problem.env.segments_clear(a.reshape(-1, 2), mid.reshape(-1, 2), problem.clearance)
    ok2 = problem.env.segments_clear(mid.reshape(-1, 2), b.reshape(-1, 2), problem.clearance)
    keep = (ok1 & ok2).reshape(k, m).all(axis=1)  # only joins whose pieces are clear qualify
    full = steps_clear(problem, a, b)
    fast = steps_clear(problem, a, b, via=mid)
    assert fast[keep].tolist() == full[keep].tolist()


def test_steps_clear_through_a_middle_point_still_tests_a_cut_corner():
    """Negative control: an L-shaped pair of clear pieces round a box corner joins into a
    diagonal through the box, which the test with ``via`` still refuses."""
    from planner.schedule import steps_clear

    box = Polygon(np.array([[4.0, 4.0], [8.0, 4.0], [8.0, 8.0], [4.0, 8.0]]))
    a, mid, b = np.array([[[2.0, 6.0]]]), np.array([[[2.0, 10.0]]]), np.array([[[10.0, 10.0]]])
    a2, b2 = np.array([[[2.0, 10.0]]]), np.array([[[6.0, 10.0]]])
    problem = Problem(20, 20, (box,), 1.0, 0.1, a[0], b[0])
    assert problem.env.segments_clear(a[0], mid[0], problem.clearance).all()
    assert problem.env.segments_clear(mid[0], b[0], problem.clearance).all()
    assert not steps_clear(problem, a, b, via=mid)[0]
    # a straight-on join of clear pieces is clear, with or without the shortcut
    assert steps_clear(problem, a2, b2, via=np.array([[[4.0, 10.0]]]))[0]
    assert steps_clear(problem, a2, b2)[0]


def _merge_moves_one_by_one(problem, w):
    """merge_moves as a plain greedy loop, one clearance test at a time (the reference)."""
    from planner.geometry import point_segment_distance

    out = [w[0]]
    movers = steps_of(w)
    k = 0
    while k < len(movers):
        cur = w[k + 1]
        if len(movers[k]) == 1:
            r = int(movers[k][0])
            start, j = out[-1][r], k
            while j + 1 < len(movers) and len(movers[j + 1]) == 1 and int(movers[j + 1][0]) == r:
                end = w[j + 2][r]
                parked = np.delete(out[-1], r, axis=0)
                if not problem.env.segments_clear(start[None], end[None], problem.clearance)[0]:
                    break
                if len(parked) and point_segment_distance(parked, start, end).min() < problem.separation:
                    break
                j += 1
            if j > k:
                cur, k = w[j + 1], j
        out.append(cur)
        k += 1
    return np.asarray(out)


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 2**31), st.integers(1, 8))
def test_merge_moves_batched_is_the_greedy_loop(seed, m):
    problem, rng = _random_problem(seed, m)
    w = [problem.start.copy()]
    for _ in range(30):  # runs of single-robot moves, now and then several robots at once
        nxt = w[-1].copy()
        movers = rng.choice(m, size=1 if rng.random() < 0.8 else rng.integers(1, m + 1), replace=False)
        if rng.random() < 0.7 and len(w) > 1:  # keep moving the robot of the last step
            moved = np.flatnonzero(np.any(w[-1] != w[-2], axis=1))
            movers = moved[:1] if len(moved) else movers
        nxt[movers] += rng.normal(0, 3, size=(len(movers), 2))
        w.append(nxt)
    w = np.asarray(w)
    from planner.schedule import merge_moves

    assert np.array_equal(merge_moves(problem, w), _merge_moves_one_by_one(problem, w))
