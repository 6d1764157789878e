"""Narrow passages (planner.passages): the near-pair search misses no pair of features
closer than the reach, so the passages equal those of the all-pairs computation."""

from __future__ import annotations

import numpy as np
import pytest

from planner import Circle, Polygon, Problem
from planner.geometry import segment_segment_distance
from planner.passages import _pairs_within, narrow_passages


def _random_segments(rng, n):
    a = rng.uniform(0, 50, (n, 2))
    b = a + rng.normal(0, rng.choice([0.5, 3.0, 20.0]), (n, 2))
    return a, b


@pytest.mark.parametrize("seed", range(8))
def test_near_pairs_hold_every_close_pair(seed):
    rng = np.random.default_rng(seed)
    a, b = _random_segments(rng, 120)
    reach = float(rng.uniform(0.5, 6.0))
    i, j = np.triu_indices(len(a), 1)
    close = segment_segment_distance(a[i], b[i], a[j], b[j]) < reach
    want = set(zip(i[close].tolist(), j[close].tolist()))
    gi, gj = _pairs_within(a, b, reach)
    got = set(zip(gi.tolist(), gj.tolist()))
    assert want <= got  # every close pair is a candidate
    assert (gi < gj).all() and len(got) == len(gi)  # once each, ordered


def test_long_segments_meeting_at_their_ends_are_found():
    """Centres 100 apart, ends 0.5 apart: a search by segment centres alone would miss them
    (the control shows such a search does)."""
    from scipy.spatial import cKDTree

    a = np.array([[0.0, 0.0], [100.5, 0.0], [40.0, 30.0]])
    b = np.array([[100.0, 0.0], [200.0, 0.0], [41.0, 30.0]])
    gi, gj = _pairs_within(a, b, 1.0)
    assert (0, 1) in set(zip(gi.tolist(), gj.tolist()))  # candidates: a superset of the close pairs
    naive = cKDTree(0.5 * (a + b)).query_pairs(1.0)
    assert (0, 1) not in naive


def _brute_passages(problem):
    """narrow_passages with every feature pair, as it was computed before the near-pair search."""
    import planner.passages as ps

    real = ps._pairs_within
    try:
        ps._pairs_within = lambda a, b, reach: np.triu_indices(len(a), 1)
        return narrow_passages(problem)
    finally:
        ps._pairs_within = real


@pytest.mark.parametrize("seed", range(10))
def test_passages_equal_the_all_pairs_ones(seed):
    rng = np.random.default_rng(100 + seed)
    obs = []
    for _ in range(int(rng.integers(2, 25))):
        c = rng.uniform(0, 60, 2)
        if rng.random() < 0.3:
            obs.append(Circle(tuple(c), float(rng.uniform(0.5, 3))))
        else:
            k = int(rng.integers(3, 7))
            ang = np.sort(rng.uniform(0, 2 * np.pi, k))
            obs.append(Polygon(c + rng.uniform(1, 5) * np.stack([np.cos(ang), np.sin(ang)], 1)))
    p = Problem(60.0, 60.0, tuple(obs), 1.0, 0.1, np.zeros((0, 2)), np.zeros((0, 2)))
    got, want = narrow_passages(p), _brute_passages(p)
    assert len(got) == len(want)
    for (m1, a1), (m2, a2) in zip(got, want):
        assert np.array_equal(m1, m2) and np.array_equal(a1, a2)
