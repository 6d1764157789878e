"""The ``obstacles:`` section (polygons checked simple in O(k log k), circles, random ones) and ``map:``.

The caps of :data:`model._MAX_OBSTACLES` and :data:`model._MAX_VERTICES` hold
for the hand-written ``obstacles:``; a ``map:`` adds its rectangles under the
caps of :mod:`sim.scenario.maps` (cells and pieces, measured there).
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from planner.inputfile import echo_key, echo_path
from planner.problem import Circle, Polygon

from .fields import _kind, _Reader
from .model import _MAX_MAP_SIDE, _MAX_OBSTACLES, _MAX_SEED, _MAX_SIDE, _MAX_VERTICES, _RANDOM_VERTICES, RandomObstacles

__all__: list[str] = []  # private to the scenario room


def _read_obstacles(r: _Reader, value, width, height) -> tuple:
    if value is None:
        return ()
    if not isinstance(value, list):
        r.fail("obstacles", f"must be a list, got {_kind(value)}")
    if len(value) > _MAX_OBSTACLES:
        r.fail("obstacles", f"must hold at most {_MAX_OBSTACLES} obstacles, got {len(value)}")
    out = []
    total, vertices = 0, 0
    for k, item in enumerate(value):
        f = f"obstacles[{k}]"
        if not isinstance(item, dict) or len(item) != 1:
            r.fail(f, f"must be a mapping with exactly one of polygon, circle, random, got {_kind(item)}")
        (kind, body), = item.items()
        if kind == "polygon":
            out.append(_read_polygon(r, body, f"{f}.polygon", width, height))
            total += 1
            vertices += len(body)
        elif kind == "circle":
            c = r.mapping(body, f"{f}.circle", ("center", "radius"))
            if "center" not in c or "radius" not in c:
                r.fail(f"{f}.circle", "needs center and radius")
            center = r.inside(c["center"], f"{f}.circle.center", width, height)
            rad = r.number(c["radius"], f"{f}.circle.radius", gt=0, le=max(width, height))
            out.append(Circle(center, rad))
            total += 1
        elif kind == "random":
            c = r.mapping(body, f"{f}.random", ("count", "size", "seed"))
            n = r.integer(c.get("count", 3), f"{f}.random.count", ge=1, le=_MAX_VERTICES // _RANDOM_VERTICES)
            size = r.pair(c.get("size", [4, 8]), f"{f}.random.size", gt=0, le=_MAX_SIDE)
            if size[0] > size[1]:
                r.fail(f"{f}.random.size", f"must be [min, max] with min <= max, got [{size[0]:g}, {size[1]:g}]")
            if size[1] >= min(width, height):
                r.fail(f"{f}.random.size", f"max {size[1]:g} does not fit the workspace")
            seed = None if c.get("seed") is None else r.integer(c["seed"], f"{f}.random.seed", ge=0, le=_MAX_SEED)
            out.append(RandomObstacles(n, size, seed))
            total += n
            vertices += _RANDOM_VERTICES * n
        else:
            r.fail(f"{f}.{echo_key(kind)}", "unknown obstacle kind (allowed: polygon, circle, random)")
        if total > _MAX_OBSTACLES:
            r.fail(f, f"brings the obstacles to {total}; a scenario may have at most {_MAX_OBSTACLES}")
        if vertices > _MAX_VERTICES:
            r.fail(f, f"brings the obstacle vertices to {vertices} (a random obstacle counts "
                   f"{_RANDOM_VERTICES}); a scenario may have at most {_MAX_VERTICES}")
    return tuple(out)


def _read_polygon(r: _Reader, body, f: str, width, height) -> Polygon:
    """A simple polygon of 3 to 512 vertices in the workspace (checked in O(k log k))."""
    if not isinstance(body, list) or not 3 <= len(body) <= _MAX_VERTICES:
        r.fail(f, f"must be a list of 3 to {_MAX_VERTICES} points [x, y], got {_kind(body)}")
    pts = np.array([r.inside(p, f"{f}[{i}]", width, height) for i, p in enumerate(body)])
    reason = _polygon_defect(pts)
    if reason:
        r.fail(f, reason)
    return Polygon(pts)


def _polygon_defect(pts: np.ndarray) -> str | None:
    """Why ``pts`` is not a simple polygon of positive area, or None.

    Shapely (GEOS) decides simplicity with a sweep over the edges, in
    O(k log k) for k vertices.  A ring whose edges cross is reported as
    self-intersecting (a bowtie too, whose signed area may be zero); one that
    does not cross but encloses no area as having zero area.
    """
    import shapely

    same = np.flatnonzero(np.all(pts == np.roll(pts, -1, axis=0), axis=1))
    if len(same):
        i = int(same[0])
        return f"repeats a vertex: points {i} and {(i + 1) % len(pts)} are the same (the ring closes by itself)"
    ring = shapely.LinearRing(pts)
    if not shapely.is_simple(ring):
        near = ""
        found = re.search(r"\[(\S+) (\S+)\]", shapely.is_valid_reason(shapely.Polygon(pts)))
        if found:
            near = f" near ({float(found.group(1)):.6g}, {float(found.group(2)):.6g})"
        return f"is self-intersecting: two of its edges cross or touch{near}; it must be a simple polygon"
    if shapely.area(shapely.Polygon(pts)) <= 1e-12:
        return "has zero area (its vertices are collinear)"
    return None


@dataclass(frozen=True, eq=False)
class _MapInfo:
    """A read ``map:``: its grid, cell size [units], workspace size [units] and obstacle rectangles."""

    path: Path
    grid: object  # maps.Grid
    cell: float
    width: float
    height: float
    obstacles: tuple[Polygon, ...]
    origin: tuple[float, float] | None = None  # the world position of the lower-left corner


def _read_map(r: _Reader, value, base: Path) -> _MapInfo:
    """``map: {file, cell, origin, threshold}``: the workspace and the obstacles of an occupancy grid.

    ``origin`` (the world position of the map's lower-left corner, as in ROS;
    default a ROS map's own ``origin``, scaled when ``cell`` differs from its
    ``resolution``) does not move anything: scenario positions are measured from
    that corner; plan files record it for ``swarmform export``.
    """
    from .maps import MapError, cover, read_grid, resolve

    m = r.mapping(value, "map", ("file", "cell", "origin", "threshold"))
    if "file" not in m:
        r.fail("map.file", "is required (a MovingAI .map, a ROS map_server .yaml, a .png or a .pgm)")
    f = m["file"]
    if not isinstance(f, str) or not f or len(f) > 4096 or "\x00" in f:
        r.fail("map.file", f"must be a path to a map file, got {_kind(f)}")
    path = resolve(f, base)
    threshold = None if m.get("threshold") is None else r.number(m["threshold"], "map.threshold", ge=1, le=255)
    origin = r.pair(m["origin"], "map.origin", ge=-1e9, le=1e9) if "origin" in m else None
    try:
        grid = read_grid(path, threshold)
        cell = grid.cell
        if m.get("cell") is not None or cell is None:
            if "cell" not in m:
                r.fail("map.cell", "is required: the side of one map cell [units]")
            cell = r.number(m["cell"], "map.cell", gt=0, le=_MAX_SIDE)
        width, height = grid.cols * cell, grid.rows * cell
        if not (1 <= width <= _MAX_MAP_SIDE and 1 <= height <= _MAX_MAP_SIDE):
            r.fail("map.cell", f"{cell:g} makes the workspace {width:g} x {height:g} ({grid.cols} x {grid.rows} "
                   f"cells); each side must be in [1, {_MAX_MAP_SIDE:g}]")
        try:
            pieces = tuple(Polygon(p) for p in cover(grid, cell))
        except MapError as exc:
            r.fail("map.file", f"{echo_path(path.name, 60)}: {exc.reason}")
    except MapError as exc:
        r.fail(f"map.{exc.key}", exc.reason)
    if origin is None and grid.origin is not None:
        scale = cell / grid.cell if grid.cell else 1.0
        origin = (grid.origin[0] * scale, grid.origin[1] * scale)
    return _MapInfo(path, grid, cell, width, height, pieces, origin)
