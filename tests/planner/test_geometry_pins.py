"""The geometry kernels the validator and the contact monitor stand on, pinned (planner/geometry.py).

Closed-form answers written by hand, and seeded random cases checked against dense
sampling, in milliseconds: the tests that mutation testing of ``planner/geometry.py``
runs (see ``tests/mutation/``).
"""

import numpy as np
import pytest

from planner.geometry import (
    Environment,
    _crossing,
    _fold_min,
    closest_approach,
    point_segment_distance,
    points_in_polygon,
    segment_segment_distance,
)
from planner.problem import Circle, Polygon

TRI = np.array([[4.0, 2.0], [8.0, 2.0], [8.0, 6.0]])
SQUARE = np.array([[12.0, 12.0], [14.0, 12.0], [14.0, 14.0], [12.0, 14.0]])


def _env():
    return Environment.build(20, 16, (Polygon(TRI), Circle((15.0, 4.0), 1.5), Polygon(SQUARE)))


def test_point_segment_distance_by_hand():
    a, b = np.array([0.0, 0.0]), np.array([4.0, 0.0])
    pts = np.array([[2.0, 3.0], [-3.0, 4.0], [7.0, -4.0], [1.0, 0.0], [4.0, 0.5]])
    assert point_segment_distance(pts, a, b) == pytest.approx([3.0, 5.0, 5.0, 0.0, 0.5])
    # a slanted segment: the foot lies inside
    assert point_segment_distance([0.0, 2.0], [0.0, 0.0], [2.0, 2.0]) == pytest.approx(np.sqrt(2))
    assert point_segment_distance([3.0, 1.0], [0.0, 0.0], [2.0, 2.0]) == pytest.approx(np.sqrt(2))
    # a zero-length segment is a point
    assert point_segment_distance([3.0, 4.0], [0.0, 0.0], [0.0, 0.0]) == pytest.approx(5.0)
    # broadcasting over (n, 1) points and (1, k) segments
    d = point_segment_distance(pts[:, None], np.zeros((1, 1, 2)) + [[0, 0]], np.zeros((1, 2)) + [[4, 0], [0, 4]])
    assert d.shape == (5, 2) and d[0] == pytest.approx([3.0, 2.0])


def test_crossing_is_strict():
    a, b = np.array([[0.0, 0.0]]), np.array([[2.0, 2.0]])
    assert _crossing(a, b, np.array([[0.0, 2.0]]), np.array([[2.0, 0.0]])).tolist() == [True]
    # touching at an end, collinear, parallel, apart: not a crossing
    for c, d in (([1.0, 1.0], [3.0, 0.0]), ([3.0, 3.0], [4.0, 4.0]), ([0.0, 1.0], [2.0, 3.0]), ([5.0, 0.0], [6.0, 1.0])):
        assert _crossing(a, b, np.array([c]), np.array([d])).tolist() == [False]
    # each of the four orientations matters
    assert _crossing(a, b, np.array([[0.0, 2.0]]), np.array([[0.9, 1.0]])).tolist() == [False]
    assert _crossing(np.array([[0.0, 2.0]]), np.array([[0.9, 1.0]]), a, b).tolist() == [False]
    assert _crossing(a, np.array([[0.9, 0.9]]), np.array([[0.0, 2.0]]), np.array([[2.0, 0.0]])).tolist() == [False]


def test_segment_segment_distance_by_hand():
    assert segment_segment_distance([0, 0], [2, 2], [0, 2], [2, 0]) == 0.0
    assert segment_segment_distance([0, 0], [4, 0], [1, 1], [3, 2]) == pytest.approx(1.0)
    assert segment_segment_distance([1, 1], [3, 2], [0, 0], [4, 0]) == pytest.approx(1.0)
    assert segment_segment_distance([0, 0], [1, 0], [3, 0], [5, 0]) == pytest.approx(2.0)
    assert segment_segment_distance([3, 0], [5, 0], [0, 0], [1, 0]) == pytest.approx(2.0)
    assert segment_segment_distance([0, 0], [0, 1], [2, -5], [2, 5]) == pytest.approx(2.0)
    assert segment_segment_distance([2, -5], [2, 5], [0, 0], [0, 1]) == pytest.approx(2.0)


