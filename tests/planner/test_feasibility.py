"""Feasibility proofs: free-space components counted, sound at the borderline."""

from __future__ import annotations

import time

import numpy as np
import pytest
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from planner import NoPlanFound, PlannerParams, Polygon, Problem, feasibility, plan
from planner.problem import Circle


def _door(width: float, left_starts: int = 3, left_targets: int = 0) -> Problem:
    """A wall 2 thick at x = 19..21 across a 40 x 40 workspace with a door ``width`` wide at y = 20."""
    lo, hi = 20 - width / 2, 20 + width / 2
    obs = (Polygon([[19, 0], [21, 0], [21, lo], [19, lo]]), Polygon([[19, hi], [21, hi], [21, 40], [19, 40]]))
    left = [[5, 5 + 6 * i] for i in range(6)]
    right = [[35, 5 + 6 * i] for i in range(6)]
    start = left[:left_starts] + right[: 3 - left_starts]
    target = left[3 : 3 + left_targets] + right[3 : 6 - left_targets]
    return Problem(40, 40, obs, 1.0, 0.1, np.array(start, float), np.array(target, float)).validate()


@pytest.mark.parametrize("width", [2.19, 2.2 - 1e-6])
def test_a_door_too_narrow_is_proven_and_named(width):
    proof = feasibility(_door(width))
    assert proof is not None
    assert (proof.starts, proof.targets) == (3, 0)
    assert proof.passage is not None and {proof.passage.a, proof.passage.b} == {0, 1}
    assert proof.passage.width == pytest.approx(width, abs=1e-9)
    assert proof.passage.point == pytest.approx((20, 20), abs=1e-6)
    line = proof.reason
    assert "\n" not in line
    assert line.startswith("no plan exists: the component around (")
    assert "holds 3 starts and 0 targets" in line
    assert "the gap between obstacle 0 and obstacle 1 at (20, 20)" in line
    assert line.endswith("robots need 2.2")
    assert ("is 2.19 wide" if width == 2.19 else "is 2.199999 wide") in line


@pytest.mark.parametrize("width", [2.2 + 1e-6, 2.2 + 1e-9, 2.3, 4.4])
def test_a_door_wide_enough_is_never_called_unsolvable(width):
    assert feasibility(_door(width)) is None


def test_equal_counts_on_each_side_prove_nothing():
    # one start and one target on the left, two of each on the right
    assert feasibility(_door(2.19, left_starts=1, left_targets=1)) is None


def test_a_borderline_door_is_planned_through():
    """2.2 + 1e-6 wide: solvable, and the planner finds the plan (negative control of the proof)."""
    lo, hi = 20 - (1.1 + 5e-7), 20 + (1.1 + 5e-7)
    obs = (Polygon([[19, 0], [21, 0], [21, lo], [19, lo]]), Polygon([[19, hi], [21, hi], [21, 40], [19, 40]]))
    p = Problem(40, 40, obs, 1.0, 0.1, np.array([[5.0, 20.0]]), np.array([[35.0, 20.0]])).validate()
    assert feasibility(p) is None
    result, stats = plan(p, PlannerParams(time_limit=20), np.random.default_rng(0))
    assert stats.found and stats.extra["feasible"] is True


