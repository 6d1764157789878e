"""The near-edge clearance details (many queries on many edges) equal the dense pass."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import planner.geometry as geometry
from planner.problem import Circle, Polygon, Problem

KERNELS = (geometry.point_segment_distance, geometry._crossing)


def _maze_world(seed: int) -> Problem:
    """Random blocked cells of a 30 x 30 grid (cell 2) as squares, a few circles and one
    concave polygon: many small obstacles, shared edges, touching corners."""
    rng = np.random.default_rng(seed)
    obstacles: list = []
    for i, j in np.argwhere(rng.random((30, 30)) < 0.3):
        x, y = 2.0 * i, 2.0 * j
        obstacles.append(Polygon(np.array([[x, y], [x + 2, y], [x + 2, y + 2], [x, y + 2]])))
    obstacles.append(Polygon(np.array([[5, 5], [15, 5], [15, 8], [8, 8], [8, 15], [5, 15]], float)))
    obstacles += [Circle((20.0, 40.0), 1.5), Circle((50.0, 10.0), 2.5)]
    return Problem(60, 60, tuple(obstacles), 1.0, 0.1, np.zeros((0, 2)), np.zeros((0, 2)))


def _both(env, fn, *args):
    old = geometry._NEAR_PAIRS
    try:
        geometry._NEAR_PAIRS = 1 << 62  # dense
        dense = getattr(env, fn)(*args)
        geometry._NEAR_PAIRS = 0  # near edges
        near = getattr(env, fn)(*args)
    finally:
        geometry._NEAR_PAIRS = old
    return dense, near


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 2**31), st.sampled_from([0.0, 0.5, 3.0, 15.0, 80.0]))
def test_near_details_equal_dense(seed, spread):
    rng = np.random.default_rng(seed)
    env = _maze_world(seed % 7).env
    a = rng.uniform(-1, 61, size=(400, 2))
    a[:40] = np.round(a[:40] / 2) * 2  # on cell corners and edges: ties and touching
    b = a + rng.normal(0, spread, size=a.shape)
    (d1, w1), (d2, w2) = _both(env, "segment_clearance_detail", a, b)
    assert np.array_equal(d1, d2) and np.array_equal(w1, w2)
    (p1, v1), (p2, v2) = _both(env, "point_clearance_detail", a)
    assert np.array_equal(p1, p2) and np.array_equal(v1, v2)


def test_near_details_see_a_polygon_from_inside_and_far_away():
    """Points deep inside an obstacle are at 0; a query far from every edge still gets
    its nearest one (the radius grows until it is found)."""
    square = Polygon(np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float))
    big = Polygon(np.array([[400, 400], [600, 400], [600, 600], [400, 600]], float))
    env = Problem(2000, 2000, (square, big), 1.0, 0.1, np.zeros((0, 2)), np.zeros((0, 2))).env
    a = np.array([[500.0, 500.0], [300.0, 300.0], [0.5, 0.5]])
    (d1, w1), (d2, w2) = _both(env, "point_clearance_detail", a)
    assert np.array_equal(d1, d2) and np.array_equal(w1, w2)
    assert d2[0] == 0.0 and w2[0] == 1 and d2[2] == 0.0 and w2[2] == 0
    assert d2[1] == pytest.approx(np.hypot(100.0, 100.0))


def test_negative_control_a_missing_edge_changes_the_answer():
    """The comparison can fail: dropping the pairs of one polygon from the near pass
    moves some query's minimum."""
    from planner import nearest

    env = _maze_world(1).env
    rng = np.random.default_rng(0)
    a = rng.uniform(0, 60, size=(300, 2))
    d_ok, _ = nearest.nearest_polygon(env, a, a, True, KERNELS)
    real = env._pairs_near

    def lossy(name, boxes, qa, qb, r):
        qi, ei = real(name, boxes, qa, qb, r)
        keep = env.edges[2][ei] != 0
        return qi[keep], ei[keep]

    object.__setattr__(env, "_pairs_near", lossy)  # the environment is a frozen dataclass
    try:
        d_bad, _ = nearest.nearest_polygon(env, a, a, True, KERNELS)
    finally:
        object.__delattr__(env, "_pairs_near")
    assert not np.array_equal(d_ok, d_bad)
