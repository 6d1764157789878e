"""Many robots at once: lattice steps, snapping rounds, TSWAP routing, the free-space roadmap, deadlines."""

from __future__ import annotations

import math
import time

import numpy as np
import pytest

from planner import NoPlanFound, Plan, PlannerParams, Polygon, Problem, check_plan, plan
from planner.bounds import lower_bounds
from planner.geometry import closest_approach, greedy_separated
from planner.lattice import build_lattice, snap, tswap
from planner.problem import Circle
from planner.validate import min_clearance


def _random_problem(m: int, seed: int, obstacles: int = 3, coverage: float = 0.1) -> Problem:
    rng = np.random.default_rng(seed)
    side = math.sqrt(m * math.pi / coverage)
    obs = []
    for _ in range(obstacles):
        d = rng.uniform(4, 8) * side / 40
        c = rng.uniform(d / 2, side - d / 2, size=2)
        ang = np.sort(rng.uniform(0, 2 * np.pi, 6))
        obs.append(Polygon(c + d / 2 * np.stack([np.cos(ang), np.sin(ang)], axis=1)))
    shell = Problem(side, side, tuple(obs), 1.0, 0.1, np.zeros((0, 2)), np.zeros((0, 2)))
    pts = []
    for _ in range(2):
        cand = rng.uniform(1.1, side - 1.1, size=(40 * m, 2))
        cand = cand[shell.env.points_clear(cand, 1.1)]
        pts.append(cand[greedy_separated(cand, shell.separation, None, m)])
    return Problem(side, side, tuple(obs), 1.0, 0.1, pts[0], pts[1]).validate()


def _lattice_moves(spacing: float, rng, n: int = 4000):
    """Random pairs of robots on a lattice, each staying or moving to a 4-neighbour,
    distinct cells before and after and no swap: ``(a, b, c, d)`` segments."""
    steps = np.array([[0, 0], [1, 0], [-1, 0], [0, 1], [0, -1]])
    s1 = np.zeros((n, 2), int)
    s2 = rng.integers(-2, 3, size=(n, 2))
    d1 = steps[rng.integers(0, 5, n)]
    d2 = steps[rng.integers(0, 5, n)]
    e1, e2 = s1 + d1, s2 + d2
    ok = (np.any(s1 != s2, axis=1) & np.any(e1 != e2, axis=1)
          & ~(np.all(e1 == s2, axis=1) & np.all(e2 == s1, axis=1)))
    return [spacing * x[ok] for x in (s1, e1, s2, e2)]


def test_lattice_steps_keep_the_separation_at_sqrt2_spacing():
    sep = 2.1
    rng = np.random.default_rng(0)
    a, b, c, d = _lattice_moves(math.sqrt(2) * sep * (1 + 1e-6), rng)
    assert closest_approach(a, b, c, d).min() >= sep
    # negative control: a little tighter, some pair (a robot following another round a corner) comes too close
    a, b, c, d = _lattice_moves(math.sqrt(2) * sep * 0.99, rng)
    assert closest_approach(a, b, c, d).min() < sep


def test_snapping_rounds_are_exactly_clear():
    """A dense line (1.02 separations) snapped onto a lattice: every round keeps the separation."""
    m = 40
    start = np.stack([5 + 2.142 * np.arange(m), np.full(m, 30.0)], axis=1)
    target = np.stack([5 + 2.142 * np.arange(m), np.full(m, 10.0)], axis=1)
    p = Problem(100, 40, (), 1.0, 0.1, start, target).validate()
    lat = build_lattice(p, math.sqrt(2) * p.separation * (1 + 1e-6))
    steps, vert = snap(p, lat, p.start, time.perf_counter() + 20)
    assert len(set(vert.tolist())) == m
    w = np.asarray([p.start, *steps])
    assert np.allclose(w[-1], lat.points[vert])
    c = min_clearance(p, Plan.from_waypoints(w, 1.0, 0.1, 2.0, 2.0))
    assert c.value >= p.margin - 1e-9


