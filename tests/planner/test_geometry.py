"""The exact geometry kernels agree with dense brute-force sampling.

Every kernel in :mod:`planner.geometry` is closed-form.  Each test here
draws random inputs, computes the same quantity by sampling densely (points
on segments, on circles, on polygon edges, values of the interpolation
parameter) and checks the two against each other with a bound that follows
from the sampling step:

* the kernel is an exact minimum, so it is never above a sampled minimum
  (up to rounding);
* the sampled minimum is never above the kernel by more than the distance
  from the true minimiser to the nearest sample (half the sampling step,
  since every sampled quantity here is 1-Lipschitz in the sample position).

Inside tests for polygons use a winding number computed from angle sums,
independently of the even-odd crossing test under test.  The negative
controls at the end feed the same checkers a deliberately wrong kernel and
expect them to object, so a checker that cannot fail is noticed.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from planner.geometry import (
    Environment,
    closest_approach,
    point_segment_distance,
    points_in_polygon,
    segment_segment_distance,
)

SETTINGS = settings(
    deadline=None,
    max_examples=120,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much],
)
EPS = 1e-9  # rounding allowance on quantities of size ~10

coord = st.floats(-10.0, 10.0, allow_nan=False, allow_infinity=False)
point = st.tuples(coord, coord).map(np.array)


# ----------------------------------------------------------------------------
# independent references


def sample_segment(a, b, n: int) -> np.ndarray:
    """``n`` evenly spaced points on ``[a, b]``, both ends included."""
    t = np.linspace(0.0, 1.0, n)[:, None]
    return np.asarray(a, float) + t * (np.asarray(b, float) - np.asarray(a, float))


def winding_numbers(pts, poly) -> np.ndarray:
    """Winding number of the closed polygon around each point (sum of turning angles)."""
    pts = np.asarray(pts, float).reshape(-1, 2)
    v = np.asarray(poly, float)[None] - pts[:, None]  # (n, k, 2)
    w = np.roll(v, -1, axis=1)
    ang = np.arctan2(v[..., 0] * w[..., 1] - v[..., 1] * w[..., 0], (v * w).sum(axis=-1))
    return np.rint(ang.sum(axis=1) / (2 * np.pi)).astype(int)


def winding_number(p, poly) -> int:
    return int(winding_numbers(p, poly)[0])


def boundary_samples(poly, step: float) -> np.ndarray:
    """Points along every edge of a closed polygon, at most ``step`` apart."""
    poly = np.asarray(poly, float)
    out = []
    for a, b in zip(poly, np.roll(poly, -1, axis=0)):
        n = max(2, int(np.ceil(np.linalg.norm(b - a) / step)) + 1)
        out.append(sample_segment(a, b, n))
    return np.concatenate(out)


def circle_samples(center, radius, step: float) -> np.ndarray:
    n = max(8, int(np.ceil(2 * np.pi * radius / step)))
    th = np.linspace(0.0, 2 * np.pi, n, endpoint=False)
    return np.asarray(center, float) + radius * np.stack([np.cos(th), np.sin(th)], axis=1)


def nearest(p, samples) -> float:
    return float(np.sqrt(((samples - np.asarray(p, float)) ** 2).sum(axis=1)).min())


def brute_point_clearance(p, width, height, circles, polygons, step):
    """Clearance of one point by sampling every boundary, with the owner index.

    Obstacle indices follow the order circles first, then polygons, matching
    the ``obstacles`` list given to :meth:`Environment.build` in the tests.
    Returns ``{owner: clearance}`` with ``-1`` for the wall.
    """
    x, y = p
    walls = np.array([[0, 0], [width, 0], [width, height], [0, height]], float)
    inside_ws = 0 < x < width and 0 < y < height
    d = nearest(p, boundary_samples(walls, step))
    out = {-1: d if inside_ws else -d}
    for k, (c, r) in enumerate(circles):
        d = nearest(p, circle_samples(c, r, step))
        out[k] = -d if np.linalg.norm(np.asarray(p) - c) < r else d
    for j, poly in enumerate(polygons):
        k = len(circles) + j
        out[k] = 0.0 if winding_number(p, poly) != 0 else nearest(p, boundary_samples(poly, step))
    return out


# ----------------------------------------------------------------------------
# checkers (shared by the property tests and the negative controls)


def check_point_segment(kernel, p, a, b, n: int = 2000):
    got = float(kernel(p, a, b))
    sampled = nearest(p, sample_segment(a, b, n))
    length = float(np.linalg.norm(np.asarray(b) - np.asarray(a)))
    assert got <= sampled + EPS, (got, sampled)
    assert sampled <= got + length / (2 * (n - 1)) + EPS, (got, sampled)


def check_segment_segment(kernel, a, b, c, d, n: int = 300):
    got = float(kernel(a, b, c, d))
    s1, s2 = sample_segment(a, b, n), sample_segment(c, d, n)
    sampled = float(np.sqrt(((s1[:, None, :] - s2[None, :, :]) ** 2).sum(-1)).min())
    l1 = float(np.linalg.norm(np.asarray(b) - np.asarray(a)))
    l2 = float(np.linalg.norm(np.asarray(d) - np.asarray(c)))
    assert got >= 0.0
    assert got <= sampled + EPS, (got, sampled)
    assert sampled <= got + (l1 + l2) / (2 * (n - 1)) + EPS, (got, sampled)


def check_closest_approach(kernel, a, b, c, d, n: int = 4001):
    a, b, c, d = (np.asarray(v, float) for v in (a, b, c, d))
    got = float(kernel(a, b, c, d))
    th = np.linspace(0.0, 1.0, n)[:, None]
    gap = (a + th * (b - a)) - (c + th * (d - c))
    sampled = float(np.sqrt((gap**2).sum(axis=1)).min())
    rel = float(np.linalg.norm((b - a) - (d - c)))  # |d gap / d theta|
    assert got <= sampled + EPS, (got, sampled)
    assert sampled <= got + rel / (2 * (n - 1)) + EPS, (got, sampled)


# ----------------------------------------------------------------------------
# strategies


@st.composite
def star_polygon(draw, cx=None, cy=None):
    """A simple, generally non-convex polygon, star-shaped about its centre.

    Vertices go round the centre at increasing angles with random radii;
    the winding is counter-clockwise or clockwise at random.
    """
    k = draw(st.integers(3, 9))
    gaps = np.array(draw(st.lists(st.floats(0.3, 1.0), min_size=k, max_size=k)))
    ang = draw(st.floats(0.0, 2 * np.pi)) + np.cumsum(gaps) / gaps.sum() * 2 * np.pi
    assume(np.max(gaps / gaps.sum() * 2 * np.pi) < np.pi * 0.95)  # centre strictly inside
    radii = np.array(draw(st.lists(st.floats(0.4, 3.0), min_size=k, max_size=k)))
    cx = draw(st.floats(3.0, 17.0)) if cx is None else cx
    cy = draw(st.floats(3.0, 17.0)) if cy is None else cy
    poly = np.stack([cx + radii * np.cos(ang), cy + radii * np.sin(ang)], axis=1)
    if draw(st.booleans()):
        poly = poly[::-1]
    return poly


@st.composite
def world(draw):
    """A 20 x 20 workspace with up to two circles and up to two star polygons."""
    circles = []
    for _ in range(draw(st.integers(0, 2))):
        c = np.array([draw(st.floats(2.0, 18.0)), draw(st.floats(2.0, 18.0))])
        circles.append((c, draw(st.floats(0.3, 2.5))))
    polygons = [draw(star_polygon()) for _ in range(draw(st.integers(0, 2)))]
    obstacles = [SimpleNamespace(center=c, radius=r) for c, r in circles]
    obstacles += [SimpleNamespace(vertices=p) for p in polygons]
    env = Environment.build(20.0, 20.0, obstacles)
    return env, circles, polygons


in_ws = st.tuples(st.floats(0.0, 20.0), st.floats(0.0, 20.0)).map(np.array)


# ----------------------------------------------------------------------------
# point to segment


@SETTINGS
@given(point, point, point)
def test_point_segment_distance_matches_sampling(p, a, b):
    check_point_segment(point_segment_distance, p, a, b)


@SETTINGS
@given(point, point)
def test_point_segment_distance_degenerate_segment_is_point_distance(p, a):
    assert point_segment_distance(p, a, a) == pytest.approx(np.linalg.norm(p - a), abs=EPS)


def test_point_segment_distance_broadcasts():
    rng = np.random.default_rng(7)
    p = rng.uniform(-5, 5, (6, 1, 2))
    a = rng.uniform(-5, 5, (1, 4, 2))
    b = rng.uniform(-5, 5, (1, 4, 2))
    got = point_segment_distance(p, a, b)
    assert got.shape == (6, 4)
    for i in range(6):
        for j in range(4):
            assert got[i, j] == pytest.approx(float(point_segment_distance(p[i, 0], a[0, j], b[0, j])))


# ----------------------------------------------------------------------------
# segment to segment


@SETTINGS
@given(point, point, point, point)
def test_segment_segment_distance_matches_sampling(a, b, c, d):
    check_segment_segment(segment_segment_distance, a, b, c, d)


@SETTINGS
@given(point, point, point, point)
def test_segment_segment_distance_is_symmetric(a, b, c, d):
    ref = float(segment_segment_distance(a, b, c, d))
    for args in ((c, d, a, b), (b, a, c, d), (a, b, d, c)):
        assert float(segment_segment_distance(*args)) == pytest.approx(ref, abs=EPS)


@SETTINGS
@given(
    point,
    st.floats(0.0, 2 * np.pi),
    st.floats(0.2, 2.9),
    st.lists(st.floats(0.1, 5.0), min_size=4, max_size=4),
)
def test_crossing_segments_are_exactly_zero_apart(x, phi, turn, ext):
    """Two segments through a common point at a clear angle meet: distance 0."""
    u = np.array([np.cos(phi), np.sin(phi)])
    v = np.array([np.cos(phi + turn), np.sin(phi + turn)])
    a, b = x - ext[0] * u, x + ext[1] * u
    c, d = x - ext[2] * v, x + ext[3] * v
    assert float(segment_segment_distance(a, b, c, d)) == 0.0


@SETTINGS
@given(point, point, st.floats(0.0, 1.0), st.floats(0.01, 5.0))
def test_touching_and_parallel_segments(a, b, t, off):
    """A segment that starts on another is 0 away; a parallel copy is ``off`` away."""
    assume(np.linalg.norm(b - a) > 1e-3)
    on = a + t * (b - a)
    n = np.array([-(b - a)[1], (b - a)[0]]) / np.linalg.norm(b - a)
    assert float(segment_segment_distance(a, b, on, on + n)) == pytest.approx(0.0, abs=EPS)
    assert float(segment_segment_distance(a, b, a + off * n, b + off * n)) == pytest.approx(off, rel=1e-9)


# ----------------------------------------------------------------------------
# closest approach of two points moving together


@SETTINGS
@given(point, point, point, point)
def test_closest_approach_matches_sampling(a, b, c, d):
    check_closest_approach(closest_approach, a, b, c, d)


@SETTINGS
@given(point, point, point)
def test_closest_approach_with_a_static_robot(a, c, d):
    """A robot that stays at ``a`` meets the mover at its point-segment distance."""
    check_closest_approach(closest_approach, a, a, c, d)
    check_closest_approach(closest_approach, c, d, a, a)
    ref = nearest(a, sample_segment(c, d, 4001))
    assert float(closest_approach(a, a, c, d)) <= ref + EPS


@SETTINGS
@given(point, point, point, point)
def test_closest_approach_theta_attains_the_distance(a, b, c, d):
    dist, theta = closest_approach(a, b, c, d, return_theta=True)
    assert 0.0 <= float(theta) <= 1.0
    gap = (a + theta * (b - a)) - (c + theta * (d - c))
    assert float(np.linalg.norm(gap)) == pytest.approx(float(dist), abs=1e-9)


def test_closest_approach_parallel_motion_keeps_the_start_gap():
    a, c = np.array([0.0, 0.0]), np.array([3.0, 4.0])
    shift = np.array([7.0, -2.0])
    assert float(closest_approach(a, a + shift, c, c + shift)) == pytest.approx(5.0)


def test_closest_approach_head_on_swap_meets():
    """Two robots swapping places along one line pass through each other at theta 1/2."""
    a, b = np.array([0.0, 0.0]), np.array([4.0, 0.0])
    dist, theta = closest_approach(a, b, b, a, return_theta=True)
    assert float(dist) == 0.0
    assert float(theta) == pytest.approx(0.5)


# ----------------------------------------------------------------------------
# point in polygon


@SETTINGS
@given(star_polygon(cx=10.0, cy=10.0), st.lists(st.tuples(st.floats(5, 15), st.floats(5, 15)), min_size=1, max_size=30))
def test_points_in_polygon_matches_winding_number(poly, pts):
    pts = np.array(pts, float)
    boundary = boundary_samples(poly, 0.01)
    keep = [p for p in pts if nearest(p, boundary) > 0.02]  # off the boundary
    assume(keep)
    keep = np.array(keep)
    got = points_in_polygon(keep, poly)
    want = winding_numbers(keep, poly) != 0
    assert got.shape == (len(keep),)
    np.testing.assert_array_equal(got, want)


def test_points_in_polygon_non_convex_notch():
    """A U shape: the notch between the arms is outside, the arms inside."""
    u = np.array([[0, 0], [6, 0], [6, 6], [4, 6], [4, 2], [2, 2], [2, 6], [0, 6]], float)
    pts = np.array([[3, 4], [1, 4], [5, 4], [3, 1], [7, 1], [3, 7]], float)
    want = [False, True, True, True, False, False]
    np.testing.assert_array_equal(points_in_polygon(pts, u), want)
    np.testing.assert_array_equal(points_in_polygon(pts, u[::-1]), want)


# ----------------------------------------------------------------------------
# environment: point clearance


@SETTINGS
@given(world(), st.lists(in_ws, min_size=1, max_size=5))
def test_point_clearance_matches_sampling(w, pts):
    env, circles, polygons = w
    step = 0.02
    pts = np.array(pts)
    got, who = env.point_clearance_detail(pts)
    assert got.shape == who.shape == (len(pts),)
    np.testing.assert_array_equal(env.point_clearance(pts), got)
    for p, g, k in zip(pts, got, who):
        ref = brute_point_clearance(p, 20.0, 20.0, circles, polygons, step)
        best = min(ref.values())
        assert abs(g - best) <= step / 2 + EPS, (p, g, ref)
        # the reported owner attains the clearance
        assert int(k) in ref
        assert abs(ref[int(k)] - g) <= step / 2 + EPS, (p, g, int(k), ref)


@SETTINGS
@given(world(), in_ws)
def test_wall_clearance_is_distance_to_the_rectangle(w, p):
    env = w[0]
    walls = np.array([[0, 0], [20, 0], [20, 20], [0, 20]], float)
    ref = nearest(p, boundary_samples(walls, 0.02))
    assert float(env.wall_clearance(p)) == pytest.approx(ref, abs=0.01 + EPS)


def test_wall_clearance_is_negative_outside():
    env = Environment.build(10.0, 8.0, [])
    got = env.wall_clearance(np.array([[-1.0, 4.0], [5.0, 9.5], [5.0, 4.0]]))
    np.testing.assert_allclose(got, [-1.0, -1.5, 4.0])


def test_point_clearance_signs_and_owners():
    """Circles are signed (negative inside); polygons are 0 inside, not negative."""
    obstacles = [
        SimpleNamespace(center=(10.0, 10.0), radius=3.0),
        SimpleNamespace(vertices=np.array([[20, 20], [30, 20], [30, 30], [20, 30]], float)),
    ]
    env = Environment.build(40.0, 40.0, obstacles)
    pts = np.array([[10.0, 11.0], [25.0, 25.0], [33.0, 25.0], [38.5, 5.0]])
    got, who = env.point_clearance_detail(pts)
    np.testing.assert_allclose(got, [-2.0, 0.0, 3.0, 1.5])
    np.testing.assert_array_equal(who, [0, 1, 1, -1])


# ----------------------------------------------------------------------------
# environment: segment clearance


@SETTINGS
@given(world(), st.lists(st.tuples(in_ws, in_ws), min_size=1, max_size=3))
def test_segment_clearance_matches_sampled_point_clearance(w, segs):
    env = w[0]
    a = np.array([s[0] for s in segs])
    b = np.array([s[1] for s in segs])
    got, who = env.segment_clearance_detail(a, b)
    np.testing.assert_array_equal(env.segment_clearance(a, b), got)
    n = 2000
    for i in range(len(a)):
        samples = sample_segment(a[i], b[i], n)
        clear, owners = env.point_clearance_detail(samples)
        sampled = float(clear.min())
        length = float(np.linalg.norm(b[i] - a[i]))
        assert got[i] <= sampled + EPS, (a[i], b[i], got[i], sampled)
        assert sampled <= got[i] + length / (2 * (n - 1)) + EPS, (a[i], b[i], got[i], sampled)
        # the reported owner is one whose own clearance along the segment attains it
        if int(who[i]) == -1:
            own = float(env.wall_clearance(samples).min())
        else:
            own = float(_owner_clearance(env, int(who[i]), samples).min())
        assert abs(own - got[i]) <= length / (2 * (n - 1)) + 1e-7, (int(who[i]), own, got[i])


def _owner_clearance(env: Environment, owner: int, pts: np.ndarray) -> np.ndarray:
    """Clearance of ``pts`` from one obstacle of ``env`` alone (no walls)."""
    if owner in env.circle_ids:
        k = env.circle_ids.index(owner)
        return np.linalg.norm(pts - env.circle_centers[k], axis=1) - env.circle_radii[k]
    poly = env.polygons[env.polygon_ids.index(owner)]
    d = point_segment_distance(pts[:, None, :], poly[None], np.roll(poly, -1, axis=0)[None]).min(axis=1)
    return np.where(winding_numbers(pts, poly) != 0, 0.0, d)


def test_segment_through_a_polygon_has_zero_clearance():
    """A segment that crosses a square without an end inside it still touches it."""
    square = SimpleNamespace(vertices=np.array([[8, 8], [12, 8], [12, 12], [8, 12]], float))
    env = Environment.build(20.0, 20.0, [square])
    got, who = env.segment_clearance_detail(np.array([[2.0, 10.0]]), np.array([[18.0, 10.0]]))
    assert got[0] == 0.0 and who[0] == 0
    got, who = env.segment_clearance_detail(np.array([[2.0, 13.0]]), np.array([[18.0, 13.0]]))
    assert got[0] == pytest.approx(1.0) and who[0] == 0


def test_segment_clearance_circle_between_the_ends():
    """The closest point to a circle is in the middle of the segment, not at an end."""
    env = Environment.build(20.0, 20.0, [SimpleNamespace(center=(10.0, 10.0), radius=1.0)])
    got, who = env.segment_clearance_detail(np.array([[4.0, 13.0]]), np.array([[16.0, 13.0]]))
    assert got[0] == pytest.approx(2.0) and who[0] == 0


# ----------------------------------------------------------------------------
# negative controls: the checkers reject wrong kernels


def _line_distance(p, a, b):
    """Wrong on purpose: distance to the infinite line, not the segment."""
    ab, ap = np.asarray(b) - np.asarray(a), np.asarray(p) - np.asarray(a)
    return abs(ab[0] * ap[1] - ab[1] * ap[0]) / np.linalg.norm(ab)


def _endpoint_only_distance(a, b, c, d):
    """Wrong on purpose: only end-point distances, so crossings are missed."""
    return min(
        point_segment_distance(a, c, d),
        point_segment_distance(b, c, d),
        point_segment_distance(c, a, b),
        point_segment_distance(d, a, b),
    )


def _unclipped_closest_approach(a, b, c, d):
    """Wrong on purpose: theta is not clipped to [0, 1]."""
    w, u = a - c, (b - a) - (d - c)
    t = -np.dot(w, u) / np.dot(u, u)
    return np.linalg.norm(w + t * u)


def test_checkers_catch_wrong_kernels():
    p, a, b = np.array([5.0, 1.0]), np.array([0.0, 0.0]), np.array([2.0, 0.0])
    check_point_segment(point_segment_distance, p, a, b)
    with pytest.raises(AssertionError):
        check_point_segment(_line_distance, p, a, b)

    cross = [np.array(v, float) for v in ([0, 0], [4, 4], [0, 4], [4, 0])]
    check_segment_segment(segment_segment_distance, *cross)
    with pytest.raises(AssertionError):
        check_segment_segment(_endpoint_only_distance, *cross)

    # two robots that would meet at theta = 3, after both have stopped
    mv = [np.array(v, float) for v in ([0, 0], [1, 0], [6, 0], [5, 0])]
    check_closest_approach(closest_approach, *mv)
    with pytest.raises(AssertionError):
        check_closest_approach(_unclipped_closest_approach, *mv)


def test_clearance_reference_catches_a_convex_hull_shortcut():
    """Treating a non-convex polygon as its convex hull is caught by the reference."""
    u = np.array([[0, 0], [6, 0], [6, 6], [4, 6], [4, 2], [2, 2], [2, 6], [0, 6]], float)
    hull = np.array([[0, 0], [6, 0], [6, 6], [0, 6]], float)
    p = np.array([3.0, 5.0])  # in the notch: 1 from the arms, inside the hull
    ref = brute_point_clearance(p + 7, 20.0, 20.0, [], [u + 7], 0.01)
    env = Environment.build(20.0, 20.0, [SimpleNamespace(vertices=u + 7)])
    wrong = Environment.build(20.0, 20.0, [SimpleNamespace(vertices=hull + 7)])
    assert abs(float(env.point_clearance(p + 7)[0]) - min(ref.values())) <= 0.005
    assert abs(float(wrong.point_clearance(p + 7)[0]) - min(ref.values())) > 0.5
