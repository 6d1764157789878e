"""The obstacle-respecting bound (planner.geobound) against a brute-force reference:
every pair of nodes (corners, starts, targets) tested for visibility with shapely,
no tangent filter, no raster, no length cap, all-pairs shortest paths, then the
bottleneck assignment."""

import numpy as np
import pytest
import shapely
from scipy.sparse.csgraph import shortest_path

import planner.geobound as gb
from planner.bounds import bottleneck_distance
from planner.geobound import geo_distances, geo_lower_bound
from planner.problem import Circle, Polygon, Problem


def _reference(problem: Problem) -> tuple[np.ndarray, float]:
    """``(start x target shortest lengths, their bottleneck)`` over the visibility graph of
    all corners of the inscribed polygons that lie in the box and in no other polygon."""
    c = problem.clearance
    polys = gb._inscribed(problem)
    shrunk = shapely.union_all([shapely.Polygon(gb._shrunk(q, 1e-6 * c)) for q in polys])
    corners = np.concatenate(polys) if polys else np.zeros((0, 2))
    inside = ((corners[:, 0] >= c - 1e-9) & (corners[:, 0] <= problem.width - c + 1e-9)
              & (corners[:, 1] >= c - 1e-9) & (corners[:, 1] <= problem.height - c + 1e-9))
    corners = corners[inside & ~shapely.intersects(shrunk, shapely.points(corners))]
    m, n = problem.m, len(problem.target)
    pts = np.concatenate([problem.start, problem.target, corners])
    k = len(pts)
    i, j = np.triu_indices(k, 1)
    keep = ~((i >= m) & (i < m + n) & (j >= m) & (j < m + n)) & ~((i < m) & (j < m))  # no target-target, start-start
    i, j = i[keep], j[keep]
    seg = shapely.linestrings(np.stack([pts[i], pts[j]], axis=1))
    ok = ~shapely.intersects(shrunk, seg)
    g = np.full((k, k), np.inf)
    w = np.linalg.norm(pts[i] - pts[j], axis=1)
    g[i[ok], j[ok]] = w[ok]
    g[j[ok], i[ok]] = w[ok]
    # a start or target is an end point only, never passed through: one row of the search each
    inner = np.full((len(corners), len(corners)), np.inf)
    inner[:] = g[m + n :, m + n :]
    dcc = shortest_path(np.where(np.isinf(inner), 0, inner), method="D", directed=False) if len(corners) else inner
    ds, dt = g[:m, m + n :], g[m : m + n, m + n :]
    via = np.full((m, n), np.inf)
    if len(corners):
        via = np.min(ds[:, :, None] + dcc[None], axis=1)  # (m, corners): start -> last corner
        via = np.min(via[:, None, :] + dt[None], axis=2)
    d = np.minimum(via, g[:m, m : m + n])
    return d, bottleneck_distance_of(d)


def bottleneck_distance_of(d: np.ndarray) -> float:
    """Bottleneck of a distance matrix by brute force over its distinct values."""
    from scipy.optimize import linear_sum_assignment

    for v in np.unique(d[np.isfinite(d)]):
        allowed = d <= v
        r, col = linear_sum_assignment(~allowed)
        if allowed[r, col].all():
            return float(v)
    return float("inf")


def _world(seed: int, m: int = 6, obstacles=None) -> Problem:
    rng = np.random.default_rng(seed)
    w, h = 40.0, 30.0
    if obstacles is None:
        obstacles = []
        for _ in range(7):
            x, y = rng.uniform(3, w - 6), rng.uniform(3, h - 6)
            obstacles.append(Polygon(np.array([[x, y], [x + rng.uniform(1, 6), y], [x + rng.uniform(1, 6), y + rng.uniform(1, 5)],
                                               [x, y + rng.uniform(1, 5)]])))
        obstacles.append(Circle((rng.uniform(5, w - 5), rng.uniform(5, h - 5)), rng.uniform(0.5, 2.0)))
    grown = shapely.union_all([shapely.Polygon(o.vertices) if isinstance(o, Polygon) else shapely.Point(o.center).buffer(o.radius)
                               for o in obstacles]).buffer(1.2)
    pts = []
    while len(pts) < 2 * m:
        q = rng.uniform([1.2, 1.2], [w - 1.2, h - 1.2])
        if not grown.contains(shapely.Point(q)) and all(np.linalg.norm(q - p) > 2.2 for p in pts):
            pts.append(q)
    pts = np.array(pts)
    return Problem(w, h, tuple(obstacles), 1.0, 0.1, pts[:m], pts[m:])


