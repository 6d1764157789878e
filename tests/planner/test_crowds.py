"""Crowded worlds: the medial-axis bridge of the free-space roadmap, the one-at-a-time
finish, priority inheritance (PIBT), and the frontier's formerly failing seeds."""

from __future__ import annotations

import time

import numpy as np
import pytest

from bench.frontier import CASES, case_problem
from planner import PlannerParams, plan
from planner.endgame import sequential_finish
from planner.freespace import FreeRoadmap, _joined, build_free_roadmap, free_roadmap_waypoints
from planner.geometry import closest_approach
from planner.schedule import step_clear

SEP = 2.1


def _case(name: str, seed: int):
    return case_problem(next(c for c in CASES if c.name == name), seed)


def _steps_clear(waypoints) -> bool:
    """Every step keeps every pair of robots the separation apart (exact)."""
    for a, b in zip(waypoints[:-1], waypoints[1:]):
        m = len(a)
        i, j = np.triu_indices(m, 1)
        if (closest_approach(a[i], b[i], a[j], b[j]) < SEP).any():
            return False
    return True


def _dead_end():
    """A corridor (a path graph along y = 0) closed at x = 12: robot 0 at x = 0,
    robot 1 at x = 3, targets at x = 7.8 and x = 12, vertices 1.2 apart between."""
    xs = [0.0, 3.0, 7.8, 12.0] + [x for x in np.arange(0.0, 12.01, 1.2) if min(
        abs(x - y) for y in (0.0, 3.0, 7.8, 12.0)) > 0.3]
    pts = np.array([[x, 0.0] for x in xs])
    order = np.argsort(pts[:, 0])
    edges = np.stack([order[:-1], order[1:]], axis=1)
    return FreeRoadmap(pts, edges, 2)


def test_finish_fills_the_dead_end_first():
    rm = _dead_end()
    out = sequential_finish(rm, rm.points[:2].copy(), [0, 1], SEP, time.perf_counter() + 10)
    assert out is not None
    end = out[-1]
    assert sorted(end[:, 0].tolist()) == [7.8, 12.0]
    assert end[1, 0] == 12.0  # robot 1 went deep, robot 0 took the mouth
    moving = [int((a != b).any(axis=1).sum()) for a, b in zip([rm.points[:2]] + out[:-1], out)]
    assert set(moving) == {1}  # one robot per step
    assert _steps_clear([rm.points[:2]] + out)


def test_finish_needs_its_search():
    """Negative control: nearest pair first without backtracking (a budget of one try)
    sends robot 1 to the mouth and leaves robot 0 shut out."""
    rm = _dead_end()
    assert sequential_finish(rm, rm.points[:2].copy(), [0, 1], SEP, time.perf_counter() + 10, budget=1) is None


def test_finish_on_targets_is_empty():
    rm = _dead_end()
    assert sequential_finish(rm, rm.points[2:4].copy(), [2, 3], SEP, time.perf_counter() + 10) == []


def test_bridge_joins_a_hairline_channel():
    """clutter-30 seed 0: the only way between two rooms is a gap 2.2465 wide (0.0465 of
    slack); the thinned grid and lanes miss it, the traced medial axis does not."""
    import planner.freespace as fs

    p = _case("clutter-30-m20", 0)
    rm = build_free_roadmap(p)
    assert _joined(rm.n, rm.edges, 2 * p.m)
    assert (p.env.segments_clear(rm.points[rm.edges[:, 0]], rm.points[rm.edges[:, 1]], p.clearance)).all()
    saved = fs._bridge
    try:
        fs._bridge = lambda problem, pts, pairs, fine: (pts, pairs)  # negative control
        bare = build_free_roadmap(p)
    finally:
        fs._bridge = saved
    assert not _joined(bare.n, bare.edges, 2 * p.m)


@pytest.mark.parametrize("router", ["tswap", "pibt"])
def test_routers_reach_the_targets_with_clear_steps(router):
    p = _case("clutter-10-m20", 1)
    w = free_roadmap_waypoints(p, time.perf_counter() + 30, np.random.default_rng(0), router=router)
    assert w is not None
    assert np.array_equal(np.unique(w[-1], axis=0), np.unique(p.target, axis=0))
    assert all(step_clear(p, w[k], w[k + 1]) for k in range(len(w) - 1))


def test_pibt_pushes_a_robot_out_of_a_corridor():
    """Two robots in a corridor, the one in front resting on its target, the one behind
    bound for beyond it: the front robot is pushed along (or the targets swapped), and
    both end on the targets."""
    from planner.pibt import pibt_route

    xs = np.arange(0.0, 15.01, 0.5)
    pts = np.array([[0.0, 0.0], [3.0, 0.0], [3.0, 0.0], [12.0, 0.0]]
                   + [[x, 0.0] for x in xs if x not in (0.0, 3.0, 12.0)])
    order = np.argsort(pts[:, 0], kind="stable")
    edges = np.stack([order[:-1], order[1:]], axis=1)
    edges = edges[np.linalg.norm(pts[edges[:, 0]] - pts[edges[:, 1]], axis=1) > 0]
    edges = np.vstack([edges, [[1, 2]]])  # start 1 and target 0 are one place
    rm = FreeRoadmap(pts, edges, 2)
    field = rm.distances(np.array([2, 3]))
    out = pibt_route(rm, field, [1, 0], SEP, time.perf_counter() + 10, np.random.default_rng(0), 200)
    assert out is not None
    assert sorted(out[-1][:, 0].tolist()) == [3.0, 12.0]
    assert _steps_clear(out)