def test_closest_approach_by_hand():
    # head on: they meet in the middle
    d, t = closest_approach([0, 0], [4, 0], [4, 0], [0, 0], return_theta=True)
    assert d == pytest.approx(0.0) and t == pytest.approx(0.5)
    # passing at distance 1, the moving one reaching the closest point at 3/4
    d, t = closest_approach([0, 1], [4, 1], [3, 0], [3, 0], return_theta=True)
    assert d == pytest.approx(1.0) and t == pytest.approx(0.75)
    d, t = closest_approach([3, 0], [3, 0], [0, 1], [4, 1], return_theta=True)
    assert d == pytest.approx(1.0) and t == pytest.approx(0.75)
    # moving apart: closest at the start; moving closer all along: at the end
    d, t = closest_approach([0, 0], [-1, 0], [2, 0], [3, 0], return_theta=True)
    assert d == pytest.approx(2.0) and t == 0.0
    d, t = closest_approach([0, 0], [1, 0], [5, 0], [4, 0], return_theta=True)
    assert d == pytest.approx(3.0) and t == 1.0
    # moving together: no relative motion, theta 0
    d, t = closest_approach([0, 0], [1, 1], [0, 3], [1, 4], return_theta=True)
    assert d == pytest.approx(3.0) and t == 0.0
    # both components of the relative motion count
    d, t = closest_approach([0, 0], [0, 4], [1, 3], [1, 3], return_theta=True)
    assert d == pytest.approx(1.0) and t == pytest.approx(0.75)
    assert closest_approach([0, 0], [4, 0], [3, 0], [3, 0]) == pytest.approx(0.0)


def test_closest_approach_matches_sampling():
    rng = np.random.default_rng(7)
    a, b, c, d = rng.uniform(-5, 5, size=(4, 200, 2))
    dist, theta = closest_approach(a, b, c, d, return_theta=True)
    ts = np.linspace(0, 1, 2001)[:, None, None]
    sampled = np.linalg.norm((a + ts * (b - a)) - (c + ts * (d - c)), axis=2)
    assert dist == pytest.approx(sampled.min(axis=0), abs=1e-3)
    assert np.all(dist <= sampled.min(axis=0) + 1e-12)
    at = np.linalg.norm((a + theta[:, None] * (b - a)) - (c + theta[:, None] * (d - c)), axis=1)
    assert at == pytest.approx(dist, abs=1e-12)


def test_points_in_polygon_by_hand():
    pts = np.array([[7.0, 3.0], [5.0, 3.5], [9.0, 3.0], [7.0, 1.0], [7.5, 5.0], [6.0, 5.0], [7.9, 5.8]])
    assert points_in_polygon(pts, TRI).tolist() == [True, False, False, False, True, False, True]
    assert points_in_polygon([13.0, 13.0], SQUARE).tolist() == [True]
    assert points_in_polygon(pts, TRI[::-1]).tolist() == [True, False, False, False, True, False, True]
    # a point level with a vertex counts the crossing once
    assert points_in_polygon([[7.0, 2.0 + 1e-12], [3.0, 6.0]], TRI).tolist() == [True, False]


def test_wall_clearance_is_the_nearest_side():
    env = _env()
    pts = np.array([[1.0, 8.0], [19.5, 8.0], [10.0, 0.25], [10.0, 15.0], [10.0, 8.0]])
    assert env.wall_clearance(pts) == pytest.approx([1.0, 0.5, 0.25, 1.0, 8.0])


