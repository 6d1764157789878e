"""Strokes: robots spread along drawn polylines by arc length.

Every robot must lie on a stroke, the count must be the one asked for, a
shape must keep the separation, junctions must hold one robot, crossing
strokes must not crowd, and bad drawings must be refused with the stroke
named.  The paper's letters, now stroke data too, must keep the placements
they had when each letter was hand-coded (pinned by a weighted checksum of
every count from 4 to 40).
"""

from __future__ import annotations

import time

import numpy as np
import pytest
from scipy.spatial.distance import pdist

from planner.formations import FORMATIONS, formation_shape
from planner.strokes import (
    Arc,
    check_polylines,
    count_at_spacing,
    drawing,
    stroke_points,
    strokes_shape,
)


def _on_drawing(points, strokes) -> np.ndarray:
    """Distance from each point to the nearest stroke."""
    return np.min([s.distance(points) for s in strokes], axis=0)


# ----------------------------------------------------------------------------
# the letters keep their placements

# sum over m = 4..40 of m * sum_i (i + 1) (x_i + sqrt(2) y_i) of the letter's
# shape (side 12, separation 2.1), computed with the hand-coded letters that
# the stroke data replaced, except A of 9 and phi of 8 robots, where a stroke
# that had no robot now has one (the A's crossbar, the phi's stem)
_LETTER_CHECKSUMS = {
    "line": 3884107.928000008,
    "A": 1030932.0610710441,
    "C": -3688036.826354583,
    "M": 3115854.233525763,
    "N": 2241902.454634577,
    "lambda": -4653323.612541894,
    "phi": 384350.66205102066,
}


@pytest.mark.parametrize("name", sorted(_LETTER_CHECKSUMS))
def test_letters_keep_their_placements(name):
    total = 0.0
    for m in range(4, 41):
        p = formation_shape(name, m, 12.0, 2.1, np.random.default_rng(0))
        total += m * np.sum(np.arange(1, m + 1) * (p[:, 0] + np.sqrt(2) * p[:, 1]))
    assert total == pytest.approx(_LETTER_CHECKSUMS[name], rel=1e-12, abs=1e-6)


def test_checksum_sees_a_moved_robot():
    """Negative control: one robot moved by 1e-4 changes the checksum."""
    p = formation_shape("A", 10, 12.0, 2.1, np.random.default_rng(0))
    q = p.copy()
    q[3, 1] += 1e-4
    w = np.arange(1, 11)
    assert np.sum(w * (p[:, 0] + np.sqrt(2) * p[:, 1])) != pytest.approx(
        np.sum(w * (q[:, 0] + np.sqrt(2) * q[:, 1])), rel=1e-12, abs=1e-6)


def test_ring_is_a_circle_of_even_spacing():
    for m in (3, 8, 31):
        p = formation_shape("ring", m, 20.0, 2.1, np.random.default_rng(0))
        # fit a circle: |p|^2 = 2 c.p + k, linear in (c, k)
        sol, *_ = np.linalg.lstsq(np.column_stack([2 * p, np.ones(m)]), (p**2).sum(1), rcond=None)
        p = p - sol[:2]
        r = np.linalg.norm(p, axis=1)
        np.testing.assert_allclose(r, r.mean(), rtol=1e-9)
        ang = np.sort(np.arctan2(p[:, 1], p[:, 0]))
        gaps = np.diff(np.r_[ang, ang[0] + 2 * np.pi])
        np.testing.assert_allclose(gaps, 2 * np.pi / m, atol=1e-9)
    assert "ring" in FORMATIONS


# ----------------------------------------------------------------------------
# sampling along strokes

_SQUARE = [[(0, 0), (1, 0), (1, 1), (0, 1), (0, 0)]]  # closed
_T = [[(0, 1), (1, 1)], [(0.5, 1), (0.5, 0)]]  # a T: the stem starts on the bar
_X = [[(0, 0), (1, 1)], [(0, 1), (1, 0)]]  # two strokes crossing in the middle
_ZIGZAG = [[(0, 0), (0.2, 1), (0.4, 0), (0.6, 1), (0.8, 0), (1, 1)]]


@pytest.mark.parametrize("lines", [_SQUARE, _T, _X, _ZIGZAG], ids=["square", "T", "X", "zigzag"])
@pytest.mark.parametrize("m", [2, 3, 5, 12, 40])
def test_points_lie_on_the_strokes(lines, m):
    st = drawing([np.asarray(p, float) for p in lines])
    pts = stroke_points(st, m)
    assert pts.shape == (m, 2)
    assert _on_drawing(pts, st).max() <= 1e-9
    assert len(np.unique(np.round(pts, 9), axis=0)) == m  # no two on one spot


def test_closed_square_is_evenly_spaced_from_its_corners():
    st = drawing([np.asarray(_SQUARE[0], float)])
    assert len(st) == 4  # opened at a corner and cut at the other three
    pts = stroke_points(st, 16)
    # perimeter 4, 16 robots: every robot 0.25 from its neighbours along it, one on each corner
    d = np.sort(np.linalg.norm(pts[:, None] - pts[None], axis=2), axis=1)[:, 1]
    np.testing.assert_allclose(d, 0.25, atol=1e-9)
    for corner in _SQUARE[0][:4]:
        assert np.sum(np.linalg.norm(pts - corner, axis=1) < 1e-9) == 1


