"""The polygons of the obstacle-respecting bound (:mod:`planner.geobound`): each obstacle
grown by the clearance as an inscribed polygon, shrunk ones for the visibility test, and
the corners of their union where shortest paths can bend (see that module's docstring)."""

from __future__ import annotations

import numpy as np

from .problem import Problem

__all__: list[str] = []

_CIRCLE_SIDES = 16


def _inscribed(problem: Problem) -> list[np.ndarray]:
    """The inscribed polygons ``O`` (counter-clockwise), one per convex polygon or disc.

    Polygons of the same vertex count are done together (maps give thousands of
    rectangles)."""
    c = problem.clearance
    found: dict[int, np.ndarray] = {}
    sizes: dict[int, list[int]] = {}
    for i, ob in enumerate(problem.obstacles):
        sizes.setdefault(len(ob.vertices) if hasattr(ob, "vertices") else 0, []).append(i)
    for k, idx in sizes.items():
        if k == 0:  # discs
            ang = np.arange(_CIRCLE_SIDES) * 2 * np.pi / _CIRCLE_SIDES
            ring = np.stack([np.cos(ang), np.sin(ang)], axis=1)
            for i in idx:
                ob = problem.obstacles[i]
                found[i] = np.asarray(ob.center, float) + (ob.radius + c) * ring
            continue
        v = np.stack([np.asarray(problem.obstacles[i].vertices, float) for i in idx])  # (P, K, 2)
        e = np.roll(v, -1, axis=1) - v  # edge k: v[k] -> v[k + 1]
        e2 = np.roll(e, -1, axis=1)
        cross = e[..., 0] * e2[..., 1] - e[..., 1] * e2[..., 0]
        convex = ~(cross < -1e-12 * (np.abs(e).max(axis=(1, 2)) ** 2)[:, None]).any(axis=1)
        n = np.stack([e[..., 1], -e[..., 0]], axis=-1)
        n /= np.linalg.norm(n, axis=-1, keepdims=True)
        n_in = np.roll(n, 1, axis=1)  # normal of the edge into vertex k
        pts = np.stack([v + c * n_in, v + c * n], axis=2).reshape(len(idx), -1, 2)
        for i, p, ok in zip(idx, pts, convex):
            if ok:  # not convex: left out (the bound stays valid)
                found[i] = p
    out = []
    for i in sorted(found):
        pts = found[i]
        keep = np.linalg.norm(pts - np.roll(pts, 1, axis=0), axis=1) > 1e-12 * c
        pts = pts[keep]
        if len(pts) >= 3:
            out.append(pts)
    return out


def _shrunk(poly: np.ndarray, delta: float) -> np.ndarray:
    """A convex counter-clockwise polygon with every edge moved inward by ``delta``."""
    e = np.roll(poly, -1, axis=0) - poly
    n = np.stack([e[:, 1], -e[:, 0]], axis=1)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    n_in = np.roll(n, 1, axis=0)
    s = n_in + n
    return poly - delta * s / (1.0 + (n_in * n).sum(axis=1))[:, None]


def _union_corners(polys: list[np.ndarray], tol: float) -> tuple[np.ndarray, np.ndarray]:
    """The corners of the union ``U`` of the inscribed polygons where ``U`` is convex, and
    their two neighbours along ``U``'s boundary: ``(nodes (V, 2), side (V, 2, 2))``.

    A shortest path among the ``O`` bends only at a vertex of ``U``'s boundary where
    ``U`` occupies less than a half-plane (taut string); a vertex where two edges of
    different ``O`` cross is not one (there ``U`` occupies more), so these are corners of
    the ``O`` themselves.  The corners left out lie inside ``U`` or where its boundary
    is straight or turns inward: on a map of cells, most of the rectangles' corners
    (the rectangles of a wall share edges).  Where ``U``'s boundary touches itself at a
    point, the point is listed once per pass, each with its own neighbours."""
    import shapely
    from shapely.geometry.polygon import orient

    groups: dict[int, list[np.ndarray]] = {}
    for q in polys:  # built by vertex count at once (maps give thousands of rectangles)
        groups.setdefault(len(q), []).append(q)
    union = shapely.union_all(np.concatenate([shapely.polygons(np.stack(g)) for g in groups.values()]))
    nodes, side = [], []
    for part in getattr(union, "geoms", [union]):
        if part.geom_type != "Polygon" or part.is_empty:
            continue
        part = orient(part, 1.0)  # the outer ring counter-clockwise, holes clockwise: U on the left
        for ring in [part.exterior, *part.interiors]:
            v = np.asarray(ring.coords, float)[:-1]
            v = v[np.linalg.norm(v - np.roll(v, 1, axis=0), axis=1) > tol]
            if len(v) < 3:
                continue
            prev, nxt = np.roll(v, 1, axis=0), np.roll(v, -1, axis=0)
            a, b = v - prev, nxt - v
            cross = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
            convex = cross > 1e-9 * np.linalg.norm(a, axis=1) * np.linalg.norm(b, axis=1)
            nodes.append(v[convex])
            side.append(np.stack([prev[convex], nxt[convex]], axis=1))
    if not nodes:
        return np.zeros((0, 2)), np.zeros((0, 2, 2))
    return np.concatenate(nodes), np.concatenate(side)