def test_point_clearance_detail_names_the_obstacle():
    env = _env()
    pts = np.array([[7.0, 3.0], [3.0, 2.0], [15.0, 6.0], [13.0, 10.0], [10.0, 8.0], [0.5, 8.0], [16.5, 4.0]])
    cl, who = env.point_clearance_detail(pts)
    assert who.tolist() == [0, 0, 1, 2, 0, -1, 1]
    assert cl == pytest.approx([0.0, 1.0, 0.5, 2.0, np.hypot(2, 2), 0.5, 0.0])
    assert env.point_clearance(pts) == pytest.approx(cl)
    # a point nearer a wall than anything: the wall, by strict comparison on ties
    cl, who = env.point_clearance_detail([[16.0, 14.5]])
    assert who.tolist() == [-1] and cl == pytest.approx([1.5])


def test_segment_clearance_detail_by_hand():
    env = _env()
    a = np.array([[10.0, 0.5], [2.0, 4.0], [10.0, 7.0], [15.0, 9.0], [1.0, 10.0], [11.0, 11.0], [4.0, 7.0]])
    b = np.array([[10.0, 6.0], [4.0, 2.0], [16.0, 7.0], [15.0, 6.5], [1.0, 15.0], [15.0, 15.0], [10.0, 1.0]])
    cl, who = env.segment_clearance_detail(a, b)
    # 0: from the bottom wall (0.5) up; 1: ends at the triangle's corner; 2: passes above the circle;
    # 3: towards the circle; 4: along the left wall; 5: through the square; 6: through the triangle
    assert who.tolist() == [-1, 0, 1, 1, -1, 2, 0]
    assert cl == pytest.approx([0.5, 0.0, 1.5, 1.0, 1.0, 0.0, 0.0])
    assert env.segment_clearance(a, b) == pytest.approx(cl)


def test_segment_clearance_matches_sampled_points():
    env = _env()
    rng = np.random.default_rng(11)
    a = rng.uniform([0.5, 0.5], [19.5, 15.5], size=(150, 2))
    b = a + rng.normal(0, 3, size=(150, 2))
    b = np.clip(b, 0.5, [19.5, 15.5])
    cl, who = env.segment_clearance_detail(a, b)
    ts = np.linspace(0, 1, 401)
    pts = (a[:, None] + ts[None, :, None] * (b - a)[:, None]).reshape(-1, 2)
    pc, pw = env.point_clearance_detail(pts)
    pc = pc.reshape(150, -1)
    assert np.all(cl <= pc.min(axis=1) + 1e-12)
    assert cl == pytest.approx(pc.min(axis=1), abs=0.04)
    k = pc.argmin(axis=1)
    agree = who == pw.reshape(150, -1)[np.arange(150), k]
    assert agree.mean() > 0.95


def test_point_clearance_matches_brute_force():
    env = _env()
    rng = np.random.default_rng(5)
    pts = rng.uniform(0, [20, 16], size=(500, 2))
    cl, who = env.point_clearance_detail(pts)
    walls = np.minimum.reduce([pts[:, 0], 20 - pts[:, 0], pts[:, 1], 16 - pts[:, 1]])
    circle = np.linalg.norm(pts - [15.0, 4.0], axis=1) - 1.5
    polys = []
    for poly in (TRI, SQUARE):
        d = point_segment_distance(pts[:, None], poly[None], np.roll(poly, -1, axis=0)[None]).min(axis=1)
        polys.append(np.where(points_in_polygon(pts, poly), 0.0, d))
    table = np.stack([walls, polys[0], circle, polys[1]], axis=1)
    assert cl == pytest.approx(table.min(axis=1), abs=1e-12)
    assert who.tolist() == [[-1, 0, 1, 2][j] for j in table.argmin(axis=1)]


def test_many_points_and_segments_in_chunks(monkeypatch):
    import planner.geometry as geometry

    env = _env()
    rng = np.random.default_rng(2)
    pts = rng.uniform(0, [20, 16], size=(50, 2))
    b = np.clip(pts + rng.normal(0, 2, size=(50, 2)), 0, [20, 16])
    whole = env.point_clearance_detail(pts), env.segment_clearance_detail(pts, b)
    monkeypatch.setattr(geometry, "_CHUNK", 64)
    parts = env.point_clearance_detail(pts), env.segment_clearance_detail(pts, b)
    for (c1, w1), (c2, w2) in zip(whole, parts):
        assert c1 == pytest.approx(c2, abs=0) and w1.tolist() == w2.tolist()


