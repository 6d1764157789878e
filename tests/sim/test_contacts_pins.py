"""The two contact witnesses, pinned event by event (sim/execute/contacts.py).

pymunk's witness is driven here with scripted collision events (begin, pre-solve,
separate) so that each rule of a touching episode is checked on its own: which pair
it belongs to, when it opens and closes, and its deepest overlap.  The gap monitor is
fed hand-made samples whose gaps are known exactly.  These are the tests that
mutation testing of ``sim/execute/contacts.py`` relies on (see ``tests/mutation/``).
"""

from types import SimpleNamespace

import numpy as np
import pytest

from planner.problem import Circle, Polygon, Problem
from sim.execute.contacts import (
    ROBOT_OBSTACLE,
    ROBOT_ROBOT,
    ROBOT_WALL,
    Contact,
    PymunkWitness,
    static_clearances,
)
from sim.execute.monitor import SERIES_CAP, GapMonitor
from sim.execute.world import OBSTACLE, ROBOT, WALL, build_world
from sim.scenario.params import SimParams


class _Space:
    def __init__(self):
        self.handlers = []

    def on_collision(self, a, b, **callbacks):
        self.handlers.append((a, b, callbacks))


def _world():
    # shapes: robots r0..r2; obstacle pieces o0a, o0b (obstacle 0), o1 (obstacle 1); a wall segment
    shapes = {name: object() for name in ("r0", "r1", "r2", "o0a", "o0b", "o1", "wall")}
    robot_of = {shapes["r0"]: 0, shapes["r1"]: 1, shapes["r2"]: 2}
    obstacle_of = {shapes["o0a"]: 0, shapes["o0b"]: 0, shapes["o1"]: 1, shapes["wall"]: -1}
    return SimpleNamespace(space=_Space(), robot_of=robot_of, obstacle_of=obstacle_of), shapes


def _arbiter(shapes, a, b, *distances):
    points = [SimpleNamespace(distance=d) for d in distances]
    return SimpleNamespace(shapes=(shapes[a], shapes[b]), contact_point_set=SimpleNamespace(points=points))


def test_the_witness_listens_to_robots_against_everything():
    world, _ = _world()
    w = PymunkWitness(world)
    assert [(a, b) for a, b, _ in world.space.handlers] == [(ROBOT, ROBOT), (ROBOT, OBSTACLE), (ROBOT, WALL)]
    for _, _, cb in world.space.handlers:
        assert cb == {"begin": w._begin, "pre_solve": w._pre_solve, "separate": w._separate}
    assert w.now == 0.0 and w.contacts() == []


def test_the_witness_names_each_pair():
    world, s = _world()
    w = PymunkWitness(world)
    assert w._key(_arbiter(s, "r2", "r0")) == (ROBOT_ROBOT, 0, 2)
    assert w._key(_arbiter(s, "r0", "r2")) == (ROBOT_ROBOT, 0, 2)
    assert w._key(_arbiter(s, "r1", "o1")) == (ROBOT_OBSTACLE, 1, 1)
    assert w._key(_arbiter(s, "o0b", "r2")) == (ROBOT_OBSTACLE, 2, 0)
    assert w._key(_arbiter(s, "wall", "r1")) == (ROBOT_WALL, 1, -1)
    assert w._key(_arbiter(s, "r0", "wall")) == (ROBOT_WALL, 0, -1)


def test_depth_is_the_deepest_point_and_never_negative():
    assert PymunkWitness._depth(_arbiter(_world()[1], "r0", "r1", -0.25, -0.5)) == 0.5
    assert PymunkWitness._depth(_arbiter(_world()[1], "r0", "r1", 0.1)) == 0.0
    assert PymunkWitness._depth(_arbiter(_world()[1], "r0", "r1")) == 0.0


