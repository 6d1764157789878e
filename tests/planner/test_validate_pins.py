"""What the exact validator reports, pinned: the gap, who, the step and the time.

A verdict names where a plan comes closest; these tests check each field of that
report against an independent computation (the plan sampled at the reported time),
and the margin at its exact boundary.  They are the tests that mutation testing of
``planner/validate.py`` relies on (see ``tests/mutation/``).
"""

import numpy as np
import pytest
from scipy.optimize import brentq

from planner import Plan, PlanInvalid, check_plan, min_clearance
from planner.plan import min_jerk_s
from planner.problem import Circle, Polygon, Problem
from planner.validate import Clearance, _same_set, _theta_to_time
from sim.execute.contacts import static_clearances

R = 1.0


def _problem(start, obstacles=(), margin=0.1, target=None):
    start = np.asarray(start, float)
    return Problem(40, 40, tuple(obstacles), R, margin, start, start if target is None else np.asarray(target, float))


def _plan(waypoints, durations, margin=0.1):
    return Plan(R, margin, np.asarray(durations, float), np.asarray(waypoints, float))


def _time_of(step_start, duration, theta):
    return step_start + duration * brentq(lambda u: min_jerk_s(u) - theta, 0.0, 1.0, xtol=1e-14)


def _gap_at(problem, plan, c: Clearance) -> float:
    pos = plan.sample([c.time])[0][0]
    if c.kind == "robot-robot":
        i, j = c.robots
        return float(np.linalg.norm(pos[i] - pos[j]) - 2 * R)
    col = -1 if c.obstacle is None else c.obstacle
    return float(static_clearances(problem.env, pos[list(c.robots)], len(problem.obstacles))[0, col] - R)


TRIANGLE = Polygon(np.array([[16.0, 15.0], [24.0, 15.0], [20.0, 22.0]]))


def test_circle_minimum_inside_a_step():
    # robot 0 passes the circle at x = 20, 40 % along its move; step 1 starts at t = 3
    problem = _problem([[12, 25], [5, 5]], [Circle((20, 20), 3.0)], target=[[32, 25], [5, 5]])
    plan = _plan([[[12, 25], [5, 5]], [[12, 25], [6, 5]], [[32, 25], [6, 5]], [[32, 25], [5, 5]]], [3.0, 2.0, 1.0])
    c = min_clearance(problem, plan)
    assert (c.kind, c.robots, c.obstacle, c.step) == ("robot-obstacle", (0,), 0, 1)
    assert c.value == pytest.approx(1.0, abs=1e-12)
    assert c.time == pytest.approx(_time_of(3.0, 2.0, 0.4), abs=1e-9)
    assert _gap_at(problem, plan, c) == pytest.approx(c.value, abs=1e-9)


def test_polygon_minimum_at_a_vertex_projection():
    problem = _problem([[12, 25]], [TRIANGLE], target=[[32, 25]])
    plan = _plan([[[12, 25]], [[32, 25]]], [2.0])
    c = min_clearance(problem, plan)
    assert (c.kind, c.robots, c.obstacle, c.step) == ("robot-obstacle", (0,), 0, 0)
    assert c.value == pytest.approx(2.0, abs=1e-12)
    assert c.time == pytest.approx(_time_of(0.0, 2.0, 0.4), abs=1e-9)


def test_polygon_minimum_where_the_path_crosses_an_edge():
    # a slanted bar no vertex of which projects inside it: only the edge crossings are at gap -r
    bar = Polygon(np.array([[18.0, 10.0], [19.0, 10.0], [23.0, 30.0], [22.0, 30.0]]))
    problem = _problem([[4, 20]], [bar], target=[[36, 20]])
    plan = _plan([[[4, 20]], [[36, 20]]], [2.0])
    c = min_clearance(problem, plan)
    assert (c.kind, c.obstacle, c.step, c.value) == ("robot-obstacle", 0, 0, -R)
    pos = plan.sample([c.time])[0][0]
    assert 20.0 - 1e-9 <= pos[0, 0] <= 21.0 + 1e-9
    # a path that ends inside: the end is as deep as any point
    problem = _problem([[4, 16]], [TRIANGLE], target=[[20, 16]])
    c = min_clearance(problem, _plan([[[4, 16]], [[20, 16]]], [2.0]))
    assert (c.kind, c.obstacle, c.step, c.value) == ("robot-obstacle", 0, 0, -R)
    assert c.time == pytest.approx(2.0, abs=1e-5)


