"""The grid stage (planner.gridstage) and the obstacle-respecting bound (planner.geobound)."""

from __future__ import annotations

import math
import time

import numpy as np
import pytest

from planner import Plan, PlannerParams, Polygon, Problem, check_plan, plan
from planner.bounds import lower_bounds
from planner.geobound import geo_distances, geo_lower_bound
from planner.geometry import closest_approach
from planner.gridstage import detect_grid, find_grid, grid_plan, grid_waypoints, step_separated
from planner.plan import step_duration
from planner.validate import PlanInvalid

CELL = 2.4


def _cells_problem(blocked: np.ndarray, starts, goals) -> Problem:
    """Cells of 2.4 (row 0 at the top), radius 1, margin 0.1, robots at cell centres."""
    rows, cols = blocked.shape
    obs = []
    for r in range(rows):
        for c in range(cols):
            if blocked[r, c]:
                x0, y0 = c * CELL, (rows - r - 1) * CELL
                obs.append(Polygon(np.array([[x0, y0], [x0 + CELL, y0], [x0 + CELL, y0 + CELL], [x0, y0 + CELL]])))

    def centres(cells):
        a = np.asarray(cells, float)
        return np.stack([(a[:, 1] + 0.5) * CELL, (rows - a[:, 0] - 0.5) * CELL], axis=1)

    return Problem(cols * CELL, rows * CELL, tuple(obs), 1.0, 0.1, centres(starts), centres(goals))


def _wall_door(m: int = 20, seed: int = 0) -> Problem:
    """12 x 12 cells, a wall down column 6 with a door one cell wide; starts and targets
    random free cells (a few robots must pass the door)."""
    blocked = np.zeros((12, 12), bool)
    blocked[:, 6] = True
    blocked[5, 6] = False
    rng = np.random.default_rng(seed)
    free = [(r, c) for r in range(12) for c in range(12) if not blocked[r, c]]
    s = [free[k] for k in rng.choice(len(free), m, replace=False)]
    g = [free[k] for k in rng.choice(len(free), m, replace=False)]
    return _cells_problem(blocked, s, g)


def test_grid_is_detected_and_paper_placements_are_not():
    p = _wall_door()
    offset, c = detect_grid(p)
    assert math.isclose(c, CELL) and np.allclose(offset, 0.5 * CELL)
    off = Problem(p.width, p.height, p.obstacles, 1.0, 0.1, p.start + np.array([1e-3, 0]), p.target)
    assert detect_grid(off) is None


def test_grid_stage_solves_a_wall_with_a_door():
    p = _wall_door()
    raw = grid_waypoints(p, deadline=math.inf)
    assert raw is not None
    result, stats = plan(p, PlannerParams(time_limit=30), np.random.default_rng(0))
    assert stats.extra["direct"] == "grid"
    check_plan(p, result)
    geo = geo_lower_bound(p)
    assert stats.makespan_lower_bound_geo_s == geo
    assert result.makespan <= 2.0 * geo


def test_every_grid_step_is_exactly_separated():
    p = _wall_door(seed=3)
    raw = grid_waypoints(p, deadline=math.inf)
    for a, b in zip(raw[:-1], raw[1:]):
        assert step_separated(p, a, b, CELL)
    check_plan(p, Plan.from_waypoints(np.asarray(raw), p.radius, p.margin, p.max_speed, p.max_accel))