def test_tswap_brings_every_robot_to_a_target_on_the_lattice():
    p = _random_problem(60, 1, obstacles=2)
    lat = build_lattice(p, math.sqrt(2) * p.separation * (1 + 1e-6))
    rng = np.random.default_rng(2)
    big = np.flatnonzero(lat.component == np.bincount(lat.component).argmax())
    v = rng.choice(big, size=120, replace=False)
    route = tswap(lat, v[:60], v[60:], time.perf_counter() + 20)
    assert route is not None and sorted(route[-1].tolist()) == sorted(v[60:].tolist())
    prev = v[:60]
    for cur in route:  # one lattice edge or a wait per robot and step, never two on a vertex
        assert len(set(cur.tolist())) == 60
        d = np.abs(lat.points[cur] - lat.points[prev]).sum(axis=1)
        assert np.all((d < 1e-9) | (np.abs(d - lat.spacing) < 1e-9))
        prev = cur


def test_many_robots_move_at_once_through_the_lattice():
    """120 robots, random to random at 10 % coverage: lattice routing, a plan near the bound."""
    p = _random_problem(120, 3)
    result, stats = plan(p, PlannerParams(time_limit=30), np.random.default_rng(3))
    assert check_plan(p, result).value >= p.margin
    assert stats.extra["direct"] == "lattice"
    assert result.steps < 30  # concurrent steps, not one robot at a time
    assert result.makespan <= 3.0 * lower_bounds(p)[0]
    assert stats.graphs == 0


def test_time_limit_is_honoured_at_200_robots():
    p = _random_problem(200, 4)
    for limit in (0.3, 1.0):
        t0 = time.perf_counter()
        try:
            plan(p, PlannerParams(time_limit=limit), np.random.default_rng(0))
        except NoPlanFound:
            pass
        assert time.perf_counter() - t0 <= 1.1 * limit + 0.5


def test_cluttered_world_is_routed_through_the_free_space_roadmap():
    rng = np.random.default_rng(5)
    obs = []
    for _ in range(14):
        c = rng.uniform(4, 26, size=2)
        obs.append(Circle(tuple(c), float(rng.uniform(0.6, 1.4))))
    shell = Problem(30, 30, tuple(obs), 1.0, 0.1, np.zeros((0, 2)), np.zeros((0, 2)))
    cand = rng.uniform(1.1, 28.9, size=(4000, 2))
    cand = cand[shell.env.points_clear(cand, 1.1)]
    pts = cand[greedy_separated(cand, 2.1, None, 24)]
    p = Problem(30, 30, tuple(obs), 1.0, 0.1, pts[:12], pts[12:]).validate()
    result, stats = plan(p, PlannerParams(time_limit=30), np.random.default_rng(5))
    assert check_plan(p, result).value >= p.margin
    assert stats.extra["direct"] == "free-space roadmap"


def test_auto_mode_reports_the_pebble_graphs_it_built(monkeypatch):
    """Where the roadmap runs in auto mode, graphs and connections are its true counts."""
    import planner.planning as planning

    built = {}
    real = planning.build_roadmap

    def spy(*args, **kwargs):
        out = real(*args, **kwargs)
        built["rm"] = out[0]
        return out

    monkeypatch.setattr(planning, "build_roadmap", spy)
    monkeypatch.setattr(planning, "_free_space", lambda *args: None)  # so that the roadmap runs
    wall = (Polygon(((0.0, 18.0), (18.0, 18.0), (18.0, 22.0), (0.0, 22.0))),  # a gap 4 wide: one at a time
            Polygon(((22.0, 18.0), (40.0, 18.0), (40.0, 22.0), (22.0, 22.0))))
    start = np.array([[4.0 + 4 * i, 5.0] for i in range(8)])
    target = np.array([[4.0 + 4 * i, 35.0] for i in range(8)])
    p = Problem(40, 40, wall, 1.0, 0.1, start, target)
    _, stats = plan(p, PlannerParams(time_limit=30), np.random.default_rng(0))
    rm = built["rm"]
    assert stats.graphs == len(rm.graphs) - 2 > 0  # besides the start's and the target's
    assert stats.connections == rm.graph.number_of_edges()
    assert stats.g == stats.graphs


def _open_grid(nx: int, ny: int):
    """An obstacle-free ``nx`` x ``ny`` grid of unit spacing (:func:`planner.grid.grid_graph`)
    and its ``(nx, ny)`` table of vertex ids."""
    from planner.grid import grid_graph

    p = Problem(nx + 1.0, ny + 1.0, (), 0.3, 0.1, np.zeros((0, 2)), np.zeros((0, 2)))
    gi, gj = np.meshgrid(np.arange(nx), np.arange(ny), indexing="ij")
    pts = np.stack([1.0 + gi.ravel(), 1.0 + gj.ravel()], axis=1).astype(float)
    lat, ok, vid = grid_graph(p, pts, nx, ny, 1.0)
    assert ok.all()
    return lat, vid