def test_wall_minimum_at_the_end_of_a_move_toward_it():
    problem = _problem([[20, 20]], target=[[20, 37.5]])
    plan = _plan([[[20, 20]], [[20, 37.5]]], [2.5])
    c = min_clearance(problem, plan)
    assert (c.kind, c.robots, c.obstacle, c.step) == ("robot-wall", (0,), None, 0)
    assert c.value == pytest.approx(1.5, abs=1e-12)
    assert c.time == pytest.approx(2.5, abs=1e-5)  # the time scaling is flat at its ends


def test_robot_pair_minimum_at_closest_approach():
    # robot 1 passes robot 0 at distance 3; robot 2 waits far away
    start = [[20, 23], [10, 20], [35, 35]]
    target = [[20, 23], [30, 20], [35, 35]]
    problem = _problem(start, target=target)
    plan = _plan([start, start, target], [1.0, 4.0])
    c = min_clearance(problem, plan)
    assert (c.kind, c.robots, c.obstacle, c.step) == ("robot-robot", (0, 1), None, 1)
    assert c.value == pytest.approx(1.0, abs=1e-12)
    assert c.time == pytest.approx(3.0, abs=1e-9)
    # the pair is reported smaller index first whichever robot moves
    plan2 = _plan([np.array(start)[[1, 0, 2]], np.array(target)[[1, 0, 2]]], [4.0])
    c2 = min_clearance(_problem(np.array(start)[[1, 0, 2]], target=np.array(target)[[1, 0, 2]]), plan2)
    assert c2.robots == (0, 1) and c2.time == pytest.approx(2.0, abs=1e-9)


def test_the_start_placement_is_reported_as_step_minus_one():
    start = [[10, 10], [12.5, 10], [30, 30]]
    problem = _problem(start, target=[[10, 10], [12.5, 10], [30, 20]])
    plan = _plan([start, [[10, 10], [12.5, 10], [30, 20]]], [1.0])
    c = min_clearance(problem, plan)
    assert (c.kind, c.robots, c.step, c.time) == ("robot-robot", (0, 1), -1, 0.0)
    assert c.value == pytest.approx(0.5, abs=1e-12)
    start = [[1.25, 10], [20, 20]]
    c = min_clearance(_problem(start), _plan([start], []))
    assert (c.kind, c.robots, c.obstacle, c.step, c.time) == ("robot-wall", (0,), None, -1, 0.0)
    assert c.value == pytest.approx(0.25)
    start = [[20, 24.5], [5, 5]]
    c = min_clearance(_problem(start, [Circle((20, 20), 3.0)]), _plan([start], []))
    assert (c.kind, c.robots, c.obstacle, c.step) == ("robot-obstacle", (0,), 0, -1)
    assert c.value == pytest.approx(0.5)


def test_a_single_robot_has_no_pair():
    c = min_clearance(_problem([[20, 20]]), _plan([[[20, 20]]], []))
    assert (c.kind, c.value) == ("robot-wall", 19.0)


def test_the_earliest_of_equal_minima_is_reported():
    # the same pass twice: the first one is reported
    start = [[20, 23], [10, 20]]
    target = [[20, 23], [10, 20]]
    problem = _problem(start, target=target)
    plan = _plan([start, [[20, 23], [30, 20]], target], [2.0, 2.0])
    c = min_clearance(problem, plan)
    assert c.step == 0 and c.time == pytest.approx(1.0, abs=1e-9)