def test_one_episode_per_pair_however_many_pieces_it_touches():
    world, s = _world()
    w = PymunkWitness(world)
    w.now = 1.0
    a = _arbiter(s, "r0", "o0a", -0.1)
    b = _arbiter(s, "o0b", "r0", -0.05)
    w._begin(a, None, None)
    w.now = 1.5
    w._begin(b, None, None)  # the second piece of the same obstacle: same episode
    w._pre_solve(_arbiter(s, "r0", "o0b", -0.3), None, None)  # deepest during the episode
    w._pre_solve(_arbiter(s, "r0", "o0b", -0.2), None, None)
    w._pre_solve(_arbiter(s, "r1", "o1", -9.0), None, None)  # no open episode: ignored
    w._separate(a, None, None)  # one piece still touching: still open
    w.now = 2.0
    w._begin(_arbiter(s, "r0", "o0a", -0.01), None, None)
    w._separate(b, None, None)
    w._separate(a, None, None)  # now closed
    w.now = 3.0
    w._begin(_arbiter(s, "r0", "o0a", -0.02), None, None)  # a new episode
    w._begin(_arbiter(s, "wall", "r1", -0.4), None, None)
    w._begin(_arbiter(s, "r2", "r1"), None, None)
    got = [c.to_dict() for c in w.contacts()]
    assert got == [
        {"time": 1.0, "kind": "robot-obstacle", "a": 0, "b": 0, "depth": 0.3, "witness": "pymunk"},
        {"time": 3.0, "kind": "robot-obstacle", "a": 0, "b": 0, "depth": 0.02, "witness": "pymunk"},
        {"time": 3.0, "kind": "robot-wall", "a": 1, "b": -1, "depth": 0.4, "witness": "pymunk"},
        {"time": 3.0, "kind": "robot-robot", "a": 1, "b": 2, "depth": 0.0, "witness": "pymunk"},
    ]
    assert all(type(c.time) is float and type(c.a) is int and type(c.depth) is float for c in w.contacts())


def test_a_stray_separate_does_nothing():
    world, s = _world()
    w = PymunkWitness(world)
    w._separate(_arbiter(s, "r0", "r1"), None, None)
    w._begin(_arbiter(s, "r0", "o1", -0.1), None, None)
    w._separate(_arbiter(s, "r0", "r1"), None, None)
    w._begin(_arbiter(s, "r0", "o1", -0.2), None, None)  # still the open episode
    assert [(c.kind, c.depth) for c in w.contacts()] == [("robot-obstacle", 0.2)]


def test_a_later_begin_keeps_a_deeper_depth():
    world, s = _world()
    w = PymunkWitness(world)
    w._begin(_arbiter(s, "r0", "o0a", -0.3), None, None)
    w._begin(_arbiter(s, "r0", "o0b", -0.1), None, None)
    w._begin(_arbiter(s, "r0", "o0b", -0.2), None, None)
    assert [c.depth for c in w.contacts()] == [0.3]
    w2 = PymunkWitness(_world()[0])
    w2._robot_of, w2._obstacle_of = w._robot_of, w._obstacle_of
    w2._begin(_arbiter(s, "r0", "o0a", -0.1), None, None)
    w2._begin(_arbiter(s, "r0", "o0b", -0.3), None, None)
    assert [c.depth for c in w2.contacts()] == [0.3]


def test_contact_text_and_dict():
    c = Contact(1.25, ROBOT_ROBOT, 2, 7, 0.0123, "monitor")
    assert c.describe() == "robots 2 and 7 touch at t = 1.250 s, depth 0.0123 (monitor)"
    assert Contact(0.5, ROBOT_WALL, 3, -1, 0.5, "pymunk").describe() == (
        "robot 3 and the wall touch at t = 0.500 s, depth 0.5 (pymunk)"
    )
    assert Contact(2.0, ROBOT_OBSTACLE, 1, 4, 1e-5, "pymunk").describe() == (
        "robot 1 and obstacle 4 touch at t = 2.000 s, depth 1e-05 (pymunk)"
    )
    assert c.to_dict() == {"time": 1.25, "kind": "robot-robot", "a": 2, "b": 7, "depth": 0.0123, "witness": "monitor"}
    assert list(c.to_dict()) == ["time", "kind", "a", "b", "depth", "witness"]


def test_the_real_world_registers_walls_as_minus_one():
    problem = Problem(10, 10, (Circle((5.0, 5.0), 1.0),), 0.5, 0.1, np.array([[2.0, 2.0]]), np.array([[2.0, 2.0]]))
    world = build_world(problem, SimParams())
    w = PymunkWitness(world)
    body = world.bodies[0]
    body.velocity = (-2.0, 0.0)
    for k in range(120):
        w.now = (k + 1) / 60
        world.space.step(1 / 60)
    got = [(c.kind, c.a, c.b) for c in w.contacts()]
    assert got and got[0] == ("robot-wall", 0, -1)


