"""The witnesses' own kernels (sim.execute.kernels) against planner.geometry's, and by hand.

Each is checked against the other: a bug in either shows up as a mismatch.
"""

import numpy as np
import pytest

from planner import geometry as G
from planner.problem import Circle, Polygon, Problem
from sim.execute import kernels as K

U = np.array([[3.0, 3.0], [7.0, 3.0], [7.0, 7.0], [5.8, 7.0], [5.8, 4.0], [4.2, 4.0], [4.2, 7.0], [3.0, 7.0]])


def _star(rng, k):
    gaps = rng.uniform(1.0, 1.9, k)
    ang = np.cumsum(gaps) / gaps.sum() * 2 * np.pi
    rad = rng.uniform(0.3, 1.0, k)
    return np.c_[rad * np.cos(ang), rad * np.sin(ang)]


@pytest.mark.parametrize("seed", range(5))
def test_segment_distance_matches_the_planner(seed):
    rng = np.random.default_rng(seed)
    p, a, b = rng.normal(size=(3, 2000, 2))
    b[:50] = a[:50]  # zero-length segments
    p[50:100] = a[50:100] + rng.uniform(0, 1, (50, 1)) * (b[50:100] - a[50:100])  # on the segment
    assert K.segment_distance(p, a, b) == pytest.approx(G.point_segment_distance(p, a, b), abs=1e-12)


def test_segment_distance_by_hand():
    a, b = np.array([0.0, 0.0]), np.array([4.0, 0.0])
    pts = np.array([[2.0, 3.0], [-3.0, 4.0], [7.0, -4.0], [4.0, 0.0], [1.0, 0.0]])
    assert K.segment_distance(pts, a, b) == pytest.approx([3.0, 5.0, 5.0, 0.0, 0.0])
    assert float(K.segment_distance([3.0, 4.0], a, a)) == pytest.approx(5.0)


@pytest.mark.parametrize("seed", range(6))
def test_inside_polygon_matches_the_planner(seed):
    rng = np.random.default_rng(seed)
    poly = _star(rng, int(rng.integers(3, 15)))
    if seed % 2:
        poly = poly[::-1]
    pts = rng.uniform(-1.1, 1.1, (3000, 2))
    # points within 1e-9 of an edge may fall either way in both kernels
    edge = G.point_segment_distance(pts[:, None], poly[None], np.roll(poly, -1, axis=0)[None]).min(axis=1)
    keep = edge > 1e-9
    assert (K.inside_polygon(pts, poly) == G.points_in_polygon(pts, poly))[keep].all()


def test_inside_polygon_by_hand():
    pts = np.array([[3.5, 5.0], [5.0, 5.0], [6.5, 6.0], [5.0, 3.5], [8.0, 5.0], [2.0, 3.0]])
    expect = [True, False, True, True, False, False]
    assert K.inside_polygon(pts, U).tolist() == expect
    assert K.inside_polygon(pts, U[::-1]).tolist() == expect


@pytest.mark.parametrize("seed", range(3))
def test_point_clearance_matches_the_planner(seed):
    rng = np.random.default_rng(seed)
    obstacles = (Polygon(U), Circle((8.0, 8.0), 1.0), Polygon(_star(rng, 9) * 2 + [14.0, 5.0]))
    start = np.array([[1.0, 1.0]])
    problem = Problem(20.0, 12.0, obstacles, 0.5, 0.1, start, start)
    env = problem.env
    pts = rng.uniform(-1.0, 21.0, (4000, 2))
    pts[:, 1] *= 12.0 / 20.0
    ours = K.wall_clearance(pts, env.width, env.height)
    assert ours == pytest.approx(env.wall_clearance(pts), abs=1e-12)
    ours = np.minimum(ours, K.circle_clearance(pts, env.circle_centers, env.circle_radii).min(axis=1))
    for poly in env.polygons:
        ours = np.minimum(ours, np.maximum(K.polygon_signed_distance(pts, poly), 0.0))
    assert ours == pytest.approx(env.point_clearance(pts), abs=1e-12)


def test_clearances_by_hand():
    assert K.wall_clearance([[1.0, 2.0], [9.5, 5.0], [-1.0, 5.0]], 10.0, 6.0) == pytest.approx([1.0, 0.5, -1.0])
    assert K.circle_clearance([[3.0, 4.0], [0.5, 0.0]], [[0.0, 0.0]], [1.0])[:, 0] == pytest.approx([4.0, -0.5])
    assert K.polygon_signed_distance([[5.0, 5.0], [3.5, 5.0], [5.0, 2.0]], U) == pytest.approx([0.8, -0.5, 1.0])