def _pocket(starts_in: int, targets_in: int, opening: float = 2.0) -> Problem:
    """A 12 x 12 room in the corner, its opening ``opening`` wide at x = 5..5+opening, y = 12..14."""
    obs = (Polygon([[12, 0], [14, 0], [14, 14], [12, 14]]),
           Polygon([[0, 12], [5, 12], [5, 14], [0, 14]]),
           Polygon([[5 + opening, 12], [14, 12], [14, 14], [5 + opening, 14]]))
    room = [[2.5, 2.5], [2.5, 6], [2.5, 9.5], [6, 2.5], [6, 6], [6, 9.5], [9.5, 2.5], [9.5, 6]]
    out = [[20 + 3.5 * (i % 5), 20 + 3.5 * (i // 5)] for i in range(10)]
    start = room[:starts_in] + out[: 8 - starts_in]
    target = room[8 - targets_in :] + out[2 : 10 - targets_in]
    return Problem(40, 40, obs, 1.0, 0.1, np.array(start, float), np.array(target, float)).validate()


def test_a_pocket_with_more_starts_than_targets_is_proven_fast():
    p = _pocket(5, 3)
    t0 = time.perf_counter()
    proof = feasibility(p)
    assert time.perf_counter() - t0 < 1.0
    assert proof is not None and (proof.starts, proof.targets) == (5, 3)
    assert proof.passage is not None and {proof.passage.a, proof.passage.b} == {1, 2}
    assert proof.passage.width == pytest.approx(2.0)
    assert 0 < proof.point[0] < 12 and 0 < proof.point[1] < 12


def test_plan_refuses_an_unsolvable_problem_at_once_with_the_reason_in_its_stats():
    p = _pocket(5, 3)
    t0 = time.perf_counter()
    with pytest.raises(NoPlanFound) as info:
        plan(p, PlannerParams(time_limit=30), np.random.default_rng(0))
    assert time.perf_counter() - t0 < 1.0
    assert str(info.value).startswith("no plan exists: the component around")
    d = info.value.stats.to_dict()
    assert d["feasible"] is False and d["infeasible_reason"] == str(info.value)


def test_pocket_with_matching_counts_and_a_wide_opening_is_not_proven():
    assert feasibility(_pocket(4, 4)) is None
    assert feasibility(_pocket(5, 3, opening=2.3)) is None


def test_circles_closing_a_gap():
    # the wall's opening (y = 14..26) is filled by two circles 2.19 apart
    obs = (Polygon([[19, 0], [21, 0], [21, 14], [19, 14]]), Polygon([[19, 26], [21, 26], [21, 40], [19, 40]]),
           Circle((20, 17), 3.0), Circle((20, 24.095), 1.905))
    p = Problem(40, 40, obs, 1.0, 0.1, np.array([[5.0, 5.0]]), np.array([[35.0, 5.0]])).validate()
    proof = feasibility(p)
    assert proof is not None and (proof.starts, proof.targets) == (1, 0)
    assert proof.passage is not None and {proof.passage.a, proof.passage.b} == {2, 3}
    assert proof.passage.width == pytest.approx(2.19)
    assert proof.passage.point == pytest.approx((20, 21.095))


# -- soundness against an independent grid flood fill --------------------------------


def _grid_components(problem: Problem, step: float):
    """Components of a fine grid of clear points joined by clear segments: every grid
    connection is a real path, so grid-connected points are truly connected."""
    xs = np.arange(problem.clearance, problem.width - problem.clearance + 1e-9, step)
    ys = np.arange(problem.clearance, problem.height - problem.clearance + 1e-9, step)
    gx, gy = np.meshgrid(xs, ys, indexing="ij")
    pts = np.stack([gx.ravel(), gy.ravel()], axis=1)
    ok = problem.env.points_clear(pts, problem.clearance)
    idx = np.arange(len(pts)).reshape(len(xs), len(ys))
    rows, cols = [], []
    for a, b in ((idx[:-1, :], idx[1:, :]), (idx[:, :-1], idx[:, 1:])):
        a, b = a.ravel(), b.ravel()
        both = ok[a] & ok[b]
        a, b = a[both], b[both]
        clear = problem.env.segments_clear(pts[a], pts[b], problem.clearance)
        rows.append(a[clear])
        cols.append(b[clear])
    r, c = np.concatenate(rows), np.concatenate(cols)
    g = coo_matrix((np.ones(len(r)), (r, c)), shape=(len(pts), len(pts)))
    _, label = connected_components(g, directed=False)
    return pts, ok, label


def _grid_label(problem, pts, ok, label, q):
    """Label of a clear grid point joined to ``q`` by a clear segment, or -1."""
    d = np.linalg.norm(pts - q, axis=1)
    near = np.flatnonzero(ok & (d < 1.0))
    near = near[np.argsort(d[near])]
    for j in near:
        if problem.env.segments_clear(q[None], pts[j][None], problem.clearance)[0]:
            return int(label[j])
    return -1


def _counts_disagree_on_grid(problem: Problem, step: float = 0.25) -> bool:
    """Whether the grid's connectivity *shows* that start and target counts can match.

    Grid components under-approximate the true ones; when every start and
    target reaches a grid component and those components' counts all
    agree, a proof of the contrary is wrong."""
    pts, ok, label = _grid_components(problem, step)
    ls = [_grid_label(problem, pts, ok, label, q) for q in problem.start]
    lt = [_grid_label(problem, pts, ok, label, q) for q in problem.target]
    if -1 in ls or -1 in lt:
        return True  # the grid cannot tell
    return sorted(ls) != sorted(lt)


@pytest.mark.parametrize("seed", range(6))
def test_proofs_on_random_cluttered_worlds_agree_with_a_grid_flood_fill(seed):
    rng = np.random.default_rng(seed)
    proven = 0
    for _ in range(6):
        obs = []
        for _ in range(int(rng.integers(8, 20))):
            d = rng.uniform(3, 7)
            c = rng.uniform(d / 2, 20 - d / 2, size=2)
            ang = np.sort(rng.uniform(0, 2 * np.pi, int(rng.integers(3, 7))))
            obs.append(Polygon(c + d / 2 * np.stack([np.cos(ang), np.sin(ang)], axis=1)))
        shell = Problem(20, 20, tuple(obs), 0.5, 0.05, np.zeros((0, 2)), np.zeros((0, 2)))
        from planner.geometry import greedy_separated

        cand = rng.uniform(0.55, 19.45, size=(4000, 2))
        cand = cand[shell.env.points_clear(cand, shell.clearance)]
        pts = cand[greedy_separated(cand, shell.separation, None, 8)]
        if len(pts) < 8:
            continue
        p = Problem(20, 20, tuple(obs), 0.5, 0.05, pts[:4], pts[4:]).validate()
        proof = feasibility(p)
        if proof is not None:
            proven += 1
            assert _counts_disagree_on_grid(p), proof.reason


def test_the_grid_check_catches_a_wrong_proof():
    """Negative control: on a solvable door the grid shows the counts can match."""
    assert not _counts_disagree_on_grid(_door(2.6), step=0.2)
    assert _counts_disagree_on_grid(_door(2.0), step=0.2)