def test_margin_boundary_is_inclusive():
    # two robots 2 r + margin apart: exactly at the margin passes
    start = [[10.0, 10.0], [12.5, 10.0]]
    plan = _plan([start], [], margin=0.5)
    assert check_plan(_problem(start, margin=0.5), plan).value == 0.5
    # within the tolerance of 1e-9 below the margin still passes, more does not
    start_tol = [[10.0, 10.0], [12.5 - 4e-10, 10.0]]
    check_plan(_problem(start_tol, margin=0.5), _plan([start_tol], [], margin=0.5))
    close = [[10.0, 10.0], [12.5 - 1e-7, 10.0]]
    with pytest.raises(PlanInvalid) as e:
        check_plan(_problem(close, margin=0.5), _plan([close], [], margin=0.5))
    assert str(e.value) == "plan violates the margin 0.5: gap 0.5 between robots 0 and 1 at t = 0.000 s (step -1)"
    assert e.value.clearance.robots == (0, 1)
    # a custom tolerance is honoured
    check_plan(_problem(close, margin=0.5), _plan([close], [], margin=0.5), tol=1e-6)


def test_check_plan_names_what_is_wrong():
    start = [[10, 10], [20, 20]]
    problem = _problem(start, target=[[10, 30], [20, 20]])
    with pytest.raises(PlanInvalid) as e:
        check_plan(problem, _plan([[[10, 10]], [[10, 30]]], [1.0]))
    assert str(e.value) == "plan moves 1 robots, problem has 2"
    assert e.value.clearance is None
    with pytest.raises(PlanInvalid) as e:
        check_plan(problem, _plan([[[10, 10], [20, 21]], [[10, 30], [20, 20]]], [1.0]))
    assert str(e.value) == "robot 1 does not start at its start position"
    with pytest.raises(PlanInvalid) as e:
        check_plan(problem, _plan([start, [[10, 29], [20, 20]]], [1.0]))
    assert str(e.value) == "the plan does not end on the target placement"
    # labels do not matter: robot 0 may end on robot 1's target
    swapped = _problem(start, target=[[20, 20], [10, 10]])
    assert check_plan(swapped, _plan([start], [])).value == pytest.approx(9.0)
    # a start within 1e-6 is the start
    check_plan(problem, _plan([[[10, 10 + 5e-7], [20, 20]], [[10, 30], [20, 20]]], [1.0]))


def test_describe_names_robots_obstacles_and_walls():
    assert Clearance(0.25, "robot-robot", (2, 5), None, 3, 1.5).describe() == (
        "gap 0.25 between robots 2 and 5 at t = 1.500 s (step 3)"
    )
    assert Clearance(-0.125, "robot-obstacle", (4,), 7, 0, 0.25).describe() == (
        "gap -0.125 between robot 4 and obstacle 7 at t = 0.250 s (step 0)"
    )
    assert Clearance(0.5, "robot-wall", (1,), None, -1, 0.0).describe() == (
        "gap 0.5 between robot 1 and the wall at t = 0.000 s (step -1)"
    )
    assert Clearance(0.5, "robot-obstacle", (1,), 0, 2, 1.0).describe().endswith("robot 1 and obstacle 0 at t = 1.000 s (step 2)")


def test_theta_to_time_inverts_the_time_scaling():
    plan = _plan([[[0, 0]], [[1, 0]], [[2, 0]]], [2.0, 4.0])
    assert _theta_to_time(plan, -1, 0.7) == 0.0
    assert _theta_to_time(plan, 0, 0.0) == pytest.approx(0.0, abs=1e-12)
    assert _theta_to_time(plan, 0, 1.0) == pytest.approx(2.0, abs=1e-5)
    assert _theta_to_time(plan, 1, 0.5) == pytest.approx(4.0, abs=1e-12)
    for theta in (0.1, 0.25, 0.9):
        assert _theta_to_time(plan, 1, theta) == pytest.approx(_time_of(2.0, 4.0, theta), abs=1e-12)