# -- the gap monitor ----------------------------------------------------------------------


def _problem(start, obstacles=(), size=10.0, radius=0.5):
    start = np.asarray(start, float)
    return Problem(size, size, tuple(obstacles), radius, 0.1, start, start)


def test_monitor_starts_empty():
    m = GapMonitor(_problem([[2, 2], [5, 5]]))
    assert (m.radius, m.cap, m.n_obstacles) == (0.5, SERIES_CAP * 0.5, 0)
    assert m.min_gap == float("inf") and np.isnan(m.min_time) and m.min_kind == "" and m.min_pair == (-1, -1)
    assert m.series.shape == (0,) and m.contacts() == []
    m.observe(np.zeros(0), np.zeros((0, 2, 2)))
    assert m.series.shape == (0,) and m.min_gap == float("inf")


def test_a_single_robot_has_only_static_gaps():
    m = GapMonitor(_problem([[2, 5]]))
    m.observe([0.0, 1.0], np.array([[[2.0, 5.0]], [[0.75, 5.0]]]))
    assert m.min_gap == pytest.approx(0.25) and (m.min_kind, m.min_pair, m.min_time) == (ROBOT_WALL, (0, -1), 1.0)
    assert m.series == pytest.approx([1.0, 0.25])


def test_monitor_series_is_capped_and_exact_below_the_cap():
    m = GapMonitor(_problem([[2, 5], [5, 5]]))
    pos = np.array([[[3.0, 5.0], [7.0, 5.0]], [[3.0, 5.0], [4.5, 5.0]], [[3.0, 5.0], [3.95, 5.0]]])
    m.observe([0.0, 0.5, 1.0], pos)
    # robot gaps: 3, 0.5, -0.05; wall gaps: 2.5 (x = 3), and 2.5 for robot 1 at x = 7
    assert m.series == pytest.approx([1.0, 0.5, -0.05])
    assert (m.min_kind, m.min_pair, m.min_time) == (ROBOT_ROBOT, (0, 1), 1.0)
    assert m.min_gap == pytest.approx(-0.05)
    [c] = m.contacts()
    assert (c.time, c.kind, c.a, c.b, c.witness) == (1.0, ROBOT_ROBOT, 0, 1, "monitor")
    assert c.depth == pytest.approx(0.05)


def test_a_gap_of_exactly_zero_is_not_a_contact():
    m = GapMonitor(_problem([[2, 5], [3, 5]]))
    m.observe([0.0], np.array([[[2.0, 5.0], [3.0, 5.0]]]))
    assert m.min_gap == 0.0 and m.contacts() == []
    m = GapMonitor(_problem([[0.5, 5]]))
    m.observe([0.0], np.array([[[0.5, 5.0]]]))
    assert m.min_gap == 0.0 and m.contacts() == []


def test_episodes_open_close_and_keep_their_deepest_overlap():
    m = GapMonitor(_problem([[2, 5]], [Circle((5.0, 5.0), 1.0)]))
    xs = [2.0, 3.7, 3.6, 3.7, 3.4, 3.8, 0.4, 0.45, 0.3, 2.0]  # circle gap 3.5 - x, wall gap x - 0.5
    pos = np.c_[xs, np.full(len(xs), 5.0)][:, None, :]
    times = np.arange(len(xs)) * 0.5
    m.observe(times[:2], pos[:2])
    m.observe(times[2:7], pos[2:7])
    m.observe(times[7:], pos[7:])
    got = [(c.time, c.kind, c.a, c.b) for c in m.contacts()]
    assert got == [(0.5, ROBOT_OBSTACLE, 0, 0), (2.5, ROBOT_OBSTACLE, 0, 0), (3.0, ROBOT_WALL, 0, -1)]
    assert [c.depth for c in m.contacts()] == pytest.approx([0.2, 0.3, 0.2])
    assert m.min_gap == pytest.approx(-0.3)
    assert (m.min_kind, m.min_pair, m.min_time) == (ROBOT_OBSTACLE, (0, 0), 2.5)