def test_fold_min_keeps_the_first_owner_on_ties():
    best, who = _fold_min(np.array([1.0, 2.0, 3.0]), np.array([-1, -1, -1]),
                          np.array([[0.5, 0.4], [2.0, 3.0], [1.0, 1.0]]), (7, 9))
    assert best.tolist() == [0.4, 2.0, 1.0] and who.tolist() == [9, -1, 7]


def test_empty_worlds_and_inputs():
    env = Environment.build(10, 10, ())
    cl, who = env.point_clearance_detail([[2.0, 3.0]])
    assert cl.tolist() == [2.0] and who.tolist() == [-1]
    cl, who = env.segment_clearance_detail([[2.0, 3.0]], [[5.0, 5.0]])
    assert cl.tolist() == [2.0] and who.tolist() == [-1]
    assert env.point_clearance_detail(np.zeros((0, 2)))[0].shape == (0,)
    assert _env().segment_clearance_detail(np.zeros((0, 2)), np.zeros((0, 2)))[0].shape == (0,)


# a comb: a ray to the right from a point in its first tooth crosses three edges
COMB = np.array([[0.0, 0.0], [6.0, 0.0], [6.0, 3.0], [5.0, 3.0], [5.0, 1.0], [3.0, 1.0], [3.0, 3.0],
                 [2.0, 3.0], [2.0, 1.0], [1.0, 1.0], [1.0, 3.0], [0.0, 3.0]])


def test_inside_tests_count_every_crossing():
    pts = np.array([[0.5, 2.0], [1.5, 2.0], [2.5, 2.0], [4.0, 2.0], [5.5, 2.0], [3.0, 0.5], [7.0, 0.5]])
    want = [True, False, True, False, True, True, False]
    assert points_in_polygon(pts, COMB).tolist() == want
    env = Environment.build(10, 10, (Polygon(COMB + 1.0),))
    assert env._inside(pts + 1.0)[:, 0].tolist() == want
    assert env._inside([[1.5, 3.0]]).tolist() == [[True]]  # a single point


def test_points_level_with_a_vertex():
    # level with the apex (8, 6), and with the bottom edge's end points
    pts = np.array([[5.0, 6.0], [9.0, 6.0], [3.0, 2.0], [9.0, 2.0], [7.0, 2.5]])
    want = [False, False, False, False, True]
    assert points_in_polygon(pts, TRI).tolist() == want
    assert _env()._inside(pts)[:, 0].tolist() == want


def test_inside_for_many_points_uses_the_index_and_agrees():
    rng = np.random.default_rng(9)
    polys = (COMB + [2.0, 8.0], TRI, SQUARE, COMB * 0.5 + [14.0, 2.0])
    env = Environment.build(20, 16, tuple(Polygon(p) for p in polys))
    pts = rng.uniform(0, [20, 16], size=(5000, 2))
    pts[:7] = [[2.5, 10.0], [4.5, 10.0], [7.0, 3.0], [13.0, 13.0], [14.25, 3.0], [19.0, 15.0], [3.5, 10.0]]
    assert len(pts) * len(env.edges[0]) > 1 << 17  # past the dense test
    got = env._inside(pts)
    want = np.stack([points_in_polygon(pts, p) for p in polys], axis=1)
    assert got.shape == want.shape and np.array_equal(got, want)
    assert got[:7].tolist() == [[True, False, False, False], [True, False, False, False], [False, True, False, False],
                                [False, False, True, False], [False, False, False, True], [False] * 4, [False] * 4]
    # every point outside every polygon's box: nothing to test
    far = np.array([[0.5, 15.5]] * 40000)
    assert not env._inside(far).any() and env._inside(far).shape == (40000, 4)
