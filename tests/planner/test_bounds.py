"""Lower bounds (bottleneck and minimum-sum assignment) and auto mode's direct first try."""

import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import planner.planning as planning
from planner import PlannerParams, check_plan, plan
from planner.bounds import bottleneck_distance, lower_bounds, min_sum_distance
from planner.problem import Circle, Polygon, Problem
from planner.upump import STAGES

coords = st.integers(0, 12).map(float)  # small integers: many equal distances (ties)
point = st.tuples(coords, coords)


def _brute(start, target, reduce):
    d = np.linalg.norm(np.asarray(start)[:, None] - np.asarray(target)[None], axis=2)
    m = len(d)
    return min(reduce(d[i, p[i]] for i in range(m)) for p in itertools.permutations(range(m)))


@settings(max_examples=150, deadline=None)
@given(st.integers(1, 6).flatmap(lambda m: st.tuples(st.lists(point, min_size=m, max_size=m),
                                                      st.lists(point, min_size=m, max_size=m))))
def test_assignment_distances_match_brute_force(pts):
    start, target = pts
    assert bottleneck_distance(start, target) == pytest.approx(_brute(start, target, max), abs=1e-12)
    assert min_sum_distance(start, target) == pytest.approx(_brute(start, target, sum), abs=1e-9)


def test_large_bottleneck_agrees_with_a_search_by_hopcroft_karp():
    # the reference tests every threshold with another algorithm (scipy's Hopcroft-Karp)
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import maximum_bipartite_matching

    rng = np.random.default_rng(3)
    for a, b in ((rng.random((90, 2)) * 100, rng.random((90, 2)) * 100),
                 (rng.random((80, 2)) * [100, 50], rng.random((80, 2)) * [100, 50] + [0, 50])):
        d = np.linalg.norm(a[:, None] - b[None], axis=2)
        values = np.unique(d)
        got = bottleneck_distance(a, b)
        k = int(np.searchsorted(values, got))
        assert values[k] == got  # one of the distances

        def perfect(v, d=d):
            return bool(np.all(maximum_bipartite_matching(csr_matrix(d <= v), perm_type="column") >= 0))

        # the threshold holds a perfect matching and the next smaller distance does not
        assert perfect(got) and not perfect(values[k - 1])


def _open_problem(m=6):
    start = np.array([[4.0 + 4 * i, 5.0] for i in range(m)])
    target = np.array([[4.0 + 4 * i, 25.0] for i in range(m)])
    return Problem(40, 40, (), 1.0, 0.1, start, target)


def test_direct_try_solves_an_open_swap_without_pebble_graphs():
    problem = _open_problem()
    result, stats = plan(problem, PlannerParams(), np.random.default_rng(0))
    assert (stats.graphs, stats.connections, stats.extra["route"]) == (0, 1, [0, 1])
    assert check_plan(problem, result).value >= problem.margin
    assert stats.makespan_s >= stats.makespan_lower_bound_s
    assert stats.makespan_s <= 1.5 * lower_bounds(problem)[0]


def test_direct_try_moves_everybody_at_once_when_that_step_is_clear():
    problem = _open_problem()
    result, stats = plan(problem, PlannerParams(), np.random.default_rng(0))
    assert (result.steps, stats.extra["sequential_steps"]) == (1, 1)
    assert stats.makespan_s == pytest.approx(stats.makespan_lower_bound_s)


def _blocked_problem():
    """A circle in one robot's straight path: the single step is not clear."""
    start = np.array([[6.0 + 4 * i, 5.0] for i in range(6)])
    target = np.array([[6.0 + 4 * i, 30.0] for i in range(6)])
    return Problem(40, 40, (Circle((16.0, 17.0), 3.0),), 1.0, 0.1, start, target)


def test_direct_try_sequences_the_moves_when_the_single_step_is_blocked():
    problem = _blocked_problem()
    result, stats = plan(problem, PlannerParams(), np.random.default_rng(0))
    assert (stats.graphs, stats.extra["route"]) == (0, [0, 1])
    assert stats.extra["sequential_steps"] > 1
    assert check_plan(problem, result).value >= problem.margin


def test_direct_try_gives_the_plan_the_roadmap_gives_for_the_same_route(monkeypatch):
    problem = _blocked_problem()
    direct, _ = plan(problem, PlannerParams(), np.random.default_rng(0))
    monkeypatch.setattr(planning, "_direct", lambda *args, **kwargs: None)
    problem = _blocked_problem()
    via_roadmap, stats = plan(problem, PlannerParams(), np.random.default_rng(0))
    assert stats.extra["route"] == [0, 1] and stats.graphs >= 0
    assert np.array_equal(direct.waypoints, via_roadmap.waypoints)
    assert np.array_equal(direct.durations, via_roadmap.durations)


def test_direct_tries_go_on_to_the_structured_stages_when_far_from_the_bound():
    # A wall with one gap: everybody must file through it, so the direct
    # sequenced plan is slow and the structured stages are tried too.
    wall = (Polygon(((0.0, 18.0), (17.0, 18.0), (17.0, 22.0), (0.0, 22.0))),
            Polygon(((23.0, 18.0), (40.0, 18.0), (40.0, 22.0), (23.0, 22.0))))
    start = np.array([[4.0 + 4 * i, 5.0] for i in range(8)])
    target = np.array([[4.0 + 4 * i, 35.0] for i in range(8)])
    problem = Problem(40, 40, wall, 1.0, 0.1, start, target)
    direct = planning._direct(problem, PlannerParams(), {})
    assert not direct.accepted and direct.best[2] > 1.5 * lower_bounds(problem)[0]
    assert set(direct.legs) >= {"sequenced", "guided chain"} and direct.covered == set(STAGES)
    result, stats = plan(problem, PlannerParams(), np.random.default_rng(0))
    assert check_plan(problem, result).value >= problem.margin
    assert stats.makespan_s <= direct.best[2]


def test_fixed_parameters_never_take_the_direct_try():
    problem = _open_problem()
    assert planning._direct(problem, PlannerParams(g=1, q=5), {}) is None
    _, stats = plan(problem, PlannerParams(g=1, q=5), np.random.default_rng(0))
    assert stats.graphs == 1