def test_two_episodes_at_once_and_the_minimum_of_the_deepest():
    # robots 0 and 1 overlap; robot 2 overlaps the wall, more deeply
    pos = np.array([[[2.0, 5.0], [2.9, 5.0], [9.55, 5.0]]])
    m = GapMonitor(_problem(pos[0]))
    m.observe([0.25], pos)
    got = sorted((c.kind, c.a, c.b) for c in m.contacts())
    assert got == [(ROBOT_ROBOT, 0, 1), (ROBOT_WALL, 2, -1)]
    assert (m.min_kind, m.min_pair) == (ROBOT_ROBOT, (0, 1)) and m.min_gap == pytest.approx(-0.1)
    pos = np.array([[[2.0, 5.0], [2.95, 5.0], [9.6, 5.0]]])
    m = GapMonitor(_problem(pos[0]))
    m.observe([0.25], pos)
    assert (m.min_kind, m.min_pair) == (ROBOT_WALL, (2, -1)) and m.min_gap == pytest.approx(-0.1)


def test_obstacle_indices_and_the_polygon_bound():
    square = Polygon(np.array([[6.0, 1.0], [8.0, 1.0], [8.0, 3.0], [6.0, 3.0]]))
    obstacles = (Circle((2.0, 8.0), 1.0), square)
    m = GapMonitor(_problem([[5, 5]], obstacles))
    # the robot enters the square from the left
    m.observe([0.0, 1.0], np.array([[[5.0, 2.0]], [[6.25, 2.0]]]))
    [c] = m.contacts()
    assert (c.kind, c.a, c.b) == (ROBOT_OBSTACLE, 0, 1)
    assert c.depth == pytest.approx(0.75)
    assert m.min_pair == (0, 1) and m.min_gap == pytest.approx(-0.75)


def test_static_clearances_columns_and_signs():
    triangle = Polygon(np.array([[6.0, 1.0], [8.0, 1.0], [8.0, 3.0]]))
    problem = _problem([[5, 5]], (Circle((2.0, 8.0), 1.0), triangle))
    pts = np.array([[2.0, 5.0], [7.5, 1.5], [5.0, 2.0]])
    out = static_clearances(problem.env, pts, 2)
    assert out.shape == (3, 3)
    assert out[:, 0] == pytest.approx([2.0, np.hypot(5.5, 6.5) - 1, np.hypot(3, 6) - 1])
    assert out[:, 1] == pytest.approx([np.hypot(4, 4), -0.5, np.hypot(1, 1)])
    assert out[:, 2] == pytest.approx([2.0, 1.5, 2.0])
    # with a bound: exact below it, elsewhere the distance to the bounding box
    low = static_clearances(problem.env, pts, 2, below=1.5)
    assert low[:, 1] == pytest.approx([np.hypot(4, 2), -0.5, np.hypot(1, 1)])
    assert low[:, [0, 2]] == pytest.approx(out[:, [0, 2]])
    per_point = static_clearances(problem.env, pts, 2, below=np.array([5.0, 0.0, 0.0]))
    assert per_point[:, 1] == pytest.approx([np.hypot(4, 4), 0.0, 1.0])
    # a single point as a flat pair
    assert static_clearances(problem.env, [7.5, 1.5], 2) == pytest.approx(out[1:2])


def test_sparse_robots_with_a_large_bound_use_nearest_neighbours():
    # many robots far apart: the pair list would be too long, so each sample is searched
    rng = np.random.default_rng(5)
    grid = np.stack(np.meshgrid(np.arange(10) * 4.0 + 2, np.arange(10) * 4.0 + 2), -1).reshape(-1, 2)
    problem = _problem(grid, size=42.0, radius=0.5)
    pos = np.repeat(grid[None], 3, axis=0) + rng.normal(0, 0.01, (3, 100, 2))
    pos[2, 57] = pos[2, 58] - [0.9, 0.0]  # robots 57 and 58 overlap by 0.1 in the last sample
    m = GapMonitor(problem)
    best, where, touching, per_sample = m._pairs_block(pos, np.inf)
    iu = np.triu_indices(100, 1)
    d = np.linalg.norm(pos[:, iu[0]] - pos[:, iu[1]], axis=2) - 1.0
    assert per_sample == pytest.approx(d.min(axis=1), abs=1e-12)
    assert best == pytest.approx(d.min(), abs=1e-12) and where == (2, 57, 58)
    assert [(s, i, j) for s, i, j, _ in touching] == [(2, 57, 58)]
    assert touching[0][3] == pytest.approx(-0.1)
    m.observe(np.arange(3.0), pos)
    assert [(c.a, c.b, c.time) for c in m.contacts()] == [(57, 58, 2.0)]
    assert m.min_time == 2.0