@pytest.mark.slow
@pytest.mark.parametrize("name, seed", [("clutter-60-m50", 5), ("clutter-30-m50", 0), ("clutter-30-m20", 0),
                                        ("density-30-m20", 4), ("density-40-m50", 16)])
def test_formerly_failing_seeds_plan(name, seed):
    p = _case(name, seed)
    t0 = time.perf_counter()
    result, stats = plan(p, PlannerParams(time_limit=30.0), np.random.default_rng(seed))
    assert stats.found and stats.min_clearance >= p.margin - 1e-9
    assert time.perf_counter() - t0 < 30.0 * 1.1 + 0.5


def _two_robots():
    """Two robots left of a wall (x 15 to 20, y 0 to 30), their targets right of it."""
    from planner import Polygon, Problem

    wall = Polygon(np.array([[15.0, 0.0], [20.0, 0.0], [20.0, 30.0], [15.0, 30.0]]))
    return Problem(40.0, 80.0, (wall,), 1.0, 0.1, np.array([[5.0, 5.0], [5.0, 20.0]]),
                   np.array([[30.0, 5.0], [30.0, 20.0]])).validate()


def _fake_lattices(problem, detours):
    """Raw plans over the wall through via points ``d`` above it (steps that cannot
    be joined into one: the straight line crosses the wall)."""
    for d in detours:
        time.sleep(0.01)
        via = np.array([[17.5, 32.0 + d], [17.5, 35.0 + d]])
        yield np.stack([problem.start, via, problem.target])


def test_lattice_keeps_the_shortest_shift(monkeypatch):
    import planner.planning as planning
    import planner.tries as tries

    p = _two_robots()
    monkeypatch.setattr(tries, "LATTICE_GOOD", 0.5)  # never good enough: every try runs
    monkeypatch.setattr(tries, "lattice_candidates", lambda problem, deadline: _fake_lattices(problem, [8, 0.5, 6]))
    out = planning._Direct()
    tries._lattice(p, out, time.perf_counter() + 30)
    spans = [planning._makespan(p, tries.merge_steps(p, w, None)) for w in _fake_lattices(p, [8, 0.5, 6])]
    assert out.best[2] == pytest.approx(min(spans)) and min(spans) < spans[0]


def test_lattice_stops_at_a_good_enough_plan(monkeypatch):
    """Negative control of the above: within LATTICE_GOOD of the bound, the first is kept."""
    import planner.planning as planning
    import planner.tries as tries

    p = _two_robots()
    monkeypatch.setattr(tries, "LATTICE_GOOD", 100.0)
    monkeypatch.setattr(tries, "lattice_candidates", lambda problem, deadline: _fake_lattices(problem, [8, 0.5, 6]))
    out = planning._Direct()
    tries._lattice(p, out, time.perf_counter() + 30)
    first = planning._makespan(p, tries.merge_steps(p, next(_fake_lattices(p, [8])), None))
    assert out.best[2] == pytest.approx(first)


def _late_direct(delay: float):
    """A stand-in for the direct tries: the straight plan, offered after ``delay`` seconds."""
    import planner.planning as planning

    def direct(problem, params, memo, deadline=float("inf"), rng=None, on_grid_fail=None):
        time.sleep(delay)
        out = planning._Direct()
        w = np.stack([problem.start, problem.target])
        out.offer("one step", 1, (w, 1, planning._makespan(problem, w)))
        out.accepted = True
        return out

    return direct


@pytest.mark.parametrize("late", [True, False])
def test_bounds_are_skipped_for_a_plan_found_late(monkeypatch, late):
    import math

    import planner.planning as planning
    from planner import Problem

    p = Problem(40.0, 40.0, (), 1.0, 0.1, np.array([[5.0, 5.0], [5.0, 20.0]]),
                np.array([[30.0, 5.0], [30.0, 20.0]])).validate()
    monkeypatch.setattr(planning, "_direct", _late_direct(0.3 if late else 0.0))
    monkeypatch.setattr(planning, "_at_once", lambda problem, a, b, deadline=None: None)  # no shortcut past _direct
    result, stats = plan(p, PlannerParams(time_limit=0.1 if late else 30.0), np.random.default_rng(0))
    assert stats.found
    assert math.isnan(stats.makespan_lower_bound_s) == late
    assert ("lower_bounds" in stats.extra) == late


def test_free_roadmap_stops_at_the_deadline_and_caps_the_medial_samples():
    """A deadline already passed: the roadmap comes back at once without its costly parts
    (the caller sees the deadline); a long outline gets a coarser medial step (the cap)."""
    import planner.freespace as fs

    p = case_problem(next(c for c in CASES if c.name.startswith("clutter")), 0)
    t = time.perf_counter()
    rm = build_free_roadmap(p, deadline=time.perf_counter() - 1.0)
    assert time.perf_counter() - t < 0.5 and len(rm.points) == 2 * p.m
    full, _ = fs.medial_graph(p, 0.25, ridges=False)
    cap = fs._MEDIAL_SAMPLES
    try:
        fs._MEDIAL_SAMPLES = 200  # far fewer samples than the outlines need at 0.25
        coarse, _ = fs.medial_graph(p, 0.25, ridges=False)
    finally:
        fs._MEDIAL_SAMPLES = cap
    assert 0 < len(coarse) < len(full)
