"""The world's geometry and the two contact witnesses, checked in isolation."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from planner.problem import Circle, Polygon, Problem
from sim.execute.contacts import PymunkWitness, static_clearances
from sim.execute.monitor import SERIES_CAP, GapMonitor
from sim.execute.world import OBSTACLE, ROBOT, WALL, build_world, convex_pieces
from sim.scenario.params import SimParams

U = np.array([[3.0, 3.0], [7.0, 3.0], [7.0, 7.0], [5.8, 7.0], [5.8, 4.0], [4.2, 4.0], [4.2, 7.0], [3.0, 7.0]])
L = np.array([[0.0, 0.0], [3.0, 0.0], [3.0, 1.0], [1.0, 1.0], [1.0, 3.0], [0.0, 3.0]])


def _area(v):
    x, y = v[:, 0], v[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y))


def _convex(v):
    a, b, c = np.roll(v, 1, axis=0), v, np.roll(v, -1, axis=0)
    cross = (b[:, 0] - a[:, 0]) * (c[:, 1] - b[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - b[:, 0])
    return bool(np.all(cross >= -1e-12))


def _star(rng, k):
    """A random polygon with ``k`` vertices, star-shaped about the origin (so simple)."""
    gaps = rng.uniform(1.0, 1.9, k)  # the largest is under half the sum for k >= 3
    ang = np.cumsum(gaps) / gaps.sum() * 2 * np.pi  # so every angular gap is < pi
    rad = rng.uniform(0.3, 1.0, k)
    return np.c_[rad * np.cos(ang), rad * np.sin(ang)]


# -- convex pieces -------------------------------------------------------------------


@pytest.mark.parametrize("poly", [U, L, U[::-1], L[::-1]], ids=["U", "L", "U-cw", "L-cw"])
def test_convex_pieces_cover_the_polygon(poly):
    pieces = convex_pieces(poly)
    assert len(pieces) <= 4
    assert all(_convex(p) and _area(p) > 0 for p in pieces)
    assert sum(_area(p) for p in pieces) == pytest.approx(abs(_area(poly)))
    # Every piece lies inside the polygon: its centroid is inside, and the
    # areas add up, so the pieces tile the polygon.
    from planner.geometry import points_in_polygon

    cents = np.array([p.mean(axis=0) for p in pieces])
    assert points_in_polygon(cents, poly).all()


def test_convex_polygon_and_collinear_vertices():
    square = np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0], [2.0, 2.0], [0.0, 2.0], [0.0, 2.0]])
    pieces = convex_pieces(square)
    assert len(pieces) == 1 and _area(pieces[0]) == pytest.approx(4.0)


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(3, 14))
def test_convex_pieces_of_random_star_polygons(seed, k):
    poly = _star(np.random.default_rng(seed), k)
    if abs(_area(poly)) < 1e-6:
        return
    pieces = convex_pieces(poly)
    assert all(_convex(p) for p in pieces)
    assert sum(_area(p) for p in pieces) == pytest.approx(abs(_area(poly)), rel=1e-9)


# -- the world ---------------------------------------------------------------------------


def _problem(start, obstacles=(), size=10.0, radius=0.5):
    start = np.asarray(start, float)
    return Problem(size, size, tuple(obstacles), radius, 0.1, start, start)


def test_world_maps_shapes_and_batch_rows():
    problem = _problem([[1.0, 1.0], [2.0, 5.0], [8.0, 3.0]], (Polygon(U), Circle((8.0, 8.0), 1.0)))
    world = build_world(problem, SimParams(mass=2.0))
    space = world.space
    assert space.gravity == (0, 0) and space.damping == 1.0
    assert sorted(world.robot_of.values()) == [0, 1, 2]
    assert set(world.obstacle_of.values()) == {-1, 0, 1}
    for shape in list(world.robot_of) + list(world.obstacle_of):
        assert shape.friction == 0 and shape.elasticity == 0
    assert {s.collision_type for s in world.robot_of} == {ROBOT}
    assert {s.collision_type for s, k in world.obstacle_of.items() if k >= 0} == {OBSTACLE}
    assert {s.collision_type for s, k in world.obstacle_of.items() if k < 0} == {WALL}
    assert all(b.mass == 2.0 for b in world.bodies)
    state = world.state()
    assert np.array_equal(state[:, :2], problem.start)
    world.forces[:] = [[2.0, 0.0], [0.0, -4.0], [0.0, 0.0]]
    world.apply_forces()
    assert [tuple(b.force) for b in world.bodies] == [(2.0, 0.0), (0.0, -4.0), (0.0, 0.0)]
    space.step(0.5)
    space.step(0.5)
    v = world.state()[:, 2:]
    assert np.allclose(v, [[0.5, 0.0], [0.0, -1.0], [0.0, 0.0]])


# -- static clearances ---------------------------------------------------------------------


def test_static_clearances_agree_with_environment():
    problem = _problem([[1.0, 1.0]], (Polygon(U), Circle((8.0, 8.0), 1.0), Polygon(L + 0.2)))
    env = problem.env
    pts = np.random.default_rng(3).uniform(0, 10, (400, 2))
    full = static_clearances(env, pts, 3)
    assert full.shape == (400, 4)
    want, who = env.point_clearance_detail(pts)
    outside = (full[:, :3] > 0).all(axis=1)
    assert np.allclose(full.min(axis=1)[outside], want[outside])
    assert np.all(np.where(who == -1, 3, who)[outside] == full.argmin(axis=1)[outside])
    inside = ~outside
    # Inside an obstacle the environment says 0 (polygons) or the negative
    # rim distance (circles); the signed polygon depth is never larger.
    assert inside.any() and np.all(want[inside] <= 0.0)
    assert np.all(full.min(axis=1)[inside] <= want[inside] + 1e-12)
    # The pruned variant is exact below the bound and a bound above it.
    below = 0.7
    pruned = static_clearances(env, pts, 3, below=below)
    exact = full < below
    assert np.allclose(pruned[exact], full[exact])
    assert np.all(pruned[~exact] >= below - 1e-12) and np.all(pruned <= full + 1e-12)


# -- the monitor -------------------------------------------------------------------------------


def test_monitor_episodes_and_minimum():
    problem = _problem([[2.0, 5.0], [4.0, 5.0]])
    monitor = GapMonitor(problem)
    # Robot 1 at x = 4 - d: gap = 2 - d - 1 = 1 - d; touch for d > 1.
    d = np.array([0.0, 0.5, 1.05, 1.1, 0.9, 0.5, 1.2, 0.0])
    pos = np.zeros((len(d), 2, 2))
    pos[:, 0] = [2.0, 5.0]
    pos[:, 1, 0] = 4.0 - d
    pos[:, 1, 1] = 5.0
    times = np.arange(len(d)) * 0.1
    monitor.observe(times[:3], pos[:3])  # an episode open across two chunks
    monitor.observe(times[3:], pos[3:])
    contacts = monitor.contacts()
    assert [(c.kind, c.a, c.b) for c in contacts] == [("robot-robot", 0, 1)] * 2
    assert [c.time for c in contacts] == pytest.approx([0.2, 0.6])
    assert [c.depth for c in contacts] == pytest.approx([0.1, 0.2])
    assert monitor.min_gap == pytest.approx(-0.2)
    assert monitor.min_time == pytest.approx(0.6)
    assert monitor.min_pair == (0, 1)


def test_monitor_walls_and_obstacles():
    problem = _problem([[5.0, 5.0]], (Circle((8.0, 5.0), 1.0),))
    monitor = GapMonitor(problem)
    xs = np.array([5.0, 6.4, 6.6, 5.0, 0.6, 0.3, 0.2])
    pos = np.c_[xs, np.full_like(xs, 5.0)][:, None, :]
    monitor.observe(np.arange(len(xs)) * 1.0, pos)
    got = [(c.kind, c.a, c.b, c.time) for c in monitor.contacts()]
    assert got == [("robot-obstacle", 0, 0, 2.0), ("robot-wall", 0, -1, 5.0)]
    assert monitor.contacts()[1].depth == pytest.approx(0.3)
    assert monitor.min_gap == pytest.approx(-0.3)
    assert monitor.min_kind == "robot-wall" and monitor.min_pair == (0, -1)


@pytest.mark.parametrize("m", [30, 400])
def test_monitor_minimum_is_exact_for_many_robots(m):
    # Random walks: the monitor's minimum must equal brute force over all pairs.
    rng = np.random.default_rng(m)
    problem = _problem(rng.uniform(5, 45, (m, 2)), size=50.0, radius=0.2)
    steps = rng.normal(0, 0.05, (40, m, 2))
    pos = problem.start[None] + np.cumsum(steps, axis=0)
    monitor = GapMonitor(problem)
    for k in range(0, 40, 8):
        monitor.observe(np.arange(k, k + 8) * 0.1, pos[k : k + 8])
    iu = np.triu_indices(m, 1)
    d = np.linalg.norm(pos[:, iu[0]] - pos[:, iu[1]], axis=2) - 0.4
    walls = problem.env.wall_clearance(pos) - 0.2
    brute = min(d.min(), walls.min())
    assert monitor.min_gap == pytest.approx(brute, abs=1e-12)
    touching = {(int(iu[0][q]), int(iu[1][q])) for q in np.flatnonzero((d < 0).any(axis=0))}
    seen = {(c.a, c.b) for c in monitor.contacts() if c.kind == "robot-robot"}
    assert seen == touching


def _brute_series(problem, pos):
    """Per-sample smallest gap by brute force, capped like the monitor's series."""
    c, m = pos.shape[:2]
    r = problem.radius
    stat = static_clearances(problem.env, pos.reshape(-1, 2), len(problem.obstacles)).reshape(c, -1).min(axis=1) - r
    iu = np.triu_indices(m, 1)
    d = np.linalg.norm(pos[:, :, None] - pos[:, None, :], axis=3)[:, iu[0], iu[1]].min(axis=1) - 2 * r
    return np.minimum(np.minimum(stat, d), SERIES_CAP * r)