def test_smooth_closed_outline_is_one_closed_stroke():
    th = np.linspace(0, 2 * np.pi, 73)
    circle = np.stack([0.5 + 0.5 * np.cos(th), 0.5 + 0.5 * np.sin(th)], axis=1)
    circle[-1] = circle[0]
    st = drawing([circle])
    assert len(st) == 1 and st[0].closed
    pts = stroke_points(st, 12)
    d = np.sort(np.linalg.norm(pts[:, None] - pts[None], axis=2), axis=1)[:, 1]
    np.testing.assert_allclose(d, d.mean(), rtol=1e-3)


def test_corners_hold_a_robot():
    """An open zigzag is cut at its sharp corners: every corner and end holds a robot."""
    st = drawing([np.asarray(_ZIGZAG[0], float)])
    assert len(st) == 5
    pts = stroke_points(st, 21)
    for corner in _ZIGZAG[0]:
        assert np.min(np.linalg.norm(pts - corner, axis=1)) <= 1e-9


def test_junction_holds_one_robot():
    st = drawing([np.asarray(p, float) for p in _T])
    assert st[0].start_free and st[0].end_free
    assert not st[1].start_free and st[1].end_free  # the stem's top lies on the bar
    for m in (5, 9, 17):
        pts = stroke_points(st, m)
        assert np.sum(np.linalg.norm(pts - [0.5, 1.0], axis=1) < 1e-9) <= 1
        assert pdist(pts).min() > 0.3 / m


def test_crossing_strokes_do_not_crowd():
    """Where strokes cross, one of two robots that would nearly meet gives way."""
    st = drawing([np.asarray(p, float) for p in _X])
    for m in (4, 6, 9, 15, 30):
        pts = stroke_points(st, m)
        assert len(pts) == m
        spacing = 2 * np.sqrt(2) / m  # total length over the count
        assert pdist(pts).min() >= 0.5 * spacing


def test_gap_avoids_enlargement_where_the_strokes_have_room():
    """Asked for robots 1.02 separations apart, the strokes need no enlargement."""
    st = drawing([np.asarray(p, float) for p in _X + _T])
    side, sep = 30.0, 2.1
    m = count_at_spacing(st, 1.5 * sep / side)  # the default count's spacing
    p = strokes_shape(st, m, side, sep)
    assert pdist(p).min() >= sep
    assert float(np.ptp(p, axis=0).max()) == pytest.approx(side, rel=1e-9)


@pytest.mark.parametrize("m", [10, 60, 150])
def test_shape_is_separated_and_sized(m):
    st = drawing([np.asarray(p, float) for p in _ZIGZAG + _X])
    for sep in (0.5, 2.1):
        p = strokes_shape(st, m, 12.0, sep)
        assert p.shape == (m, 2)
        assert pdist(p).min() >= sep
        lo, hi = p.min(axis=0), p.max(axis=0)
        np.testing.assert_allclose((lo + hi) / 2, 0.0, atol=1e-9)
        assert float((hi - lo).max()) >= 12.0 * (1 - 1e-12)


def test_scribble_is_bounded_in_time():
    """64 random strokes crossing everywhere: still exactly m robots, in bounded time."""
    rng = np.random.default_rng(0)
    st = drawing(check_polylines([rng.uniform(0, 1, (16, 2)) for _ in range(64)]))
    t0 = time.perf_counter()
    p = strokes_shape(st, 300, 60.0, 2.1)
    assert time.perf_counter() - t0 < 20.0
    assert p.shape == (300, 2) and pdist(p).min() >= 2.1


def test_arcs_and_polylines_mix():
    st = drawing([Arc(0.5, 0.5, 0.5, 0.0, np.pi), np.array([(0.0, 0.5), (1.0, 0.5)])])
    pts = stroke_points(st, 11)
    assert _on_drawing(pts, st).max() <= 1e-9
    # the diameter's ends lie on the half circle: each holds at most one robot
    for end in ((0.0, 0.5), (1.0, 0.5)):
        assert np.sum(np.linalg.norm(pts - end, axis=1) < 1e-9) <= 1


def test_a_dot_holds_one_robot():
    st = drawing([np.array([(0.0, 0.0), (1.0, 0.0)]), np.array([(0.5, 0.8), (0.5, 0.8)])])
    pts = stroke_points(st, 6)
    assert np.sum(np.linalg.norm(pts - (0.5, 0.8), axis=1) < 1e-9) == 1


# ----------------------------------------------------------------------------
# bad drawings


@pytest.mark.parametrize(
    "lines, says",
    [
        ([], "1 to 64 strokes"),
        ([[(0, 0), (1, 1)]] * 65, "1 to 64 strokes"),
        ([[(0, 0)]], "strokes[0]: must be a list of 2 to 512"),
        ([[(0, 0), (1, 1)], [(0.5, 0.5)] * 513], "strokes[1]: must be a list of 2 to 512"),
        ([[(0, 0), (1, float("nan"))]], "strokes[0]: holds a non-finite"),
        ([[(0, 0), (0, 0)], [(1, 1), (1, 1)]], "zero length"),
        ([[(0, 0), (1, 1)] * 200] * 6, "more than 1024 points"),
        ([["a", "b"]], "strokes[0]"),
    ],
)
def test_bad_drawings_are_refused(lines, says):
    with pytest.raises(ValueError) as info:
        check_polylines(lines)
    assert says in str(info.value)


def test_stroke_points_refuses_nonsense():
    st = drawing([np.array([(0.0, 0.0), (1.0, 0.0)])])
    with pytest.raises(ValueError):
        stroke_points(st, 0)
    with pytest.raises(ValueError):
        stroke_points((), 3)