def test_same_set_tolerance_is_inclusive():
    a = np.array([[0.0, 0.0], [4.0, 0.0]])
    assert _same_set(a, a[::-1])
    assert _same_set(a, a + [0.5, 0.0], atol=0.5)
    assert not _same_set(a, a + [0.5, 0.0], atol=0.25)
    assert _same_set(a, a + [0.5e-6, 0.0])
    assert not _same_set(a, a + [2e-6, 0.0])


def test_the_robot_nearest_the_world_or_a_neighbour_is_named_at_the_start():
    start = [[20, 20], [1.5, 30], [30, 30], [33.0, 30], [10, 10]]
    c = min_clearance(_problem(start), _plan([start], []))
    assert (c.kind, c.robots, c.value) == ("robot-wall", (1,), 0.5)
    start = [[20, 20], [30, 30], [5, 30], [33.0, 30], [10, 10]]
    c = min_clearance(_problem(start), _plan([start], []))
    assert (c.kind, c.robots) == ("robot-robot", (1, 3))
    assert c.value == pytest.approx(1.0)


def test_gaps_subtract_the_radius_whatever_it_is():
    r = 0.5
    start = np.array([[10.0, 10.0], [12.0, 10.0]])
    target = np.array([[10.0, 10.0], [12.0, 30.0]])
    problem = Problem(40, 40, (), r, 0.1, start, target)
    c = min_clearance(problem, Plan(r, 0.1, np.array([1.0]), np.array([start, target])))
    assert c.kind == "robot-robot" and c.value == pytest.approx(1.0)
    # a move toward the wall, the pair far apart
    start = np.array([[10.0, 10.0], [30.0, 20.0]])
    target = np.array([[10.0, 10.0], [39.0, 20.0]])
    problem = Problem(40, 40, (), r, 0.1, start, target)
    c = min_clearance(problem, Plan(r, 0.1, np.array([1.0]), np.array([start, target])))
    assert (c.kind, c.robots, c.step) == ("robot-wall", (1,), 0) and c.value == pytest.approx(0.5)
    # a pass between two moving robots
    start = np.array([[10.0, 20.0], [30.0, 22.0]])
    target = np.array([[30.0, 20.0], [10.0, 22.0]])
    problem = Problem(40, 40, (), r, 0.1, start, target)
    c = min_clearance(problem, Plan(r, 0.1, np.array([2.0]), np.array([start, target])))
    assert (c.kind, c.step) == ("robot-robot", 0) and c.value == pytest.approx(1.0)
    assert c.time == pytest.approx(1.0, abs=1e-9)


def test_a_move_just_below_the_start_minimum_is_reported():
    # start: robot 1 is 2.5 from the wall (gap 1.5); robot 0 then passes the circle at gap 1
    problem = _problem([[12, 25], [3.5, 5]], [Circle((20, 20), 3.0)], target=[[32, 25], [3.5, 5]])
    plan = _plan([[[12, 25], [3.5, 5]], [[32, 25], [3.5, 5]]], [2.0])
    c = min_clearance(problem, plan)
    assert (c.kind, c.robots, c.step) == ("robot-obstacle", (0,), 0) and c.value == pytest.approx(1.0)


def test_ties_go_to_what_is_found_first():
    # start: a wall gap of 0.5 and a pair gap of 0.5: the wall is reported
    start = [[1.5, 20], [20, 20], [22.5, 20]]
    c = min_clearance(_problem(start), _plan([start], []))
    assert (c.kind, c.robots, c.step) == ("robot-wall", (0,), -1)
    # a later move reaching the same gap does not replace the start placement
    start = [[1.5, 20], [20, 5], [30, 30]]
    target = [[1.5, 20], [20, 1.5], [30, 30]]
    c = min_clearance(_problem(start, target=target), _plan([start, target], [1.0]))
    assert (c.robots, c.step) == ((0,), -1)
    start = [[10, 10], [12.5, 10], [20, 30], [25, 32.5]]
    target = [[10, 10], [12.5, 10], [30, 30], [25, 32.5]]
    c = min_clearance(_problem(start, target=target), _plan([start, target], [1.0]))
    assert (c.robots, c.step) == ((0, 1), -1)