@pytest.mark.parametrize("moving", ["smooth", "jumping"])
def test_monitor_series_is_the_exact_per_sample_minimum(moving):
    # Smooth motion uses the Verlet lists; samples that jump everywhere use
    # nearest neighbours per sample.  Both must give every sample's exact minimum.
    rng = np.random.default_rng(3)
    obstacles = (Polygon(U + [10.0, 10.0]), Circle((4.0, 15.0), 1.5), Polygon(L + [15.0, 2.0]))
    m, c = (60, 80) if moving == "smooth" else (120, 40)
    base = rng.uniform(1.0, 19.0, size=(m, 2))
    if moving == "smooth":
        pos = base[None] + np.cumsum(rng.normal(0, 0.03, size=(c, m, 2)), axis=0)
    else:
        pos = rng.uniform(0.3, 19.7, size=(c, m, 2))
    problem = _problem(base, obstacles, size=20.0)
    monitor = GapMonitor(problem)
    for k in range(0, c, 25):
        monitor.observe(np.arange(k, min(k + 25, c)) * 0.1, pos[k : k + 25])
    series = monitor.series
    assert series.shape == (c,)
    assert series == pytest.approx(_brute_series(problem, pos), abs=1e-12)
    assert monitor.min_gap == pytest.approx(series.min(), abs=1e-12)
    assert (series < SERIES_CAP * problem.radius).any()


# -- pymunk's witness -----------------------------------------------------------------------


def test_pymunk_witness_one_record_per_episode():
    # One robot pushed into the inner corner of the L: two convex pieces, one obstacle.
    problem = _problem([[2.5, 2.5]], (Polygon(L + 0.5),))
    world = build_world(problem, SimParams())
    witness = PymunkWitness(world)
    body = world.bodies[0]
    body.velocity = (-1.0, -1.0)
    for k in range(240):
        witness.now = (k + 1) / 240
        world.space.step(1 / 240)
    contacts = witness.contacts()
    assert [(c.kind, c.a, c.b) for c in contacts] == [("robot-obstacle", 0, 0)]
    # The disc centre at (2.5 - t, 2.5 - t) touches both arms (the lines
    # x = 1.5 and y = 1.5) at t = 0.5.
    assert contacts[0].time == pytest.approx(0.5, abs=2 / 240)
    assert contacts[0].depth > 0