def test_nearest_neighbour_search_reports_the_touching_pair_in_order():
    grid = np.stack(np.meshgrid(np.arange(10) * 4.0 + 2, np.arange(10) * 4.0 + 2), -1).reshape(-1, 2)
    pos = grid[None].copy()
    pos[0, 31] = pos[0, 30] + [0.5, 0.0]  # robot 31 moved onto robot 30
    problem = _problem(grid, size=42.0)
    best, where, touching, per_sample = GapMonitor(problem)._pairs_block(pos, np.inf)
    assert where == (0, 30, 31) and best == pytest.approx(-0.5)
    assert [(s, i, j) for s, i, j, _ in touching] == [(0, 30, 31)]
    assert per_sample == pytest.approx([-0.5])


def test_pairs_farther_than_the_cutoff_are_not_measured_but_the_minimum_is_exact():
    pos = np.array([[[1.0, 1.0], [1.0, 2.5], [8.0, 8.0]]] * 2)
    pos[1, 1] = [1.0, 2.2]
    m = GapMonitor(_problem(pos[0]))
    best, where, touching, per_sample = m._pairs_block(pos, 0.0)
    assert where == (1, 0, 1) and best == pytest.approx(0.2) and touching == []
    assert per_sample == pytest.approx([0.5, 0.2])
    # no pair within reach: nothing measured
    far = np.array([[[1.0, 1.0], [8.0, 8.0]]])
    best, where, touching, per_sample = GapMonitor(_problem(far[0]))._pairs_block(far, 0.0)
    assert (best, where, touching) == (np.inf, None, []) and per_sample == pytest.approx([np.inf])


def test_verlet_blocks_cover_every_sample():
    # 40 samples: three blocks of 16; a touch in the last block is found and timed
    c = 40
    pos = np.zeros((c, 2, 2))
    pos[:, 0] = [3.0, 5.0]
    pos[:, 1] = [6.0, 5.0]
    pos[37, 1] = [3.9, 5.0]
    m = GapMonitor(_problem(pos[0]))
    m.observe(np.arange(c) * 0.1, pos)
    [contact] = m.contacts()
    assert contact.time == pytest.approx(3.7) and contact.depth == pytest.approx(0.1)
    assert m.min_time == pytest.approx(3.7)
    assert m.series[37] == pytest.approx(-0.1) and m.series[36] == pytest.approx(SERIES_CAP * 0.5)


def test_every_polygon_is_measured_after_one_that_is_far():
    far = Polygon(np.array([[8.0, 8.0], [9.0, 8.0], [9.0, 9.0]]))
    near = Polygon(np.array([[2.0, 1.0], [4.0, 1.0], [4.0, 3.0]]))
    problem = _problem([[5, 5]], (far, near))
    pts = np.array([[3.5, 2.0], [1.0, 2.0]])
    low = static_clearances(problem.env, pts, 2, below=1.5)
    assert low[:, 1] == pytest.approx([-np.sqrt(0.125), np.sqrt(2)])
    assert (low[:, 0] >= 1.5).all()


def test_ties_keep_the_first_sample_and_the_static_gap():
    # the same wall gap in samples 1 and 3: the first is the minimum's time
    m = GapMonitor(_problem([[5, 5]]))
    xs = [5.0, 0.75, 5.0, 0.75]
    m.observe(np.arange(4.0), np.c_[xs, np.full(4, 5.0)][:, None, :])
    assert m.min_time == 1.0
    m.observe([4.0], np.array([[[0.75, 5.0]]]))
    assert m.min_time == 1.0
    # a wall gap equal to a pair gap: the wall (found first) is kept
    pos = np.array([[[1.0, 5.0], [5.0, 5.0], [6.5, 5.0]]])
    m = GapMonitor(_problem(pos[0]))
    m.observe([0.0], pos)
    assert m.min_gap == 0.5 and (m.min_kind, m.min_pair) == (ROBOT_WALL, (0, -1))


