"""The fast boolean clearance tests agree exactly with the exact kernels."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from planner.problem import Circle, Polygon, Problem


def _world():
    obstacles = (
        Polygon(np.array([[12, 10], [20, 10], [20, 13], [15, 13], [15, 20], [12, 20]])),
        Circle((28, 28), 3.0),
        Polygon(np.array([[30, 5], [36, 5], [33, 11]])),
    )
    return Problem(40, 40, obstacles, 1.0, 0.1, np.zeros((0, 2)), np.zeros((0, 2)))


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 2**31), st.floats(0.0, 3.0))
def test_segments_and_points_clear_match_exact(seed, clearance):
    rng = np.random.default_rng(seed)
    env = _world().env
    a = rng.uniform(-2, 42, size=(300, 2))
    b = a + rng.normal(0, 6, size=(300, 2))
    assert np.array_equal(env.segments_clear(a, b, clearance), env.segment_clearance(a, b) >= clearance)
    assert np.array_equal(env.points_clear(a, clearance), env.point_clearance(a) >= clearance)


def test_edge_planner_shortcut_agrees_with_full_test():
    """The KD-tree rejection never changes an answer of the exact edge test."""
    from planner.geometry import point_segment_distance
    from planner.pebble import edge_mask, sample_free_points

    p = _world()
    rng = np.random.default_rng(4)
    v = sample_free_points(p, 90, rng)
    iu, ju = np.triu_indices(len(v), 1)
    pairs = np.stack([iu, ju], axis=1)
    fast = edge_mask(p, v, pairs)
    d = point_segment_distance(v[None], v[iu][:, None], v[ju][:, None])
    d[np.arange(len(iu)), iu] = np.inf
    d[np.arange(len(iu)), ju] = np.inf
    full = (d.min(axis=1) >= p.separation) & (p.env.segment_clearance(v[iu], v[ju]) >= p.clearance)
    assert np.array_equal(fast, full)


def test_segments_wholly_inside_or_grazing_a_polygon():
    """Segments inside a polygon (no edge near) and segments passing its box's corner."""
    env = _world().env
    inside_a = np.array([[13.5, 15.0], [12.5, 11.0], [18.0, 11.5]])
    inside_b = inside_a + [[0.0, 4.0], [1.0, 0.5], [0.5, 0.5]]
    assert not env.segments_clear(inside_a, inside_b, 0.1).any()
    assert np.array_equal(env.segments_clear(inside_a, inside_b, 0.0), env.segment_clearance(inside_a, inside_b) >= 0.0)
    # past the box's corner (20, 13): clear iff the corner stays ``clearance`` away
    a = np.array([[21.0, 12.0], [20.5, 14.5]])
    b = np.array([[21.0, 14.0], [22.5, 14.5]])
    for clearance in (0.4, 0.9, 1.0, 1.2):
        assert np.array_equal(env.segments_clear(a, b, clearance), env.segment_clearance(a, b) >= clearance)


def test_segments_at_exactly_the_clearance_agree_with_the_exact_kernel():
    """Parallel to an edge, or ending, exactly ``clearance`` away: the fast test is the
    exact one to the bit (a segment exactly at the clearance is clear)."""
    env = _world().env
    a = np.array([[12.0, 9.0], [11.0, 12.0], [16.0, 14.0], [14.0, 20.5], [13.0, 8.0]])
    b = np.array([[20.0, 9.0], [11.0, 18.0], [16.0, 24.0], [17.0, 20.5], [13.0, 22.0]])
    for clearance in (0.5, 1.0, 1.5):
        fast = env.segments_clear(a, b, clearance)
        assert np.array_equal(fast, env.segment_clearance(a, b) >= clearance)
    assert env.segments_clear(a[:3], b[:3], 1.0).all()  # each exactly 1.0 away
    assert not env.segments_clear(a[3:], b[3:], 1.0).any()  # 0.5 above the top; across the polygon


def _cluttered(seed: int) -> Problem:
    rng = np.random.default_rng(seed)
    obs = []
    for _ in range(40):
        d = rng.uniform(1, 6)
        c = rng.uniform(0, 40, size=2)
        ang = np.sort(rng.uniform(0, 2 * np.pi, int(rng.integers(3, 8))))
        obs.append(Polygon(c + d / 2 * np.stack([np.cos(ang), np.sin(ang)], axis=1)))
    obs.append(Polygon(np.array([[2, 2], [30, 2], [30, 3], [2, 3]])))  # one long thin obstacle
    for _ in range(5):
        obs.append(Circle(tuple(rng.uniform(0, 40, size=2)), float(rng.uniform(0.5, 3))))
    return Problem(40, 40, tuple(obs), 1.0, 0.1, np.zeros((0, 2)), np.zeros((0, 2)))


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 2**31), st.sampled_from([0.0, 0.3, 1.1, 2.5]))
def test_indexed_kernels_match_the_dense_ones_in_clutter(seed, clearance):
    """Many obstacles: the indexed boolean tests give the exact kernels' answers, for
    short and long segments, points and points on obstacle corners and box sides."""
    import planner.geometry as geometry

    geometry._DENSE_PAIRS, saved = 0, geometry._DENSE_PAIRS  # always through the index
    try:
        _indexed_vs_dense(seed, clearance)
    finally:
        geometry._DENSE_PAIRS = saved


def _indexed_vs_dense(seed, clearance):
    from planner.geometry import points_in_polygon

    rng = np.random.default_rng(seed)
    p = _cluttered(seed % 7)
    env = p.env
    a = rng.uniform(-1, 41, size=(400, 2))
    b = a + rng.normal(0, 1, size=(400, 1)) * rng.choice([0.5, 4.0, 30.0], size=(400, 1)) * rng.normal(0, 1, (400, 2))
    assert np.array_equal(env.segments_clear(a, b, clearance), env.segment_clearance(a, b) >= clearance)
    corners = np.concatenate(env.polygons)
    boxes = env.obstacle_boxes
    on_sides = np.stack([boxes[:, 0], rng.uniform(boxes[:, 1], boxes[:, 3])], axis=1)
    pts = np.vstack([a, corners, on_sides])
    assert np.array_equal(env.points_clear(pts, clearance), env.point_clearance(pts) >= clearance)
    inside = env._inside(pts)
    dense = np.stack([points_in_polygon(pts, poly) for poly in env.polygons], axis=1)
    assert np.array_equal(inside, dense)