def test_following_with_a_turn_is_caught_by_the_exact_check():
    """Robot 0 leaves (0, 0) upwards while robot 1 enters it from the left: on a grid
    of 2.4 < sqrt(2) * 2.1 they come within 2.4 / sqrt(2) = 1.70 < 2.1."""
    a = np.array([[10.0, 10.0], [10.0 - CELL, 10.0]])
    b = np.array([[10.0, 10.0 + CELL], [10.0, 10.0]])
    d = closest_approach(a[0], b[0], a[1], b[1])
    assert math.isclose(float(d), CELL / math.sqrt(2), rel_tol=1e-9)
    p = Problem(30.0, 30.0, (), 1.0, 0.1, a, b)
    assert not step_separated(p, a, b, CELL)
    try:
        check_plan(p, Plan.from_waypoints(np.stack([a, b]), 1.0, 0.1, p.max_speed, p.max_accel))
    except PlanInvalid:
        pass
    else:
        raise AssertionError("the turn was not caught")
    # following straight on is fine
    b2 = np.array([[10.0 + CELL, 10.0], [10.0, 10.0]])
    assert step_separated(p, a, b2, CELL)


def test_geo_bound_between_straight_bound_and_makespan():
    p = _wall_door(seed=1)
    result, stats = plan(p, PlannerParams(time_limit=30), np.random.default_rng(0))
    geo = geo_lower_bound(p)
    assert lower_bounds(p)[0] - 1e-9 <= geo <= result.makespan


def test_geo_distances_are_lower_bounds_around_a_wall():
    """A wall of 10 x 2 between two points: the shortest path of a centre goes around the
    wall grown by 1.1, at least the path around the inscribed octagon, and more than straight."""
    wall = Polygon(np.array([[9.0, 5.0], [11.0, 5.0], [11.0, 15.0], [9.0, 15.0]]))
    s, t = np.array([[5.0, 10.0]]), np.array([[15.0, 10.0]])
    p = Problem(20.0, 20.0, (wall,), 1.0, 0.1, s, t)
    d = float(geo_distances(p)[0, 0])
    c = 1.1
    # true: tangent to the rounded corner (9, 15) from s, around to (11, 15), down to t
    corner = np.array([9.0, 15.0])
    r = np.linalg.norm(s[0] - corner)
    tangent = math.sqrt(r * r - c * c)
    ang = math.atan2(s[0, 1] - corner[1], s[0, 0] - corner[0]) % (2 * math.pi)  # corner -> s
    arc = ang - math.acos(c / r) - math.pi / 2  # from the tangent point round to straight up
    true = 2 * (tangent + c * arc) + 2.0  # 16.97
    assert 16.9 < true < 17.0
    assert 10.0 < d <= true + 1e-9
    assert d > 0.97 * true


def test_geo_bound_exceeds_the_straight_bound_on_a_maze():
    blocked = np.zeros((9, 9), bool)
    blocked[2, 0:8] = True
    blocked[4, 1:9] = True
    blocked[6, 0:8] = True
    starts = [(0, c) for c in range(0, 9, 2)]
    goals = [(8, c) for c in range(0, 9, 2)]
    p = _cells_problem(blocked, starts, goals)
    geo = geo_lower_bound(p)
    assert geo > 1.5 * lower_bounds(p)[0]
    result, stats = plan(p, PlannerParams(time_limit=30), np.random.default_rng(0))
    assert geo <= result.makespan
    # the bound of a straight step over the bottleneck path length
    assert geo == step_duration(p.__dict__["_geo_bottleneck"], p.max_speed, p.max_accel)


def _rooms_scattered(m: int, seed: int) -> Problem:
    """16 x 16 cells in four rooms (walls through the middle, a door one cell wide in
    each), starts and targets scattered over the free space: off every grid."""

    blocked = np.zeros((16, 16), bool)
    blocked[8, :] = blocked[:, 8] = True
    for r, c in ((8, 3), (8, 12), (3, 8), (12, 8)):
        blocked[r, c] = False
    return _scattered(blocked, (0, 0), m, seed)


def _scattered(blocked: np.ndarray, free_cell, m: int, seed: int) -> Problem:
    """The cells of ``blocked`` with ``m`` starts and ``m`` targets scattered over the free
    space (``free_cell`` one free cell; radius 1, margin 0.1)."""
    from planner.scatter import scatter

    shell = _cells_problem(blocked, [free_cell], [free_cell])
    rng = np.random.default_rng(seed)
    s = scatter(shell.env, m, shell.separation, shell.clearance, rng)
    g = scatter(shell.env, m, shell.separation, shell.clearance, rng)
    return Problem(shell.width, shell.height, shell.obstacles, 1.0, 0.1, s, g)


