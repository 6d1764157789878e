"""The part of the workspace a picture shows: all of it, or the free space's box where
that is a small part of it (a ROS map is mostly unknown space)."""

from __future__ import annotations

import numpy as np

from planner.problem import Circle, Problem

__all__ = ["VIEW_CROP_BELOW", "view_box"]

#: A workspace whose free space (its bounding box, padded) covers less than this share of
#: it is drawn cropped to that box.
VIEW_CROP_BELOW = 0.5


def view_box(problem: Problem) -> tuple[float, float, float, float]:
    """``(x0, y0, x1, y1)``: the part of the workspace a picture shows (cached).

    All of it, unless the bounding box of the free space (the workspace less the
    obstacles, and every start and target), padded by two radii and 2 % of its
    longer side, covers less than :data:`VIEW_CROP_BELOW` of it: then that box.
    """
    cached = problem.__dict__.get("_view_box")
    if cached is not None:
        return cached
    full = (0.0, 0.0, float(problem.width), float(problem.height))
    box = full
    if problem.obstacles:
        import shapely
        from shapely.geometry import Point
        from shapely.geometry import Polygon as ShapelyPolygon
        from shapely.geometry import box as rect

        shapes = [Point(ob.center).buffer(ob.radius) if isinstance(ob, Circle) else ShapelyPolygon(ob.vertices)
                  for ob in problem.obstacles]
        free = rect(*full).difference(shapely.union_all([g if g.is_valid else g.buffer(0) for g in shapes]))
        if not free.is_empty:
            pts = np.concatenate([np.asarray(problem.start, float).reshape(-1, 2),
                                  np.asarray(problem.target, float).reshape(-1, 2)])
            x0, y0, x1, y1 = free.bounds
            if len(pts):
                x0, y0 = min(x0, pts[:, 0].min()), min(y0, pts[:, 1].min())
                x1, y1 = max(x1, pts[:, 0].max()), max(y1, pts[:, 1].max())
            pad = 2 * problem.radius + 0.02 * max(x1 - x0, y1 - y0)
            x0, y0 = max(0.0, x0 - pad), max(0.0, y0 - pad)
            x1, y1 = min(full[2], x1 + pad), min(full[3], y1 + pad)
            if (x1 - x0) * (y1 - y0) < VIEW_CROP_BELOW * full[2] * full[3]:
                box = (float(x0), float(y0), float(x1), float(y1))
    problem.__dict__["_view_box"] = box
    return box
