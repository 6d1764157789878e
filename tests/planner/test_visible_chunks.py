"""Straight visibility between placements (planner.visible): chunked, and bounded by a deadline."""

from __future__ import annotations

import time

import numpy as np
import pytest

import planner.visible as visible
from planner import Polygon, Problem


def _walls(m: int) -> Problem:
    rng = np.random.default_rng(0)
    walls = (Polygon(np.array([[9.0, 2.0], [10.0, 2.0], [10.0, 18.0], [9.0, 18.0]])),
             Polygon(np.array([[3.0, 9.0], [7.0, 9.0], [7.0, 10.0], [3.0, 10.0]])))
    pts = rng.uniform(0.5, 19.5, (4 * m, 2))
    shell = Problem(20.0, 20.0, walls, 0.2, 0.05, pts[:1], pts[:1])
    pts = pts[shell.env.points_clear(pts, shell.clearance)][: 2 * m]
    return Problem(20.0, 20.0, walls, 0.2, 0.05, pts[:m], pts[m:])


def test_chunked_visibility_is_the_whole_test(monkeypatch):
    problem = _walls(60)
    whole = visible._visible(problem, problem.start, problem.target)
    assert 0 < whole.sum() < whole.size  # the walls hide some pairs, not all
    monkeypatch.setattr(visible, "_VISIBLE_CHUNK", 7)  # chunks of one row, some rows split never
    assert np.array_equal(visible._visible(problem, problem.start, problem.target), whole)
    aa = np.repeat(problem.start, len(problem.target), axis=0)
    bb = np.tile(problem.target, (len(problem.start), 1))
    direct = problem.env.segment_clearance(aa, bb) >= problem.clearance
    assert np.array_equal(whole.ravel(), direct)


def test_straight_lengths_stop_at_the_deadline(monkeypatch):
    """900 robots to 900 targets among walls tested 810 000 segments in one call: 2.7 GB and
    14 s past a 30 s limit.  Now chunks, and a deadline that has passed stops them (nothing
    is remembered, so a later call with time left computes them)."""
    problem = _walls(60)
    monkeypatch.setattr(visible, "_VISIBLE_CHUNK", 60)
    with pytest.raises(visible.Late):
        visible.straight_lengths(problem, problem.start, problem.target, deadline=time.perf_counter() - 1.0)
    assert not problem.__dict__.get("_straight_lengths")
    got = visible.straight_lengths(problem, problem.start, problem.target, deadline=time.perf_counter() + 60)
    assert np.isinf(got).any() and np.isfinite(got).any()