def test_both_robots_of_a_pair_moving_in_a_later_step():
    # step 0 puts robot 1 in place; in step 1 both move and pass at the middle
    start = [[10, 20], [30, 30]]
    mid = [[10, 20], [30, 22]]
    end = [[30, 20], [10, 22]]
    problem = _problem(start, target=end)
    plan = _plan([start, mid, end], [1.0, 2.0])
    c = min_clearance(problem, plan)
    assert (c.kind, c.robots, c.step) == ("robot-robot", (0, 1), 1)
    assert c.time == pytest.approx(2.0, abs=1e-9)


def test_a_move_back_to_the_start_is_checked():
    # the last leg returns robot 0 to its start, passing the circle
    a, b, cpt = [12, 25], [12, 35], [32, 35]
    problem = _problem([a, [35, 5]], [Circle((22, 20), 3.0)])
    plan = _plan([[a, [35, 5]], [b, [35, 5]], [cpt, [35, 5]], [[32, 25], [35, 5]], [a, [35, 5]]], [1, 1, 1, 2])
    c = min_clearance(problem, plan)
    assert (c.kind, c.step) == ("robot-obstacle", 3) and c.value == pytest.approx(1.0)
    assert c.time == pytest.approx(_time_of(3.0, 2.0, 0.5), abs=1e-9)


def test_a_unit_move_toward_an_obstacle_ends_at_its_minimum():
    problem = _problem([[20, 26]], [Circle((20, 20), 3.0)], target=[[20, 25]])
    c = min_clearance(problem, _plan([[[20, 26]], [[20, 25]]], [1.5]))
    assert (c.step, c.value) == (0, pytest.approx(1.0))
    assert c.time == pytest.approx(1.5, abs=1e-5)


# a polygon with a vertex beyond the path's end and an edge whose line crosses the
# path's line there: the minimum on the path itself is at its middle (x = 15)
NOTCH = Polygon(np.array([[15, 24], [12, 20], [30, 20], [30, 25.5], [26, 25.5], [22, 22]], float))


@pytest.mark.parametrize("forward", [True, False])
def test_candidates_off_the_path_are_not_taken(forward):
    a, b = ([10, 25], [20, 25]) if forward else ([20, 25], [10, 25])
    problem = _problem([a, [3, 35]], [NOTCH], target=[b, [3, 35]])
    plan = _plan([[a, [3, 35]], [b, [3, 35]]], [2.0])
    c = min_clearance(problem, plan)
    assert (c.kind, c.robots, c.obstacle, c.step) == ("robot-obstacle", (0,), 0, 0)
    assert c.value == pytest.approx(0.0, abs=1e-12)
    assert c.time == pytest.approx(1.0, abs=1e-9)


def test_a_slanted_path_through_a_bar_is_timed_at_a_crossing():
    bar = Polygon(np.array([[18.0, 10.0], [19.0, 10.0], [23.0, 30.0], [22.0, 30.0], [20.0, 20.5]]))
    a, b = np.array([4.0, 16.0]), np.array([36.0, 24.0])
    problem = _problem([a], [bar], target=[b])
    plan = _plan([[a], [b]], [2.0])
    c = min_clearance(problem, plan)
    assert (c.kind, c.obstacle, c.value) == ("robot-obstacle", 0, -R)
    pos = plan.sample([c.time])[0][0]
    assert problem.env.point_clearance(pos)[0] == pytest.approx(0.0, abs=1e-9)


def test_a_path_along_an_edge_line_is_timed():
    bar = Polygon(np.array([[18.0, 10.0], [19.0, 10.0], [23.0, 30.0], [22.0, 30.0]]))
    problem = _problem([[4, 10]], [bar], target=[[36, 10]])
    plan = _plan([[[4, 10]], [[36, 10]]], [2.0])
    c = min_clearance(problem, plan)
    assert np.isfinite(c.time) and c.value == -R
    assert 18.0 - 1e-9 <= plan.sample([c.time])[0][0, 0, 0] <= 19.0 + 1e-9


