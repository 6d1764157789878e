"""The cut (throughput) makespan bound: its formula on doors, never above a real plan."""

import math

import numpy as np
import pytest

from planner import Plan, PlannerParams, check_plan, plan
from planner.cutbound import best_lower_bound, cut_lower_bound, cuts
from planner.problem import Polygon, Problem
from planner.stats import PlanStats


def _door(width: float, start, target, side: float = 20.0, thick: float = 2.0) -> Problem:
    mid = side / 2
    lo, hi = mid - width / 2, mid + width / 2
    t = thick / 2
    obs = (Polygon([[mid - t, 0], [mid + t, 0], [mid + t, lo], [mid - t, lo]]),
           Polygon([[mid - t, hi], [mid + t, hi], [mid + t, side], [mid - t, side]]))
    return Problem(side, side, obs, 1.0, 0.1, np.asarray(start, float), np.asarray(target, float)).validate()


def _kinematic(d: float, v: float, a: float) -> float:
    return math.sqrt(2 * d / a) if d <= v * v / (2 * a) else d / v + v / (2 * a)


def _column(x: float, m: int, side: float = 20.0) -> np.ndarray:
    ys = side / 2 + 2.3 * (np.arange(m) - (m - 1) / 2)
    return np.stack([np.full(m, x), ys], axis=1)


def test_door_bound_equals_the_formula():
    # a door exactly as wide as a robot needs: the free part of the cut is one point
    start, target = _column(4.0, 6), _column(16.0, 6)
    problem = _door(2.2, start, target)
    (cut,) = cuts(problem)
    assert cut.k == 6 and cut.a < 1e-5
    x = cut.p[0]
    door = np.array([x, 10.0])
    v, a = problem.max_speed, problem.max_accel
    gap = problem.separation / v
    ds = np.sort(np.linalg.norm(start - door, axis=1))
    es = np.sort(np.linalg.norm(target - door, axis=1))
    first = max(_kinematic(ds[j], v, a) + (5 - j) * gap for j in range(6)) + _kinematic(es[0], v, a)
    second = max(_kinematic(es[j], v, a) + (5 - j) * gap for j in range(6)) + _kinematic(ds[0], v, a)
    assert cut.bound == pytest.approx(max(first, second), abs=1e-4)
    assert cut_lower_bound(problem) == cut.bound


def test_no_cut_without_a_narrow_passage():
    start, target = _column(4.0, 3), _column(16.0, 3)
    assert math.isnan(cut_lower_bound(_door(6.0, start, target)))  # two robots fit side by side
    free = Problem(20.0, 20.0, (), 1.0, 0.1, start, target).validate()
    assert math.isnan(cut_lower_bound(free))
    balanced = _door(2.2, np.vstack([start[:1], target[1:]]), np.vstack([target[:1], start[1:]]))
    assert cut_lower_bound(balanced) > 0  # one robot must still cross
    assert math.isnan(cut_lower_bound(_door(2.2, start[:2], start[1:])))  # nobody crosses


def _frontier_door(name: str) -> Problem:
    from bench.frontier import CASES, case_problem

    return case_problem(next(c for c in CASES if c.name == name), 0)


@pytest.mark.parametrize("width", [2.2, 2.6, 2.5, 3.5])
def test_bound_is_never_above_a_planned_makespan(width):
    if width in (2.2, 2.6):  # 10 robots in 40 x 40 (bench.frontier's door-W)
        problem = _frontier_door(f"door-{width:g}")
    else:
        problem = _door(width, _column(5.0, 4), _column(15.0, 4))
    bound = cut_lower_bound(problem)
    assert math.isfinite(bound)
    result, stats = plan(problem, PlannerParams(time_limit=30), rng=np.random.default_rng(0))
    assert result.makespan >= bound
    stats.makespan_lower_bound_cut_s = bound
    assert best_lower_bound(stats) == max(bound, stats.makespan_lower_bound_s)


def _staggered_pair():
    """Two robots through a thin door 4.22 wide side by side but staggered (a = 2.02 < 2.1),
    in one straight step: a valid plan that crosses both within 0.65 / speed."""
    start = np.array([[4.85, 6.0], [4.2, 4.0]])
    target = start + [0.95, 0.0]
    problem = _door(4.22, start, target, side=10.0, thick=0.02)
    result = Plan.from_waypoints(np.stack([start, target]), problem.radius, problem.margin,
                                 problem.max_speed, problem.max_accel)
    check_plan(problem, result)
    return problem, result


def test_bound_holds_for_a_staggered_crossing():
    problem, result = _staggered_pair()
    (cut,) = cuts(problem)
    assert cut.k == 2 and 2.0 < cut.a < 2.1
    assert cut.bound <= result.makespan


def test_a_bound_without_the_cut_width_is_caught():
    # negative control: spacing crossings separation / speed apart (ignoring the width
    # a of the cut's free part) claims more than a valid plan takes
    problem, result = _staggered_pair()
    (cut,) = cuts(problem)
    v = problem.max_speed
    honest_gap = (problem.separation - cut.a) / v
    wrong = cut.bound - honest_gap + problem.separation / v  # k = 2: one gap
    assert cut.bound <= result.makespan < wrong


def test_best_lower_bound_ignores_missing_bounds():
    stats = PlanStats(makespan_lower_bound_s=3.0)
    assert best_lower_bound(stats) == 3.0
    stats.makespan_lower_bound_cut_s = 5.0
    assert best_lower_bound(stats) == 5.0
    assert math.isnan(best_lower_bound(PlanStats()))


def test_deadline_gives_nan():
    problem = _door(2.2, _column(4.0, 3), _column(16.0, 3))
    assert math.isnan(cut_lower_bound(problem, deadline=0.0))
