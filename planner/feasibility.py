"""Proofs that no plan exists: free-space components counted (before any sampling).

A robot's centre must stay in the *free space* ``F``: the workspace shrunk
by ``c = radius + margin``, minus every obstacle grown by ``c``.  A robot
never leaves the connected component of ``F`` it starts in, whatever the
other robots do, so a plan exists only if every component holds as many
starts as targets.  When some component does not, :func:`feasibility`
returns an :class:`Infeasible` proof naming the component, and, when it
can find one, the passage narrower than ``2 c`` that splits it off.

Soundness (a solvable problem is never called unsolvable): the components
are computed for an *over-approximation* of ``F``, so two points in
different approximate components are in different true components too.

* Obstacles are grown by ``c - delta`` with ``delta`` far above the
  floating-point noise of the overlay (1e-7 plus 1e-12 of the workspace
  extent) and at least the validator's tolerance: a passage that the
  exact validator would let a robot through is never closed.
* Round joins of the growth are polygons inscribed in the true arcs
  (GEOS puts every vertex on the offset circle), so the grown obstacles
  are subsets of the true ones.
* A point that cannot be placed in a component with certainty ends the
  test without a proof.

The test is necessary, not sufficient: equal counts do not prove that a
plan exists.  A fast path skips the overlay when every obstacle is convex
(a circle or a convex polygon), the obstacles keep ``2 c`` from each other
and each comes closer than ``2 c`` to one wall at most (its box decides):
the workspace minus disjoint convex islands, each meeting the boundary in
one interval or not at all, is connected.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from .problem import Circle, Problem, describe_obstacle

__all__ = ["Infeasible", "Passage", "feasibility", "free_space_parts"]

_QUAD_SEGS = 16  # segments per quarter circle in the grown obstacles


@dataclass(frozen=True)
class Passage:
    """A gap narrower than a robot needs: between ``a`` and ``b`` (obstacle
    indices, -1 for the wall), at ``point`` (its middle), ``width`` wide."""

    a: int
    b: int
    point: tuple[float, float]
    width: float


@dataclass(frozen=True)
class Infeasible:
    """A proof that no plan exists.

    point: a point of the component whose counts differ; starts, targets:
    how many of each it holds; passage: the narrow gap that splits it from
    a neighbouring component (``None`` when none was found); need: the
    width a robot needs, ``2 (radius + margin)``; seconds: the test's time.
    """

    point: tuple[float, float]
    starts: int
    targets: int
    passage: Passage | None
    need: float
    seconds: float

    @property
    def reason(self) -> str:
        """One line: ``no plan exists: the component around (x, y) holds ...``."""
        x, y = self.point
        text = (f"no plan exists: the component around ({x:.3g}, {y:.3g}) holds "
                f"{_count(self.starts, 'start')} and {_count(self.targets, 'target')}")
        p = self.passage
        if p is not None:
            first, second = sorted((p.a, p.b), key=lambda k: (k < 0, k))
            pair = (f"{describe_obstacle(first)} and {describe_obstacle(second)}"
                    if first >= 0 else "the wall and the wall")
            width, need = _distinct(p.width, self.need)
            text += (f"; the gap between {pair} at ({p.point[0]:.3g}, {p.point[1]:.3g}) "
                     f"is {width} wide; robots need {need}")
        return text


def _count(n: int, noun: str) -> str:
    return f"{n} {noun}" + ("" if n == 1 else "s")


def _distinct(width: float, need: float) -> tuple[str, str]:
    """Both numbers with the fewest significant digits (3 or more) that tell them apart."""
    for digits in range(3, 13):
        a, b = f"{width:.{digits}g}", f"{need:.{digits}g}"
        if a != b:
            return a, b
    return f"{width:.17g}", f"{need:.17g}"


def feasibility(problem: Problem) -> Infeasible | None:
    """An :class:`Infeasible` proof when some free-space component holds
    more starts than targets (or fewer), else ``None`` (no proof: a plan
    may or may not exist)."""
    t0 = time.perf_counter()
    if _islands_apart(problem):
        return None
    import shapely

    c = problem.clearance
    got = free_space_parts(problem)
    if got is None:
        return None  # validated placements cannot exist; nothing to prove here
    parts, raw = got
    if len(parts) <= 1:
        return None
    where_s = _component_of(parts, problem.start)
    where_t = _component_of(parts, problem.target)
    if where_s is None or where_t is None:
        return None  # a point on no component or on two: no certain proof
    n_s = np.bincount(where_s, minlength=len(parts))
    n_t = np.bincount(where_t, minlength=len(parts))
    bad = np.flatnonzero(n_s != n_t)
    if len(bad) == 0:
        return None
    # The component with the largest surplus of starts (ties: lowest index).
    k = int(bad[np.argmax(n_s[bad] - n_t[bad])])
    comp = parts[k]
    pts = np.vstack([problem.start[where_s == k], problem.target[where_t == k]])
    centre = shapely.Point(*pts.mean(axis=0))
    here = centre if comp.contains(centre) else comp.representative_point()
    passage = _splitting_passage(problem, raw, parts, k, c)
    return Infeasible((float(here.x), float(here.y)), int(n_s[k]), int(n_t[k]), passage, 2 * c,
                      time.perf_counter() - t0)


def free_space_parts(problem: Problem) -> tuple[list, list] | None:
    """``(components, obstacle geometries)``: the connected components of an
    over-approximation of the free space ``F`` as shapely polygons (obstacles grown by
    ``c - delta``, see the module's soundness notes), or ``None`` when the workspace is
    narrower than ``2 c``.  Only the robots' placements are ignored (``problem`` may have none)."""
    import shapely
    from shapely.geometry import box

    c = problem.clearance
    extent = max(problem.width, problem.height)
    delta = 1e-7 + 1e-12 * extent
    grow = c - delta
    if problem.width <= 2 * grow or problem.height <= 2 * grow:
        return None
    raw = _obstacle_geometries(problem)
    room = box(grow, grow, problem.width - grow, problem.height - grow)
    if raw:
        grown = [_grow(g, ob, grow) for g, ob in zip(raw, problem.obstacles)]
        free = room.difference(shapely.union_all(grown))
    else:
        free = room
    return [g for g in getattr(free, "geoms", [free]) if not g.is_empty and g.area > 0], raw


def _islands_apart(problem: Problem) -> bool:
    """Every obstacle convex, at least ``2 c`` from the others and near one wall at
    most: the free space is then one component (a box minus disjoint convex islands)."""
    c2 = 2 * problem.clearance
    env = problem.env
    boxes = env.obstacle_boxes
    if len(boxes) == 0:
        return True
    # An island may bite into one wall (its grown self then meets the boundary in
    # one interval, which leaves the rest connected), not two.
    walls = ((boxes[:, 0] < c2).astype(int) + (boxes[:, 1] < c2) + (boxes[:, 2] > problem.width - c2)
             + (boxes[:, 3] > problem.height - c2))
    if (walls > 1).any():
        return False
    for poly in env.polygons:
        e1 = poly - np.roll(poly, 1, axis=0)
        e2 = np.roll(poly, -1, axis=0) - poly
        if ((e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]) < 0).any():  # a reflex corner (CCW)
            return False
    if len(boxes) == 1:
        return True
    gap_x = np.maximum(boxes[None, :, 0] - boxes[:, None, 2], boxes[:, None, 0] - boxes[None, :, 2])
    gap_y = np.maximum(boxes[None, :, 1] - boxes[:, None, 3], boxes[:, None, 1] - boxes[None, :, 3])
    near = np.maximum(gap_x, gap_y) < c2
    np.fill_diagonal(near, False)
    i, j = np.nonzero(np.triu(near))
    if len(i) == 0:
        return True
    if len(i) > 64:
        return False  # leave crowded worlds to the exact overlay

    geoms = _obstacle_geometries(problem)
    for a, b in zip(i.tolist(), j.tolist()):
        if _feature_distance(geoms[a], problem.obstacles[a], geoms[b], problem.obstacles[b]) < c2:
            return False
    return True


