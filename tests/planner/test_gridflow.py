"""The shortest grid routing (planner.gridflow): legal, exactly separated, shorter than TSWAP."""

from __future__ import annotations

import math
import time

import numpy as np
import pytest

from planner import Plan, check_plan
from planner.gridflow import _flow_value, flow_route, relaxed_horizon, tail_route
from planner.gridstage import build_grid, detect_grid, grid_plan, grid_waypoints, step_separated
from planner.tswap import tswap
from planner.validate import PlanInvalid

from .test_grid_stage import CELL, _cells_problem, _wall_door


def _graph(p):
    g = detect_grid(p)
    lat, _, _ = build_grid(p, *g)
    near = lambda pts: np.argmin(np.linalg.norm(lat.points[None] - pts[:, None], axis=2), axis=1)  # noqa: E731
    return lat, near(p.start), near(p.target)


def _legal(lat, sv, steps, turns=False):
    """Every step: moves along edges or stays, distinct vertices, no swap, and (unless
    ``turns``) no robot entering a vertex whose occupant leaves it sideways."""
    prev = np.asarray(sv)
    for cur in steps:
        assert len(np.unique(cur)) == len(cur)
        for a, b in zip(prev, cur):
            assert a == b or b in lat.nbr[a]
        pos = {int(v): i for i, v in enumerate(prev)}
        for i, (a, b) in enumerate(zip(prev, cur)):
            j = pos.get(int(b))
            if a == b or j is None or j == i:
                continue
            assert cur[j] != a, "swap"
            if not turns and cur[j] != b:
                d_in = lat.points[b] - lat.points[a]
                d_out = lat.points[cur[j]] - lat.points[b]
                assert abs(float(np.dot(d_in, d_out))) > 1e-9, "follows with a turn"
        prev = cur


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_flow_routes_are_legal_separated_and_no_longer_than_tswap(seed):
    p = _wall_door(m=60, seed=seed)
    lat, sv, gv = _graph(p)
    ts = tswap(lat, sv, gv, math.inf, turns=False)
    fl = flow_route(lat, sv, gv, math.inf, below=len(ts) + 1, budget=30)
    assert fl is not None and len(fl) <= len(ts)
    assert len(fl) >= relaxed_horizon(lat, sv, gv, len(ts), math.inf)
    _legal(lat, sv, fl)
    assert sorted(fl[-1]) == sorted(gv)
    pts = [p.start] + [lat.points[s] for s in fl]
    for a, b in zip(pts[:-1], pts[1:]):
        assert step_separated(p, a, b, CELL * (1 + 1e-9))
    check_plan(p, Plan.from_waypoints(np.asarray(pts), p.radius, p.margin, p.max_speed, p.max_accel))


def test_a_row_shifted_along_a_corridor_takes_exactly_its_shift():
    blocked = np.ones((3, 12), bool)
    blocked[1, :] = False
    p = _cells_problem(blocked, [(1, c) for c in range(5)], [(1, c + 3) for c in range(5)])
    lat, sv, gv = _graph(p)
    fl = flow_route(lat, sv, gv, math.inf, below=20, budget=10)
    assert len(fl) == 3  # straight following is allowed: the row moves as one
    _legal(lat, sv, fl)


def test_turn_rule_matters_and_the_exact_check_catches_its_absence():
    """A full L-shaped corridor shifted by one cell: allowing following with a turn, the
    whole chain moves in one step, and that step fails the exact check (negative
    control); with the rule the routing needs more steps and passes."""
    blocked = np.ones((6, 6), bool)
    blocked[1:5, 1] = False  # the vertical arm, rows 1-4 of column 1
    blocked[4, 1:5] = False  # the horizontal arm, row 4
    cells = [(1, 1), (2, 1), (3, 1), (4, 1), (4, 2), (4, 3)]
    p = _cells_problem(blocked, cells[:5], cells[1:])
    lat, sv, gv = _graph(p)
    loose = flow_route(lat, sv, gv, math.inf, turns=True, below=10, budget=10)
    assert len(loose) == 1
    assert not step_separated(p, p.start, lat.points[loose[0]], CELL * (1 + 1e-9))
    with pytest.raises(PlanInvalid):
        check_plan(p, Plan.from_waypoints(np.asarray([p.start, lat.points[loose[0]]]), p.radius, p.margin,
                                          p.max_speed, p.max_accel))
    strict = flow_route(lat, sv, gv, math.inf, turns=False, below=10, budget=10)
    assert len(strict) > 1
    _legal(lat, sv, strict)
    pts = [p.start] + [lat.points[s] for s in strict]
    for a, b in zip(pts[:-1], pts[1:]):
        assert step_separated(p, a, b, CELL * (1 + 1e-9))


