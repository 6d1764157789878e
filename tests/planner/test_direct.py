"""Auto mode's direct tries: whole-placement chains, grouped moves, the roadmap's incumbent."""

import time
from pathlib import Path

import numpy as np
import pytest

import planner.planning as planning
import planner.sequenced as sequenced
from planner import Plan, PlannerParams, check_plan, plan
from planner.bounds import lower_bounds
from planner.connect import sequenced_moves
from planner.problem import Polygon, Problem
from planner.upump import STAGES, build_roadmap, stage_chain
from planner.validate import PlanInvalid
from sim.scenario import build_problem, read_scenario

ROOT = Path(__file__).resolve().parents[2]


def _rotation(side: float, phi: float, k: int = 3) -> Problem:
    """A regular k-gon of robots turned by ``phi``: every robot's chord passes the next one's source."""
    r = side / (2 * np.sin(np.pi / k))
    ang = 2 * np.pi * np.arange(k) / k
    c = np.array([10.0, 10.0])
    start = c + r * np.stack([np.cos(ang), np.sin(ang)], axis=1)
    target = c + r * np.stack([np.cos(ang + phi), np.sin(ang + phi)], axis=1)
    return Problem(20.0, 20.0, (), 1.0, 0.1, start, target)


def _plan_of(problem: Problem, seq) -> Plan:
    w = np.asarray([problem.start, *seq.waypoints(problem.start, seq.rows)])
    return Plan.from_waypoints(w, problem.radius, problem.margin, problem.max_speed, problem.max_accel)


def test_a_dependency_cycle_moves_as_one_group():
    problem = _rotation(2.6, 0.8)
    assert sequenced_moves(problem, problem.start, problem.target) is None  # a cycle
    seq = sequenced_moves(problem, problem.start, problem.target, groups=True)
    assert [sorted(g) for g in seq.groups] == [[0, 1, 2]]
    assert check_plan(problem, _plan_of(problem, seq)).value >= problem.margin


def test_a_group_whose_robots_would_meet_is_refused(monkeypatch):
    # Turned further, the three chords' midpoints come closer than the separation.
    problem = _rotation(2.3, 1.0)
    assert sequenced_moves(problem, problem.start, problem.target, groups=True) is None
    # Negative control: without the closest-approach check inside the group,
    # the grouped move is returned and the exact validator rejects it.
    monkeypatch.setattr(sequenced, "closest_approach", lambda a, b, c, d: np.full((3, 3, 1), np.inf))
    seq = sequenced_moves(problem, problem.start, problem.target, groups=True)
    assert seq is not None
    with pytest.raises(PlanInvalid):
        check_plan(problem, _plan_of(problem, seq))


def _scenario(name: str, seed: int) -> Problem:
    sc = read_scenario(ROOT / "scenarios" / "paper" / f"{name}.yaml")
    return build_problem(sc, np.random.default_rng(seed))


@pytest.mark.parametrize("seed", range(4))
def test_expand_cross_contract_chain_is_whole_and_its_plan_valid(seed):
    problem = _scenario("fig1-line-to-phi", seed)  # a line too tight for CAPT: it expands first
    chain = stage_chain(problem, "expand-cross-contract")
    assert len(chain) >= 4 and all(len(p) == problem.m for p in chain)
    assert np.array_equal(chain[0], problem.start) and np.array_equal(chain[-1], problem.target)
    raw = planning._chain_waypoints(problem, chain)
    waypoints, _, makespan = planning._timed(problem, PlannerParams(), raw)
    assert sorted(map(tuple, waypoints[-1])) == sorted(map(tuple, problem.target))
    result = Plan.from_waypoints(waypoints, problem.radius, problem.margin, problem.max_speed, problem.max_accel)
    assert check_plan(problem, result).value >= problem.margin
    assert makespan == pytest.approx(result.makespan)


def test_line_to_phi_is_planned_without_pebble_graphs_when_a_chain_is_good_enough():
    solved_directly = 0
    for seed in range(6):
        problem = _scenario("fig1-line-to-phi", seed)
        result, stats = plan(problem, PlannerParams(), np.random.default_rng(seed))
        assert check_plan(problem, result).value >= problem.margin
        if stats.graphs == 0:
            solved_directly += 1
            assert stats.extra["direct"] in ("one step", *STAGES)
            assert stats.makespan_s <= 2.0 * lower_bounds(problem)[0] + 1e-9
    assert solved_directly >= 3


def _walled_in():
    box = (
        Polygon(np.array([[5, 5], [15, 5], [15, 6], [5, 6]])),
        Polygon(np.array([[5, 14], [15, 14], [15, 15], [5, 15]])),
        Polygon(np.array([[5, 6], [6, 6], [6, 14], [5, 14]])),
        Polygon(np.array([[14, 6], [15, 6], [15, 14], [14, 14]])),
    )
    return Problem(40, 40, box, 1.0, 0.1, np.array([[10.0, 10.0], [30.0, 30.0]]),
                   np.array([[30.0, 10.0], [25.0, 30.0]]))


def test_with_an_incumbent_the_roadmap_neither_samples_on_nor_fails():
    problem = _walled_in()  # nothing connects; without an incumbent it samples to the limit
    t0 = time.perf_counter()
    _, _, _, stats = build_roadmap(problem, PlannerParams(time_limit=20), np.random.default_rng(0),
                                   time.perf_counter() + 20, makespan=lambda rm, route: 1.0,
                                   incumbent=1e9, covered=set(STAGES))
    assert time.perf_counter() - t0 < 5
    assert stats.found and stats.graphs <= 1  # at most the shared graph


def test_stages_run_directly_are_not_run_again_by_the_roadmap(monkeypatch):
    problem = _scenario("fig1-line-to-phi", 0)
    calls = []
    import planner.upump as upump

    for name in ("_add_capt", "_add_direct_chain"):
        real = getattr(upump, name)
        monkeypatch.setattr(upump, name, lambda *a, _n=name, _r=real: (calls.append(_n), _r(*a))[1])
    build_roadmap(problem, PlannerParams(), np.random.default_rng(0), time.perf_counter() + 20,
                  makespan=lambda rm, route: 1e9, incumbent=1e9, covered={"expand-cross-contract"})
    assert calls == ["_add_direct_chain"]