# -- swept ---------------------------------------------------------------------------


@pytest.mark.parametrize("seed", range(5))
def test_swept_pair_matches_the_planners_closest_approach(seed):
    rng = np.random.default_rng(seed)
    a, b, c, d = rng.normal(size=(4, 3000, 2))
    b[:40] = a[:40]
    d[:40] = c[:40]  # both still
    d[40:80] = c[40:80] + (b[40:80] - a[40:80])  # same motion
    dist, s = K.swept_pair_distance(a, b, c, d)
    ref, theta = G.closest_approach(a, b, c, d, return_theta=True)
    assert dist == pytest.approx(ref, abs=1e-9)
    at = np.linalg.norm((a + s[:, None] * (b - a)) - (c + s[:, None] * (d - c)), axis=1)
    assert at == pytest.approx(dist, abs=1e-9)
    assert ((s >= 0) & (s <= 1)).all()


def test_swept_pair_by_hand():
    # head-on through each other, offset 0.3: closest at s = 0.5
    dist, s = K.swept_pair_distance([0.0, 0.0], [10.0, 0.0], [10.0, 0.3], [0.0, 0.3])
    assert float(dist) == pytest.approx(0.3) and float(s) == pytest.approx(0.5)
    # moving apart: closest at the start
    dist, s = K.swept_pair_distance([0.0, 0.0], [-1.0, 0.0], [2.0, 0.0], [3.0, 0.0])
    assert float(dist) == pytest.approx(2.0) and float(s) == 0.0
    # approaching, not yet passed: closest at the end
    dist, s = K.swept_pair_distance([0.0, 0.0], [1.0, 0.0], [5.0, 0.0], [4.0, 0.0])
    assert float(dist) == pytest.approx(3.0) and float(s) == 1.0


@pytest.mark.parametrize("seed", range(5))
def test_swept_segment_matches_the_planners_segment_distance(seed):
    rng = np.random.default_rng(seed)
    p0, p1, a, b = rng.normal(size=(4, 3000, 2))
    p1[:40] = p0[:40]  # a still centre
    dist, s = K.swept_segment_distance(p0, p1, a, b)
    assert dist == pytest.approx(G.segment_segment_distance(p0, p1, a, b), abs=1e-12)
    at = p0 + s[:, None] * (p1 - p0)
    assert K.segment_distance(at, a, b) == pytest.approx(dist, abs=1e-9)


def test_swept_segment_by_hand():
    wall_a, wall_b = [5.0, -1.0], [5.0, 1.0]
    dist, s = K.swept_segment_distance([0.0, 0.0], [10.0, 0.0], wall_a, wall_b)  # through it
    assert float(dist) == 0.0 and float(s) == pytest.approx(0.5)
    dist, s = K.swept_segment_distance([0.0, 3.0], [10.0, 3.0], wall_a, wall_b)  # past its end
    assert float(dist) == pytest.approx(2.0) and float(s) == pytest.approx(0.5)
    dist, s = K.swept_segment_distance([0.0, 0.0], [4.0, 0.0], wall_a, wall_b)  # stops short
    assert float(dist) == pytest.approx(1.0) and float(s) == 1.0


def test_swept_circle_and_wall():
    rng = np.random.default_rng(7)
    p0, p1, c = rng.normal(size=(3, 2000, 2))
    rad = rng.uniform(0.1, 1.0, 2000)
    dist, s = K.swept_circle_distance(p0, p1, c, rad)
    assert dist == pytest.approx(G.point_segment_distance(c, p0, p1) - rad, abs=1e-12)
    dist, s = K.swept_circle_distance([0.0, 0.5], [10.0, 0.5], [5.0, 0.0], 1.0)
    assert float(dist) == pytest.approx(-0.5) and float(s) == pytest.approx(0.5)
    # walls: the minimum of a concave clearance is at an end, so a fine sampling never goes lower
    q0, q1 = rng.uniform(-1, 11, (2, 500, 2))
    clear, _ = K.swept_wall_clearance(q0, q1, 10.0, 8.0)
    ss = np.linspace(0, 1, 101)[:, None, None]
    sampled = K.wall_clearance(q0 + ss * (q1 - q0), 10.0, 8.0).min(axis=0)
    assert (sampled >= clear - 1e-12).all() and clear == pytest.approx(np.minimum(
        K.wall_clearance(q0, 10.0, 8.0), K.wall_clearance(q1, 10.0, 8.0)))