def test_exact_touching_is_not_an_overlap_while_another_pair_overlaps():
    # robots 0-1 overlap; robots 2-3 touch exactly; robot 4 touches the wall exactly, robot 5 overlaps it
    pos = np.array([[[2.0, 2.0], [2.9, 2.0], [5.0, 5.0], [6.0, 5.0], [0.5, 8.0], [9.6, 8.0]]])
    m = GapMonitor(_problem(pos[0]))
    m.observe([0.0], pos)
    got = sorted((c.kind, c.a, c.b) for c in m.contacts())
    assert got == [(ROBOT_ROBOT, 0, 1), (ROBOT_WALL, 5, -1)]


def test_exact_touching_in_the_nearest_neighbour_search():
    grid = np.stack(np.meshgrid(np.arange(10) * 4.0 + 2, np.arange(10) * 4.0 + 2), -1).reshape(-1, 2)
    pos = grid[None].copy()
    pos[0, 31] = pos[0, 30] + [0.5, 0.0]  # overlaps robot 30
    pos[0, 71] = pos[0, 70] + [1.0, 0.0]  # touches robot 70 exactly
    problem = _problem(grid, size=42.0)
    _, _, touching, _ = GapMonitor(problem)._pairs_block(pos, np.inf)
    assert [(s, i, j) for s, i, j, _ in touching] == [(0, 30, 31)]


def test_nearest_neighbour_ties_keep_the_first_sample():
    grid = np.stack(np.meshgrid(np.arange(10) * 4.0 + 2, np.arange(10) * 4.0 + 2), -1).reshape(-1, 2)
    pos = np.repeat(grid[None], 3, axis=0)
    pos[1, 31] = pos[1, 30] + [0.5, 0.0]
    pos[2, 31] = pos[2, 30] + [0.5, 0.0]
    _, where, _, _ = GapMonitor(_problem(grid, size=42.0))._pairs_block(pos, np.inf)
    assert where == (1, 30, 31)


def test_pair_gaps_with_a_radius_other_than_a_half():
    pos = np.array([[[3.0, 5.0], [4.5, 5.0]]])
    m = GapMonitor(_problem(pos[0], radius=1.0))
    m.observe([0.0], pos)
    [c] = m.contacts()
    assert (c.kind, c.a, c.b) == (ROBOT_ROBOT, 0, 1) and c.depth == pytest.approx(0.5)


def test_pairs_beyond_the_cap_still_give_the_minimum():
    # two robots 1.5 apart (more than the cap of 1), far from the walls
    pos = np.array([[[50.0, 50.0], [52.5, 50.0]]])
    m = GapMonitor(_problem(pos[0], size=100.0))
    m.observe([0.0], pos)
    assert m.min_gap == pytest.approx(1.5) and m.min_kind == ROBOT_ROBOT


def test_series_is_exact_below_the_cap_after_a_smaller_minimum():
    # first a wall gap of 0.1; then two robots at gap 0.5 in the middle of the room
    m = GapMonitor(_problem([[0.6, 5.0], [8.0, 8.0]], size=20.0))
    m.observe([0.0], np.array([[[0.6, 5.0], [8.0, 8.0]]]))
    m.observe([1.0], np.array([[[10.0, 10.0], [11.5, 10.0]]]))
    assert m.series == pytest.approx([0.1, 0.5])


def test_series_is_exact_for_a_polygon_whose_box_is_nearer():
    # a triangle whose bounding box is nearer than its edges, in the second sample only
    tri = Polygon(np.array([[10.0, 10.0], [14.0, 10.0], [14.0, 14.0]]))
    m = GapMonitor(_problem([[0.6, 5.0]], (tri,), size=30.0))
    m.observe([0.0, 1.0], np.array([[[0.6, 5.0]], [[10.0, 10.0 + 0.7 * np.sqrt(2) * 2]]]))
    exact = static_clearances(m.env, np.array([[10.0, 10.0 + 1.4 * np.sqrt(2)]]), 1)[0, 0] - 0.5
    assert exact < SERIES_CAP * 0.5
    assert m.series == pytest.approx([0.1, exact])
