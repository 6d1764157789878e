"""Scatter: Poisson-disc placements over the free space, checked exactly and independently.

The placements must be exactly ``m``, pairwise at least ``2 r + margin``
apart, clear of walls and obstacles by ``r + margin`` (checked with the
kernels and again by dense boundary sampling), inside the region, and
spread over all of it: near the sampler's maximum every cell of a coarse
grid over the free region has a robot close by.  Too many robots fail with
the field and the maximum, and that maximum is honest: a count a little
below it succeeds.  Negative controls show that each check catches a
placement that breaks it.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from scipy.spatial import cKDTree
from scipy.spatial.distance import pdist

from planner.geometry import Environment
from planner.problem import ProblemError
from planner.scatter import poisson_disc, scatter

W = H = 40.0
SEP, CLEAR = 2.1, 1.1


def _obstacles():
    return [
        SimpleNamespace(center=(12.0, 28.0), radius=5.0),
        SimpleNamespace(vertices=np.array([[24, 6], [34, 6], [34, 16], [29, 10], [24, 16]], float)),  # non-convex
    ]


ENV = Environment.build(W, H, _obstacles())


def _brute_clearance(pts):
    """Clearance by dense boundary sampling (at most 0.01 above the truth) and exact walls."""
    best = np.minimum(pts, [W, H] - pts).min(axis=1)
    for ob in _obstacles():
        if hasattr(ob, "vertices"):
            v = ob.vertices
            samples = np.concatenate([a + np.linspace(0, 1, 2000)[:, None] * (b - a)
                                      for a, b in zip(v, np.roll(v, -1, axis=0))])
            d = cKDTree(samples).query(pts)[0]
            inside = np.array([_winding(p, v) for p in pts])
            best = np.minimum(best, np.where(inside, 0.0, d))
        else:
            best = np.minimum(best, np.linalg.norm(pts - ob.center, axis=1) - ob.radius)
    return best


def _winding(p, poly):
    v = poly - p
    w = np.roll(v, -1, axis=0)
    ang = np.arctan2(v[:, 0] * w[:, 1] - v[:, 1] * w[:, 0], (v * w).sum(1))
    return abs(ang.sum()) > np.pi


def _check(pts, m, region=(0, 0, W, H)):
    assert pts.shape == (m, 2)
    assert pdist(pts).min() >= SEP
    assert ENV.point_clearance(pts).min() >= CLEAR
    assert _brute_clearance(pts).min() >= CLEAR - 0.01
    x0, y0, x1, y1 = region
    assert np.all((pts[:, 0] >= x0) & (pts[:, 0] <= x1) & (pts[:, 1] >= y0) & (pts[:, 1] <= y1))


@pytest.mark.parametrize("m", [2, 20, 80, 150])
def test_scatter_is_separated_and_clear(m):
    _check(scatter(ENV, m, SEP, CLEAR, np.random.default_rng(m)), m)


def test_checks_catch_bad_placements():
    """Negative controls: a robot on another, in an obstacle, outside the region."""
    pts = scatter(ENV, 30, SEP, CLEAR, np.random.default_rng(0))
    close = pts.copy()
    close[1] = close[0] + [SEP * 0.9, 0]
    with pytest.raises(AssertionError):
        _check(close, 30)
    inside = pts.copy()
    inside[2] = [29.0, 8.0]  # in the non-convex polygon's lower part
    with pytest.raises(AssertionError):
        _check(inside, 30)
    notch = pts.copy()
    notch[2] = [29.0, 11.0]  # in the notch: outside the polygon, 1 above its reflex corner
    assert not _winding(notch[2], _obstacles()[1].vertices)
    assert ENV.point_clearance(notch[2:3])[0] < CLEAR  # caught by the clearance, not by chance
    with pytest.raises(AssertionError):
        _check(notch, 30)
    with pytest.raises(AssertionError):
        _check(pts, 30, region=(0, 0, 20, 40))


def test_region_is_respected():
    region = (2.0, 20.0, 38.0, 38.0)
    pts = scatter(ENV, 40, SEP, CLEAR, np.random.default_rng(3), region=region)
    _check(pts, 40, region)


def test_saturated_sample_covers_the_free_space():
    """Near the maximum, every free cell of a 4 x 4 grid has a robot within 2 separations."""
    rng = np.random.default_rng(7)
    full = poisson_disc(ENV, (0, 0, W, H), SEP, CLEAR, rng)
    m = int(0.9 * len(full))
    pts = scatter(ENV, m, SEP, CLEAR, rng)
    _check(pts, m)
    g = np.stack(np.meshgrid(np.arange(1, 40, 2.0), np.arange(1, 40, 2.0)), -1).reshape(-1, 2)
    free = g[ENV.points_clear(g, CLEAR)]
    d, _ = cKDTree(pts).query(free)
    assert d.max() <= 2 * SEP, f"a free point {free[np.argmax(d)]} is {d.max():.2f} from every robot"


def test_sparse_scatter_spreads_over_the_whole_region():
    """Few robots are spread out, not bunched: each quarter of the workspace gets its share."""
    pts = scatter(ENV, 40, SEP, CLEAR, np.random.default_rng(11))
    quarters = np.bincount((pts[:, 0] >= 20).astype(int) * 2 + (pts[:, 1] >= 20).astype(int), minlength=4)
    assert quarters.min() >= 5, quarters
    assert pdist(pts).min() >= 2 * SEP  # the spacing grew to spread them


def test_pockets_cut_off_by_obstacles_get_robots():
    """Two chambers joined by nothing: darts find the second one too."""
    wall = SimpleNamespace(vertices=np.array([[19, 0], [21, 0], [21, 40], [19, 40]], float))
    env = Environment.build(W, H, [wall])
    pts = scatter(env, 60, SEP, CLEAR, np.random.default_rng(2))
    assert env.point_clearance(pts).min() >= CLEAR and pdist(pts).min() >= SEP
    left = (pts[:, 0] < 20).sum()
    assert 20 <= left <= 40


def test_too_many_names_the_field_and_an_honest_maximum():
    rng = np.random.default_rng(0)
    with pytest.raises(ProblemError) as info:
        scatter(ENV, 1000, SEP, CLEAR, rng, field="targets[2]")
    assert info.value.field == "targets[2]"
    reason = info.value.reason
    assert "1000 robots do not fit" in reason and "at most" in reason
    most = int(reason.split("at most ")[1].split()[0])
    assert 150 < most < 1000
    # honest: a count a little below the reported maximum fits
    pts = scatter(ENV, int(0.95 * most), SEP, CLEAR, np.random.default_rng(1))
    _check(pts, int(0.95 * most))


def test_blocked_region_fails():
    with pytest.raises(ProblemError, match="at most 0"):
        scatter(ENV, 5, SEP, CLEAR, np.random.default_rng(0), region=(8.0, 25.0, 14.0, 30.0))  # inside the disc


def test_scatter_is_deterministic_per_seed():
    a = scatter(ENV, 30, SEP, CLEAR, np.random.default_rng(4))
    b = scatter(ENV, 30, SEP, CLEAR, np.random.default_rng(4))
    c = scatter(ENV, 30, SEP, CLEAR, np.random.default_rng(5))
    assert a.tobytes() == b.tobytes() and not np.array_equal(a, c)


def test_poisson_disc_refuses_a_tiny_spacing():
    with pytest.raises(ValueError, match="too fine"):
        poisson_disc(ENV, (0, 0, W, H), 0.01, CLEAR, np.random.default_rng(0))


def test_scatter_keeps_to_the_largest_connected_part():
    """A closed room in the corner is free space no robot outside can reach: a scenario's
    scatter (``part=largest_part``) puts nobody there; without it some land inside."""
    from planner.problem import Polygon, Problem
    from planner.scatter import largest_part

    walls = [Polygon(np.array(v, float)) for v in (
        [[0, 14], [16, 14], [16, 16], [0, 16]],   # the room's top wall
        [[14, 0], [16, 0], [16, 14], [14, 14]],   # its right wall
    )]
    shell = Problem(W, H, tuple(walls), 1.0, 0.1, np.zeros((0, 2)), np.zeros((0, 2)))
    part = largest_part(shell)
    assert part is not None
    def in_room(p):
        return (p[:, 0] < 14) & (p[:, 1] < 14)
    free = scatter(shell.env, 60, SEP, CLEAR, np.random.default_rng(0))
    assert in_room(free).any()  # the control: the pocket is free space
    kept = scatter(shell.env, 60, SEP, CLEAR, np.random.default_rng(0), part=part)
    assert not in_room(kept).any()
    assert pdist(kept).min() >= SEP and shell.env.point_clearance(kept).min() >= CLEAR
    open_world = Problem(W, H, tuple(walls[:1]), 1.0, 0.1, np.zeros((0, 2)), np.zeros((0, 2)))
    assert largest_part(open_world) is None  # one component: nothing to restrict


def test_scatter_stops_at_its_deadline_and_draws_the_same_without_one():
    """A deadline already past raises Late before the sample grows; a far one changes nothing."""
    import time

    import numpy as np
    import pytest

    from planner.geometry import Environment
    from planner.scatter import scatter
    from planner.visible import Late

    env = Environment.build(40.0, 40.0, ())
    with pytest.raises(Late):
        scatter(env, 50, 2.1, 1.1, np.random.default_rng(3), deadline=time.perf_counter() - 1.0)
    a = scatter(env, 50, 2.1, 1.1, np.random.default_rng(3))
    b = scatter(env, 50, 2.1, 1.1, np.random.default_rng(3), deadline=time.perf_counter() + 60.0)
    assert np.array_equal(a, b)