def test_relaxed_flow_is_a_lower_bound_and_counts_robots():
    p = _wall_door(m=40, seed=5)
    lat, sv, gv = _graph(p)
    assert _flow_value(lat, sv, gv, 0) == int(np.isin(sv, gv).sum())
    low = relaxed_horizon(lat, sv, gv, 200, math.inf)
    assert _flow_value(lat, sv, gv, low) == 40 > _flow_value(lat, sv, gv, low - 1)
    assert flow_route(lat, sv, gv, math.inf, below=low, budget=5) is None  # nothing shorter exists


def test_grid_plan_keeps_the_shorter_routing_and_the_deadline():
    p = _wall_door(m=80, seed=1)
    w, steps = grid_plan(p, math.inf, rng=np.random.default_rng(0))
    raw = grid_waypoints(p, math.inf)
    assert steps <= len(raw) - 1
    check_plan(p, Plan.from_waypoints(np.asarray(w), p.radius, p.margin, p.max_speed, p.max_accel))
    t = time.perf_counter()
    lat, sv, gv = _graph(p)
    assert flow_route(lat, sv, gv, time.perf_counter() - 1, below=len(raw)) is None
    assert time.perf_counter() - t < 1.0


@pytest.mark.parametrize(("m", "searched"), [(50, False), (200, True)])
def test_the_routing_searches_run_only_on_a_crowded_grid(monkeypatch, m, searched):
    """room-32-32-4 has 682 free cells: 50 robots take 7 % (below FLOW_MIN_OCCUPANCY, only the
    end of TSWAP's routing is routed again), 200 take 29 % (both searches run, and as here
    neither finds a routing, the end of TSWAP's is routed again too)."""
    import planner.gridflow
    import planner.superflow
    from bench.maps import map_problem
    from planner.gridstage import FLOW_MIN_OCCUPANCY, route_budget

    calls = []
    monkeypatch.setattr(planner.gridflow, "flow_route", lambda *a, **k: calls.append("flow"))
    monkeypatch.setattr(planner.superflow, "super_route", lambda *a, **k: calls.append("twos"))
    monkeypatch.setattr(planner.gridflow, "tail_route", lambda *a, **k: calls.append("tail"))
    problem = map_problem("room-32-32-4", m, 0)
    assert (m >= FLOW_MIN_OCCUPANCY * 682) == searched
    assert grid_plan(problem, time.perf_counter() + 30, rng=np.random.default_rng(0)) is not None
    assert calls == (["flow", "twos", "tail"] if searched else ["tail"])
    assert route_budget(100) == pytest.approx(1.0 + 0.5 * (100 / 150) ** 2) and route_budget(400) == pytest.approx(16.5)


def test_the_end_of_a_routing_is_routed_again_shorter():
    """Routings that dawdle: the robots still moving after a step are routed anew among the
    ones that stay, legally, to the same vertices, in fewer steps; a shortest routing is
    left alone."""
    blocked = np.zeros((5, 9), bool)
    blocked[:, 4] = True
    blocked[2, 4] = False  # a door in the middle wall
    p = _cells_problem(blocked, [(0, 0), (4, 0), (2, 8), (0, 8)], [(2, 2), (0, 6), (4, 8), (0, 8)])
    lat, sv, gv = _graph(p)
    short = flow_route(lat, sv, gv, math.inf, below=30, budget=10)
    # everybody waits three steps first: only a tail with all four robots is shorter
    slow = [np.asarray(sv)] * 3 + list(short)
    got = tail_route(lat, np.stack([sv, *slow]), math.inf, budget=10.0, first_cap=1)
    assert got is not None and len(got) == len(short)
    _legal(lat, sv, got)
    assert sorted(got[-1]) == sorted(gv)
    # one robot leaves its target and comes back at the end: the tail of that one robot goes
    end = short[-1]
    i = 3  # the robot on (0, 8), which never has to move
    away = next(u for u in lat.nbr[end[i]] if u >= 0 and u not in end)
    detour = list(short) + [end.copy(), end.copy()]
    detour[-2][i] = away
    _legal(lat, sv, detour)
    got = tail_route(lat, np.stack([sv, *detour]), math.inf, budget=10.0, first_cap=1)
    assert got is not None and len(got) <= len(short)
    _legal(lat, sv, got)
    assert sorted(got[-1]) == sorted(gv)
    assert tail_route(lat, np.stack([sv, *short]), math.inf, budget=10.0, first_cap=1) is None