def _obstacle_geometries(problem: Problem) -> list:
    """Shapely geometries of the obstacles (a circle as its centre point)."""
    import shapely
    from shapely.geometry import Point, Polygon

    out = []
    for ob in problem.obstacles:
        if isinstance(ob, Circle):
            out.append(Point(ob.center))
        else:
            g = Polygon(ob.vertices)
            if not g.is_valid:
                g = shapely.make_valid(g)
            out.append(g)
    return out


def _grow(geom, ob, d: float):
    """The obstacle grown by ``d`` (inscribed round joins: a subset of the true growth)."""
    if isinstance(ob, Circle):
        return geom.buffer(ob.radius + d, quad_segs=_QUAD_SEGS)
    return geom.buffer(d, quad_segs=_QUAD_SEGS)


def _feature_distance(ga, oa, gb, ob) -> float:
    """Exact distance between two obstacles (circles: centre distance less the radius)."""
    d = ga.distance(gb)
    for o in (oa, ob):
        if isinstance(o, Circle):
            d -= o.radius
    return max(d, 0.0)


def _component_of(parts: list, points: np.ndarray) -> np.ndarray | None:
    """The component index of every point (each strictly inside exactly one); ``None`` otherwise."""
    import shapely

    tree = shapely.STRtree(parts)
    pts = shapely.points(np.asarray(points, float))
    idx_pt, idx_part = tree.query(pts, predicate="intersects")
    counts = np.bincount(idx_pt, minlength=len(points))
    if len(points) and (counts != 1).any():
        return None
    out = np.empty(len(points), int)
    out[idx_pt] = idx_part
    return out