def test_tswap_assigns_for_the_least_longest_route():
    """Robot A rests on target a = (0, 0); B at (1, 2) is 3 steps from a and 4 from b = (3, 0),
    A is 3 from b.  The fewest squares (0 + 16 < 9 + 9) keep A home and send B 4 steps; the
    bottleneck assignment sends both 3 steps (the control without it takes the 4)."""
    lat, ids = _open_grid(5, 4)
    start = np.array([ids[0, 0], ids[1, 2]])
    goal = np.array([ids[0, 0], ids[3, 0]])
    route = tswap(lat, start, goal, time.perf_counter() + 10, turns=False)
    assert route is not None and sorted(route[-1].tolist()) == sorted(goal.tolist())
    assert len(route) == 3
    control = tswap(lat, start, goal, time.perf_counter() + 10, turns=False, bottleneck=False)
    assert control is not None and len(control) == 4


@pytest.mark.parametrize("bfs_from", [0, 10**9], ids=["breadth-first", "dijkstra"])
def test_tswap_distance_fields_are_breadth_first_distances(bfs_from, monkeypatch):
    """The fields TSWAP routes by are the lattice's shortest step counts (networkx's
    breadth-first search), -1 across components, on a grid with walls and a sealed room,
    by either of its two methods (large lattices and small)."""
    import networkx as nx

    import planner.tswap as ts
    from planner.grid import Lattice
    from planner.tswap import _fields

    monkeypatch.setattr(ts, "_BFS_FROM", bfs_from)

    lat, ids = _open_grid(9, 7)
    nbr = lat.nbr.copy()
    cut = {(int(a), int(b)) for i in range(7) for a, b in [(ids[4, i], ids[5, i])] if i != 3}  # a wall, one door
    cut |= {(int(ids[i, 5]), int(ids[i, 6])) for i in range(3)} | {(int(ids[2, 6]), int(ids[3, 6]))}  # a sealed room
    for a, b in cut:
        nbr[a][nbr[a] == b] = -1
        nbr[b][nbr[b] == a] = -1
    walled = Lattice(lat.points, nbr, lat.spacing, lat.component)
    g = nx.Graph((v, int(w)) for v in range(walled.n) for w in nbr[v] if w >= 0)
    g.add_nodes_from(range(walled.n))
    sources = np.array([ids[0, 0], ids[8, 6], ids[0, 6], ids[4, 3], ids[0, 0]])
    field = _fields(walled, sources, time.perf_counter() + 10)
    assert field is not None and field.shape == (len(sources), walled.n)
    for row, s in zip(field, sources):
        want = np.full(walled.n, -1)
        for v, d in nx.single_source_shortest_path_length(g, int(s)).items():
            want[v] = d
        assert np.array_equal(row, want)
    assert field[0, ids[8, 0]] == 8 + 2 * 3  # through the door at row 3, not across the wall
    assert (field[2] >= 0).sum() == 3  # the sealed room: three cells
    assert _fields(walled, np.array([], int), time.perf_counter() + 10).shape == (0, walled.n)


def test_tswap_tries_share_fields_and_assignments_through_the_memo(monkeypatch):
    """With a memo, later tries on the same robots compute no distance field again and
    route exactly as a fresh call; other robots start afresh."""
    import planner.tswap as ts

    lat, ids = _open_grid(8, 6)
    start = ids[:3].ravel()
    goal = ids[-3:].ravel()
    fresh = [tswap(lat, start, goal, time.perf_counter() + 10, rng=np.random.default_rng(5), bottleneck=b)
             for b in (True, False)]
    calls = []
    real = ts._fields
    monkeypatch.setattr(ts, "_fields", lambda *a: calls.append(1) or real(*a))
    memo: dict = {}
    for _ in range(2):
        for b, want in zip((True, False), fresh):
            got = tswap(lat, start, goal, time.perf_counter() + 10, rng=np.random.default_rng(5), bottleneck=b, memo=memo)
            assert got is not None and len(got) == len(want)
            assert all(np.array_equal(x, y) for x, y in zip(got, want))
    assert len(calls) == 1
    other = tswap(lat, ids[:2].ravel(), goal[:12], time.perf_counter() + 10, memo=memo)
    assert other is not None and len(calls) == 2
