"""Pebble graphs: the exact edge planner and the unlabeled pebble solver."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from planner.geometry import point_segment_distance
from planner.pebble import PebbleGraph, build_pebble_graph, edge_mask, sample_free_points, solve_pebbles
from planner.problem import Circle, Polygon, Problem


def _replay(graph: PebbleGraph, start, moves):
    """Apply moves, checking each goes along an edge onto a free vertex."""
    occ = set(int(v) for v in start)
    for u, w in moves:
        assert u in occ, f"move from empty vertex {u}"
        assert w not in occ, f"move onto occupied vertex {w}"
        assert w in set(graph.neighbors[u].tolist()), f"({u}, {w}) is not an edge"
        occ.remove(u)
        occ.add(w)
    return occ


@st.composite
def graph_and_placements(draw):
    n = draw(st.integers(2, 24))
    p = draw(st.floats(0.05, 0.6))
    seed = draw(st.integers(0, 2**31))
    rng = np.random.default_rng(seed)
    iu, ju = np.triu_indices(n, 1)
    keep = rng.random(len(iu)) < p
    edges = np.stack([iu[keep], ju[keep]], axis=1)
    k = draw(st.integers(1, n))
    s = rng.choice(n, k, replace=False)
    t = rng.choice(n, k, replace=False)
    return PebbleGraph.from_edges(np.zeros((n, 2)), edges), s, t


@settings(max_examples=400, deadline=None)
@given(graph_and_placements())
def test_solver_complete_and_valid(case):
    graph, s, t = case
    if graph.signature(s) != graph.signature(t):
        with pytest.raises(ValueError):
            solve_pebbles(graph, s, t)
        return
    moves = solve_pebbles(graph, s, t)
    assert _replay(graph, s, moves) == set(int(v) for v in t)
    assert len(moves) <= graph.n * graph.n  # polynomial: O(n^2) moves


def test_solver_reaches_target_whenever_signatures_match():
    """Exhaustive on a small path graph: every equal-signature pair is solved."""
    import itertools

    n = 6
    edges = [(i, i + 1) for i in range(n - 1)]
    graph = PebbleGraph.from_edges(np.zeros((n, 2)), edges)
    for k in range(1, n + 1):
        for s in itertools.combinations(range(n), k):
            for t in itertools.combinations(range(n), k):
                assert _replay(graph, s, solve_pebbles(graph, s, t)) == set(t)


def test_replay_catches_bad_moves():
    """Negative control: the checker used above rejects an illegal move."""
    graph = PebbleGraph.from_edges(np.zeros((3, 2)), [(0, 1)])
    with pytest.raises(AssertionError):
        _replay(graph, [0], [(0, 2)])  # not an edge
    with pytest.raises(AssertionError):
        _replay(graph, [0, 1], [(0, 1)])  # onto an occupied vertex


def test_signature_counts_pebbles_per_component():
    graph = PebbleGraph.from_edges(np.zeros((5, 2)), [(0, 1), (1, 2), (3, 4)])
    assert graph.n_components == 2
    assert graph.signature([0, 3]) == (1, 1)
    assert graph.signature([0, 2]) == (2, 0)


def _problem():
    obstacles = (
        Polygon(np.array([[12, 10], [20, 10], [20, 13], [15, 13], [15, 20], [12, 20]])),  # an L
        Circle((28, 28), 3.0),
    )
    return Problem(40, 40, obstacles, 1.0, 0.1, np.zeros((0, 2)), np.zeros((0, 2)))


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 2**31))
def test_edge_planner_matches_dense_sampling(seed):
    """An edge exists exactly when a densely sampled robot stays clear.

    Sampling 2000 points can only miss a violation by the sampling step, so
    the comparison allows that slack in the direction sampling is blind to.
    """
    rng = np.random.default_rng(seed)
    p = _problem()
    v = sample_free_points(p, 12, rng)
    iu, ju = np.triu_indices(len(v), 1)
    pairs = np.stack([iu, ju], axis=1)
    ok = edge_mask(p, v, pairs)
    theta = np.linspace(0, 1, 2000)
    for (i, j), e in zip(pairs, ok):
        pts = v[i] + theta[:, None] * (v[j] - v[i])
        step = np.linalg.norm(v[j] - v[i]) / 1999
        clear = p.env.point_clearance(pts).min()
        others = np.delete(v, [i, j], axis=0)
        sep = np.min(np.linalg.norm(pts[:, None] - others[None], axis=2)) if len(others) else np.inf
        sampled_ok = clear >= p.clearance and sep >= p.separation
        if e:
            assert sampled_ok
        elif sampled_ok:  # the violation must hide between samples
            assert clear < p.clearance + step or sep < p.separation + step


def test_pebble_graph_edges_avoid_every_other_vertex():
    rng = np.random.default_rng(3)
    p = _problem()
    g = build_pebble_graph(p, sample_free_points(p, 30, rng))
    for u in range(g.n):
        for w in g.neighbors[u]:
            others = np.delete(g.vertices, [u, w], axis=0)
            d = point_segment_distance(others, g.vertices[u], g.vertices[w])
            assert d.min() >= p.separation


def test_sample_free_points_separated_and_clear():
    rng = np.random.default_rng(0)
    p = _problem()
    v = sample_free_points(p, 80, rng, bridge_fraction=0.3)
    assert len(v) == 80
    assert p.env.point_clearance(v).min() >= p.clearance
    d = np.linalg.norm(v[:, None] - v[None], axis=2) + np.eye(len(v)) * 1e9
    assert d.min() >= p.separation