def _splitting_passage(problem: Problem, raw: list, parts: list, k: int, c: float) -> Passage | None:
    """The widest gap narrower than ``2 c`` with component ``k`` on one side and
    another component on the other (``None`` when none is found).

    Candidate gaps are pairs of obstacles, or an obstacle and a wall, closer
    than ``2 c`` but apart.  Across the gap's middle, perpendicular to the
    segment between the closest points, the free space begins at distance
    ``sqrt(c^2 - w^2 / 4)`` on each side; points a little beyond are probed
    for the component they lie in.
    """
    import shapely
    from shapely.geometry import LineString, Point
    from shapely.ops import nearest_points

    w_, h_ = problem.width, problem.height
    walls = [LineString([(0, 0), (w_, 0)]), LineString([(w_, 0), (w_, h_)]),
             LineString([(w_, h_), (0, h_)]), LineString([(0, h_), (0, 0)])]
    feats = [(g, i, ob) for i, (g, ob) in enumerate(zip(raw, problem.obstacles))]
    pairs = []
    if raw:
        tree = shapely.STRtree(raw)
        # circles are stored as centres: widen their search by their radius
        big = max((ob.radius for ob in problem.obstacles if isinstance(ob, Circle)), default=0.0)
        ia, ib = tree.query(raw, predicate="dwithin", distance=2 * c + 2 * big)
        for a, b in zip(ia.tolist(), ib.tolist()):
            if a < b:
                pairs.append((feats[a], feats[b]))
        for g, i, ob in feats:
            for wall in walls:
                pairs.append(((g, i, ob), (wall, -1, None)))
    comp_tree = shapely.STRtree(parts)
    best = None
    for (ga, ia, oa), (gb, ib, ob) in pairs:
        pa, pb = nearest_points(ga, gb)
        p, q = np.array(pa.coords[0]), np.array(pb.coords[0])
        u = q - p
        dist = float(np.hypot(*u))
        if dist <= 0:
            continue
        u /= dist
        if oa is not None and ob is not None and not isinstance(oa, Circle) and not isinstance(ob, Circle):
            # parallel faces: the middle of the part of each within reach of the other
            p, q = _middle_near(ga, gb, dist, p), _middle_near(gb, ga, dist, q)
        elif ob is None and not isinstance(oa, Circle):
            p = _middle_near(ga, gb, dist, p)
            q = np.array(nearest_points(Point(*p), gb)[1].coords[0])
        if isinstance(oa, Circle):
            p = p + oa.radius * u
        if isinstance(ob, Circle):
            q = q - ob.radius * u
        width = dist - (oa.radius if isinstance(oa, Circle) else 0.0) - (ob.radius if isinstance(ob, Circle) else 0.0)
        if not 0 < width < 2 * c or (best is not None and width <= best.width):
            continue
        mid = 0.5 * (p + q)
        axis = np.array([-u[1], u[0]])
        reach0 = math.sqrt(max(c * c - width * width / 4, 0.0))
        sides = []
        for sign in (1.0, -1.0):
            found = None
            for step in np.linspace(0.02, 4.0, 40) * c:
                probe = Point(*(mid + sign * (reach0 + step) * axis))
                hit = comp_tree.query(probe, predicate="intersects")
                if len(hit) == 1:
                    found = int(hit[0])
                    break
            sides.append(found)
        if None in sides or sides[0] == sides[1] or k not in sides:
            continue
        best = Passage(ia, ib, (float(mid[0]), float(mid[1])), float(width))
    return best


def _middle_near(g, other, dist: float, fallback: np.ndarray) -> np.ndarray:
    """The centroid of the part of ``g``'s outline within ``dist`` (plus a hair) of ``other``."""
    outline = g.boundary if g.geom_type in ("Polygon", "MultiPolygon") else g
    near = outline.intersection(other.buffer(dist * 1.001 + 1e-6, quad_segs=_QUAD_SEGS))
    if near.is_empty:
        return fallback
    c = near.centroid
    return fallback if c.is_empty else np.array(c.coords[0])