def _fresh(p: Problem) -> Problem:
    return Problem(p.width, p.height, p.obstacles, p.radius, p.margin, p.start, p.target)


@pytest.mark.parametrize("small", [1000, 0])  # without and with the length cap
@pytest.mark.parametrize("seed", range(6))
def test_fast_bound_equals_brute_force(seed, small, monkeypatch):
    monkeypatch.setattr(gb, "_SMALL", small)
    _matches_reference(_world(seed))


def _matches_reference(p: Problem) -> Problem:
    """Assert the fast distances and bottleneck of ``p`` equal the brute force's; the
    fresh problem they were computed on."""
    d_ref, b_ref = _reference(p)
    d = geo_distances(_fresh(p))
    fin = np.isfinite(d_ref)
    assert (np.isfinite(d) == fin).all()
    assert np.allclose(d[fin], d_ref[fin], rtol=0, atol=1e-9)
    q = _fresh(p)
    geo_lower_bound(q)
    b = q.__dict__["_geo_bottleneck"]
    assert b >= 1e299 if np.isinf(b_ref) else b == pytest.approx(b_ref, abs=1e-9)  # split: no assignment
    assert b_ref >= bottleneck_distance(p.start, p.target) - 1e-9
    return q


def _cells(seed: int, m: int = 6) -> Problem:
    """A map of 2.4-unit cells, every blocked cell its own square (walls of squares that
    share edges and corners, as a map file gives them), robots on free cell centres."""
    rng = np.random.default_rng(seed)
    nx, ny, cell = 14, 11, 2.4
    blocked = rng.random((nx, ny)) < 0.3
    obstacles = tuple(Polygon(np.array([[i, j], [i + 1, j], [i + 1, j + 1], [i, j + 1]], float) * cell)
                      for i, j in zip(*np.nonzero(blocked)))
    free = np.argwhere(~blocked)
    pick = free[rng.choice(len(free), 2 * m, replace=False)]
    pts = (pick + 0.5) * cell
    return Problem(nx * cell, ny * cell, obstacles, 1.0, 0.1, pts[:m], pts[m:])


@pytest.mark.parametrize("small", [1000, 0])
@pytest.mark.parametrize("seed", range(8))
def test_union_corners_keep_the_bound_of_every_corner(seed, small, monkeypatch):
    """On cell maps most corners lie where the union of the grown squares is flat or turns
    inward; leaving them out of the graph keeps every distance of the all-corner reference."""
    monkeypatch.setattr(gb, "_SMALL", small)
    q = _matches_reference(_cells(seed))
    assert len(q.__dict__["_geo_world"].nodes) < 0.7 * sum(len(x) for x in gb._inscribed(q))


def test_comparison_catches_a_wrong_world():
    """Negative control: the reference of the world without one obstacle is lower, and
    with an extra wall higher, on some of the worlds; the test above would fail then."""
    lower = higher = 0
    for seed in range(6):
        p = _world(seed)
        geo_lower_bound(p)
        b = p.__dict__["_geo_bottleneck"]
        for k in range(len(p.obstacles)):
            fewer = Problem(p.width, p.height, p.obstacles[:k] + p.obstacles[k + 1 :], 1.0, 0.1, p.start, p.target)
            lower += _reference(fewer)[1] < b - 1e-6
        wall = Polygon(np.array([[19.5, 0.0], [20.5, 0.0], [20.5, 26.0], [19.5, 26.0]]))
        more = Problem(p.width, p.height, p.obstacles + (wall,), 1.0, 0.1, p.start, p.target)
        higher += _reference(more)[1] > b + 1e-6
    assert lower > 0
    assert higher > 0


def test_deadline_passed_raises():
    p = _world(0)
    with pytest.raises(TimeoutError):
        geo_lower_bound(p, deadline=0.0)
    assert "_geo_lower_bound" not in p.__dict__