def test_a_map_grid_is_read_from_the_obstacles_and_not_from_off_lattice_ones():
    from planner.gridstage import find_grid, map_grid

    p = _rooms_scattered(30, 0)
    assert detect_grid(p) is None
    offset, c = map_grid(p)
    assert math.isclose(c, CELL) and np.allclose(offset, 0.5 * CELL)
    assert find_grid(p)[1] is True
    # negative controls: rectangles off the cell lines, and too few rectangles among discs
    moved = list(p.obstacles)
    moved[0] = Polygon(moved[0].vertices + np.array([0.37, 0.0]))
    assert map_grid(Problem(p.width, p.height, tuple(moved), 1.0, 0.1, p.start, p.target)) is None
    from planner import Circle

    discs = tuple(Circle((3.0 + 4 * k, 30.0), 0.5) for k in range(len(p.obstacles) // 5))
    assert map_grid(Problem(p.width, p.height, p.obstacles + discs, 1.0, 0.1, p.start, p.target)) is None
    # cells narrower than the separation: the grid takes every second cell line
    fine = Problem(p.width, p.height, p.obstacles, 0.6, 0.1, p.start[:2] * 0 + 10, p.target[:2] * 0 + 10)
    assert math.isclose(map_grid(fine)[1], CELL)


def test_scattered_robots_on_a_map_are_snapped_onto_its_cells_and_routed(monkeypatch):
    import planner.tries as tries

    monkeypatch.setattr(tries, "FREE_AFTER_GRID_MAX_ROBOTS", 0)  # the grid stage's own plan
    for seed, m in ((0, 30), (1, 60)):
        p = _rooms_scattered(m, seed)
        result, stats = plan(p, PlannerParams(time_limit=30), np.random.default_rng(seed))
        assert stats.extra["direct"] == "grid", stats.extra
        check_plan(p, result)
        assert np.allclose(result.waypoints[0], p.start)
        end = np.asarray(result.waypoints[-1])
        assert np.allclose(end[np.lexsort(end.T)], p.target[np.lexsort(p.target.T)])  # the target set, unlabeled
        geo = geo_lower_bound(p)
        assert result.makespan <= 3.0 * geo, (result.makespan, geo)


def _arena(m: int, seed: int) -> Problem:
    """16 x 16 cells, a band of 3 blocked all round (a ROS map's unknown space) and four
    pillars in the open arena; starts and targets scattered: off every grid."""

    blocked = np.zeros((16, 16), bool)
    blocked[:3] = blocked[-3:] = True
    blocked[:, :3] = blocked[:, -3:] = True
    for r, c in ((6, 6), (6, 9), (9, 6), (9, 9)):
        blocked[r, c] = True
    return _scattered(blocked, (3, 3), m, seed)


def test_a_short_snapped_grid_plan_is_followed_by_the_free_space_roadmap(monkeypatch):
    """25 robots scattered in an open arena: the grid plan is a few steps (snap, route,
    snap back); the free-space roadmap, tried after it, moves them from where they stand
    and its plan is kept, shorter; the control: without the follow-up the grid's plan stands."""
    import planner.tries as tries

    p = _arena(25, 0)
    result, stats = plan(p, PlannerParams(time_limit=30), np.random.default_rng(0))
    check_plan(p, result)
    short = tries.FREE_AFTER_GRID_MAX_STEPS
    monkeypatch.setattr(tries, "FREE_AFTER_GRID_MAX_ROBOTS", 0)
    grid_only, grid_stats = plan(_arena(25, 0), PlannerParams(time_limit=30), np.random.default_rng(0))
    assert grid_stats.extra["direct"] == "grid" and len(grid_only.durations) <= short
    assert stats.extra["direct"] == "free-space roadmap"
    assert result.makespan < 0.7 * grid_only.makespan


def _fine_door(door_cells: tuple[int, int]) -> Problem:
    """Cells of 0.5 (five per separation of 2.1): 40 x 30 cells, a wall 2 cells thick
    across the middle with a door of cells ``door_cells`` (a free band of 0.8 units
    for a robot's centre: an even grid of every fifth cell line can miss it)."""
    s = 0.5
    blocked = np.zeros((30, 40), bool)
    blocked[14:16, :] = True
    blocked[14:16, door_cells[0]:door_cells[1]] = False
    obs = []
    for r, c in zip(*np.nonzero(blocked)):
        x0, y0 = c * s, (30 - r - 1) * s
        obs.append(Polygon(np.array([[x0, y0], [x0 + s, y0], [x0 + s, y0 + s], [x0, y0 + s]])))
    return Problem(40 * s, 30 * s, tuple(obs), 1.0, 0.1, np.array([[3.0, 3.0]]), np.array([[3.0, 12.0]]))


def test_uneven_lines_pass_a_door_an_even_grid_misses():
    from planner.gridstage import Lines, build_grid, map_grid

    p = _fine_door((21, 27))  # x in [10.5, 13.5]: centres in [11.6, 12.4]
    lines = map_grid(p)
    assert isinstance(lines, Lines) and lines.gap >= p.separation - 1e-9
    assert lines.reach <= 9 * 0.5 + 1e-9
    lat = build_grid(p, lines)[0]
    below, above = lat.points[:, 1] < 7.0, lat.points[:, 1] > 8.0
    assert set(lat.component[below]) & set(lat.component[above])  # one component spans the wall
    # the control: the even grid of every fifth cell centre (x = 0.25 + 2.5 k) has no line in
    # the door's band, so the wall splits it
    even = build_grid(p, np.array([0.25, 0.25]), 2.5)[0]
    assert not set(even.component[even.points[:, 1] < 7.0]) & set(even.component[even.points[:, 1] > 8.0])


def test_scattered_robots_cross_a_fine_door_on_uneven_lines():
    from planner.scatter import scatter

    shell = _fine_door((21, 27))
    rng = np.random.default_rng(3)
    lo = scatter(shell.env, 12, shell.separation, shell.clearance, rng, region=(0, 0, 20, 6.5))
    hi = scatter(shell.env, 12, shell.separation, shell.clearance, rng, region=(0, 8.5, 20, 15))
    p = Problem(shell.width, shell.height, shell.obstacles, 1.0, 0.1, lo, hi)
    grid = find_grid(p)
    assert grid is not None and grid[1]  # snapped onto the map's cells
    found = grid_plan(p, time.perf_counter() + 30, grid[0], np.random.default_rng(0))
    assert found is not None
    check_plan(p, Plan.from_waypoints(found[0], p.radius, p.margin, p.max_speed, p.max_accel))
    # auto mode may keep a shorter plan of another stage (the lattice meeting after a long
    # grid plan on cells finer than a robot), always exact
    result, stats = plan(p, PlannerParams(time_limit=30), np.random.default_rng(0))
    assert stats.extra["direct"] in ("grid", "dense")
    check_plan(p, result)


def test_bounds_are_not_tried_over_the_obstacle_cap():
    """Over 2000 obstacles the geo and cut bounds are skipped with a reason (on the maps
    measured they always ran out of budget there); with 60 they are computed (the control)."""
    import time

    from planner import Circle
    from planner.plan import PlanStats
    from planner.tries import _BOUND_MAX_OBSTACLES, _cut_bound, _geo_bound

    def world(n):
        discs = tuple(Circle((1.0 + 2.0 * (k % 60), 130.0 + 2.0 * (k // 60)), 0.2) for k in range(n))
        start = np.array([[5.0 + 3 * k, 5.0] for k in range(12)])
        return Problem(130.0, 200.0, discs, 1.0, 0.1, start, start + [0.0, 60.0])

    over, stats = world(_BOUND_MAX_OBSTACLES + 1), PlanStats(found=True)
    t = time.perf_counter()
    _geo_bound(over, stats, t + 60, t + 60)
    _cut_bound(over, stats, t + 60, t + 60)
    assert "2001 obstacles" in stats.extra["geo_lower_bound"] and "2001 obstacles" in stats.extra["cut_lower_bound"]
    assert math.isnan(stats.makespan_lower_bound_geo_s)
    at, stats = world(60), PlanStats(found=True)
    _geo_bound(at, stats, time.perf_counter() + 60, time.perf_counter() + 60)
    assert stats.makespan_lower_bound_geo_s > 0 and "geo_lower_bound" not in stats.extra


def test_bounds_are_not_started_where_their_budget_cannot_cover_them():
    """With 1000 obstacles and 0.1 s of budget, neither bound starts (each takes at least
    about 0.2 s there) and the stats say why, in no time; with 60 s both run (the control)."""
    import time

    from planner import Circle
    from planner.plan import PlanStats
    from planner.tries import _cut_bound, _geo_bound

    discs = tuple(Circle((1.0 + 2.0 * (k % 60), 130.0 + 2.0 * (k // 60)), 0.2) for k in range(1000))
    start = np.array([[5.0 + 3 * k, 5.0] for k in range(12)])
    problem = Problem(130.0, 200.0, discs, 1.0, 0.1, start, start + [0.0, 60.0])
    stats, t = PlanStats(found=True), time.perf_counter()
    _geo_bound(problem, stats, t + 0.1, t + 60)
    _cut_bound(problem, stats, t + 0.1, t + 60)
    assert time.perf_counter() - t < 0.05
    assert "takes at least about" in stats.extra["geo_lower_bound"]
    assert "takes at least about" in stats.extra["cut_lower_bound"]
    assert math.isnan(stats.makespan_lower_bound_geo_s) and math.isnan(stats.makespan_lower_bound_cut_s)
    stats, t = PlanStats(found=True), time.perf_counter()
    _geo_bound(problem, stats, t + 60, t + 60)
    _cut_bound(problem, stats, t + 60, t + 60)
    assert stats.makespan_lower_bound_geo_s > 0
    assert "geo_lower_bound" not in stats.extra and "cut_lower_bound" not in stats.extra


def test_uneven_lines_are_a_separation_apart_in_floating_point():
    """Cell centres 9 cells of 0.05 apart differ by 0.4499999999999886 < 0.45 (the control);
    the lines are moved by ulps so that robots on neighbouring vertices are never counted
    too close by the exact checks."""
    from planner.mapgrid import _apart

    raw = np.array([13.575, 14.025, 14.475])
    sep = 0.45
    assert (np.diff(raw) < sep).any()
    moved = _apart(raw, sep)
    assert (np.diff(moved) >= sep).all() and np.abs(moved - raw).max() < 1e-12


def test_a_sparse_map_is_routed_near_the_obstacle_respecting_bound():
    """random-64-64-10 with 200 robots on random cells (seed 1): the fewest squared distances
    alone sent one robot 18 cells where no assignment needs more than 12 (2.13x the geo
    bound); with the bottleneck assignment first the plan is within 2x of it."""
    from bench.maps import map_problem

    p = map_problem("random-64-64-10", 200, 1)
    result, stats = plan(p, PlannerParams(time_limit=60), np.random.default_rng(1))
    assert stats.extra.get("direct") == "grid"
    check_plan(p, result)
    assert result.makespan <= 2.0 * geo_lower_bound(p)


def test_grid_tries_are_counted_by_work_not_by_the_clock(monkeypatch):
    """The number of grid tries, and the plan, do not depend on how fast the clock runs: on a
    machine a hundred times slower (a clock that jumps half a second at every reading) the
    same tries run and the same plan comes out.  A clock-budgeted loop would stop after the
    first try here (room-32-32-4 at 100 robots runs twelve)."""
    import planner.gridstage as gs
    from bench.maps import map_problem

    def run(clock):
        problem = map_problem("room-32-32-4", 100, 0)
        calls = []
        real = gs.grid_waypoints

        def spy(*args, **kwargs):
            calls.append(kwargs.get("rng") is not None or (len(args) > 3 and args[3] is not None))
            return real(*args, **kwargs)

        monkeypatch.setattr(gs, "grid_waypoints", spy)
        monkeypatch.setattr(gs, "FLOW_MIN_ROBOTS", 10**9)  # the tries only
        if clock is not None:
            monkeypatch.setattr(gs, "time", clock)
        out = gs.grid_plan(problem, 1e18, gs.find_grid(problem)[0], np.random.default_rng(0))
        monkeypatch.undo()
        return calls, out

    class Slow:
        now = 0.0

        @classmethod
        def perf_counter(cls):
            cls.now += 0.5
            return cls.now

    calls, out = run(None)
    slow_calls, slow_out = run(Slow)
    assert len(calls) == gs.GRID_TRIES  # ties there change the routing: every try runs
    assert slow_calls == calls
    assert np.array_equal(slow_out[0], out[0]) and slow_out[1] == out[1]


def test_grid_tries_stop_when_the_tie_breaks_change_nothing():
    """On den312d at 100 robots each assignment's first random try routes as its plain one; with
    tries counted as costly (:data:`SETTLE_WORK_S` at 0) no more run, and as they are (cheap)
    all twelve do."""
    import planner.gridstage as gs
    from bench.maps import map_problem

    problem = map_problem("den312d", 100, 0)
    grid = gs.find_grid(problem)[0]
    calls = []
    real = gs.grid_waypoints
    counts = []
    for settle in (0.0, gs.SETTLE_WORK_S):
        calls.clear()
        try:
            gs.grid_waypoints = lambda *a, **k: calls.append(1) or real(*a, **k)
            saved = gs.FLOW_MIN_ROBOTS, gs.SETTLE_WORK_S
            gs.FLOW_MIN_ROBOTS, gs.SETTLE_WORK_S = 10**9, settle
            gs.grid_plan(problem, 1e18, grid, np.random.default_rng(0))
        finally:
            gs.grid_waypoints = real
            gs.FLOW_MIN_ROBOTS, gs.SETTLE_WORK_S = saved
        counts.append(len(calls))
    assert counts == [4, gs.GRID_TRIES]
    assert gs.try_work(100, 10_000, 50, True) == pytest.approx(0.15e-6 * 1e6 + 6e-6 * 5000)


def test_a_grid_plan_made_mostly_of_snapping_rounds_is_followed_too(monkeypatch):
    """Over 5 steps, the follow-up runs where the snapping rounds are at least the routing
    steps (a crowd in an open arena, as in a ROS map's room), and not where the routing
    dominates (the control: a MovingAI map's scattered robots, 2 rounds and 8 steps)."""
    import planner.tries as tries
    from planner.params import PlannerParams as Params

    p = _arena(25, 0)
    calls = []
    monkeypatch.setattr(tries, "_free_space", lambda *a, **k: calls.append("free"))
    monkeypatch.setattr(tries, "_lattice", lambda *a, **k: calls.append("lattice"))
    for info, ran in (({"snap_rounds": 14, "route_steps": 2}, True), ({"snap_rounds": 2, "route_steps": 8}, False)):
        calls.clear()
        out = tries._Direct()
        w = np.stack([p.start] * 9)  # 8 steps: over FREE_AFTER_GRID_MAX_STEPS
        out.offer("grid", 8, (w, 8, 99.0))
        tries._after_grid(p, Params(), out, info, time.perf_counter(), time.perf_counter() + 30,
                          np.random.default_rng(0), lattice=True)
        assert (calls == ["free", "lattice"]) if ran else not calls
        assert out.best[3] == "grid"