def test_chunked_pair_search_finds_the_same_earliest_minimum(monkeypatch):
    import planner.validate as validate

    rng = np.random.default_rng(3)
    start = rng.uniform(3, 37, size=(6, 2))
    w = [start]
    for _ in range(8):
        nxt = w[-1].copy()
        nxt[rng.integers(6)] = rng.uniform(3, 37, size=2)
        w.append(nxt)
    # two identical passes of robots far from the others, in steps 9 and 11
    w = np.array(w)
    problem = _problem(w[0], target=w[-1])
    plan = _plan(w, np.ones(len(w) - 1))
    whole = min_clearance(problem, plan)
    monkeypatch.setattr(validate, "_PAIRS_PER_CALL", 7)
    assert min_clearance(problem, plan) == whole
    monkeypatch.setattr(validate, "_PAIRS_PER_CALL", 1)
    assert min_clearance(problem, plan) == whole
    # equal minima in different chunks: the earliest is kept
    start = [[10, 20], [20, 23], [35, 35]]
    w = np.array([start, [[30, 20], [20, 23], [35, 35]], [[30, 20], [20, 23], [5, 35]], [[10, 20], [20, 23], [5, 35]]], float)
    problem = _problem(w[0], target=w[-1])
    plan = _plan(w, [1.0, 1.0, 1.0])
    c = min_clearance(problem, plan)
    assert (c.robots, c.step) == ((0, 1), 0)
    monkeypatch.setattr(validate, "_PAIRS_PER_CALL", 3)
    assert min_clearance(problem, plan) == c


def test_start_tolerance_is_absolute_one_micron_per_unit():
    r = 0.01
    start = np.array([[0.03, 0.03], [0.06, 0.03]])
    problem = Problem(40, 40, (), r, 0.001, start, start)
    check_plan(problem, Plan(r, 0.001, np.zeros(0), (start + [5e-7, 0])[None]))
    with pytest.raises(PlanInvalid, match="robot 0 does not start"):
        check_plan(problem, Plan(r, 0.001, np.zeros(0), (start + [[2e-6, 0], [0, 0]])[None]))


def test_the_wrong_start_names_the_farthest_robot():
    start = [[10, 10], [30, 30]]
    problem = _problem(start)
    with pytest.raises(PlanInvalid, match=r"^robot 0 does not start at its start position$"):
        check_plan(problem, _plan([[[10, 11], [30, 30]]], []))


def test_zero_tolerance_keeps_the_margin_exact():
    start = [[10.0, 10.0], [12.5, 10.0]]
    assert check_plan(_problem(start, margin=0.5), _plan([start], [], margin=0.5), tol=0.0).value == 0.5


@pytest.mark.parametrize(
    "a, b, bar",
    [
        # a long, slightly slanted path through a slanted bar no vertex of which projects inside it
        ([4.0, 14.0], [36.0, 26.0], [[18.0, 10.0], [19.0, 10.0], [23.0, 30.0], [22.0, 30.0]]),
        # a path shorter than the bar's edges (their cross product is below 1)
        ([20.1, 20.0], [20.9, 20.1], [[20.0, 19.5], [20.2, 19.5], [21.0, 20.5], [20.8, 20.5]]),
    ],
)
def test_a_path_crossing_a_bar_is_timed_inside_it(a, b, bar):
    problem = _problem([a], [Polygon(np.array(bar))], target=[b])
    plan = _plan([[a], [b]], [2.0])
    c = min_clearance(problem, plan)
    assert (c.kind, c.obstacle, c.value) == ("robot-obstacle", 0, -R)
    pos = plan.sample([c.time])[0][0]
    assert problem.env.point_clearance(pos)[0] == pytest.approx(0.0, abs=1e-9)
    # neither end is inside: the time is strictly inside the step
    assert 0.0 < c.time < 2.0
