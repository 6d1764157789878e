"""Many segment queries against the box index are met in groups: same answers, bounded memory."""

import numpy as np

import planner.geometry as geometry
from planner.problem import Polygon


def _world(rng):
    polys = [Polygon(np.array([[x, y], [x + 1, y], [x + 1, y + 1], [x, y + 1]], float))
             for x, y in rng.uniform(1, 90, (300, 2))]
    return polys


def test_grouped_queries_answer_as_one_call(monkeypatch):
    rng = np.random.default_rng(1)
    polys = _world(rng)
    a = rng.uniform(0, 100, (20000, 2))
    b = a + rng.normal(0, 3, a.shape)
    whole = geometry.Environment.build(100, 100, polys).segments_clear(a, b, 0.6)
    monkeypatch.setattr(geometry, "_PIECES_PER_CALL", 5000)
    grouped = geometry.Environment.build(100, 100, polys).segments_clear(a, b, 0.6)
    assert 0.1 < whole.mean() < 0.9  # both answers occur
    assert np.array_equal(whole, grouped)


def test_the_grouping_is_used(monkeypatch):
    # negative control for the test above: with a small group size the recursion runs
    rng = np.random.default_rng(2)
    env = geometry.Environment.build(100, 100, _world(rng))
    calls = []
    real = geometry.Environment._pairs_near
    monkeypatch.setattr(geometry, "_PIECES_PER_CALL", 2000)
    monkeypatch.setattr(geometry.Environment, "_pairs_near",
                        lambda self, *args: calls.append(1) or real(self, *args))
    a = rng.uniform(0, 100, (5000, 2))
    env.segments_clear(a, a + 2.0, 0.6)
    assert len(calls) > 2
