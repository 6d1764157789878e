"""From a formation spec to robot placements: letters, line, ring, random, text, strokes, scatter.

Every kind but ``scatter`` and explicit ``points`` is a *shape* first (``m``
points centred on the origin, its bounding-box side ``scale * min(W, H)``,
enlarged when two robots would come closer than ``2 r + margin``), then
*placed*: rotated by ``rotation`` degrees counter-clockwise and shifted to
``center`` (either may be random: :func:`planner.formations.place_formation`).
``scatter`` draws its placements directly over the free space
(:func:`planner.scatter.scatter`).

Text is rendered off-screen (:mod:`sim.scenario.glyphs`) and reaches the planner's
samplers as plain data: the stroke skeleton of the glyphs
(:func:`planner.skeleton.mask_strokes`, sampled like the letters) for
``fill: strokes``, or the glyph mask (:func:`planner.area.area_points`)
for ``fill: area``.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

from planner.area import area_points, ink_points
from planner.formations import DEFAULT_COUNTS, formation_box, formation_shape
from planner.strokes import (
    SPACING_SLACK,
    Stroke,
    bounds,
    count_at_spacing,
    drawing,
    extent,
    scaled_shape,
    strokes_shape,
)

__all__ = [
    "AREA_SPACING",
    "FIT",
    "MAX_DEFAULT_COUNT",
    "STROKE_SPACING",
    "default_count",
    "formation_drawing",
    "formation_side",
    "make_shape",
    "text_glyphs",
    "text_strokes",
    "uses_rng",
]

#: Default counts of text and strokes: robots this many separations apart
#: along the strokes, or packed hexagonally at this spacing over the area.
STROKE_SPACING = 1.5
AREA_SPACING = 1.3
#: A default count never exceeds this (set robots.count for more).
MAX_DEFAULT_COUNT = 500


@lru_cache(maxsize=32)
def text_glyphs(text: str, font: str | None):
    """The rendered text, a :class:`sim.scenario.glyphs.Glyphs` (cached: reading and building a
    scenario render it once; pygame is imported only for text)."""
    from .glyphs import render_text

    return render_text(text, font)


@lru_cache(maxsize=32)
def text_strokes(text: str, font: str | None) -> tuple[Stroke, ...]:
    """The strokes traced from the skeleton of ``text``'s glyphs (cached)."""
    from planner.skeleton import mask_strokes

    return drawing(mask_strokes(text_glyphs(text, font).mask))


@lru_cache(maxsize=32)
def _user_strokes(polylines: tuple) -> tuple[Stroke, ...]:
    return drawing([np.asarray(p, float) for p in polylines])


def formation_drawing(spec) -> tuple[Stroke, ...] | None:
    """The strokes robots are spread along (text with ``fill: strokes``, ``strokes``), or None."""
    if spec.text is not None and spec.fill == "strokes":
        return text_strokes(spec.text, spec.font)
    if spec.strokes is not None:
        return _user_strokes(spec.strokes)
    return None


def _extent(points: np.ndarray) -> float:
    return max(float(np.ptp(points, axis=0).max()), 1e-12)


#: ``scale: fit``: the formation's box fills this fraction of the workspace
#: (less the wall clearance) in the direction that binds
FIT = 0.9


def formation_side(spec, width: float, height: float, clearance: float = 0.0) -> float:
    """The requested bounding-box side [units]: ``scale * min(W, H)``, or for ``scale: fit``
    (``spec.scale is None``) the largest side at which the box, unrotated, fills at most
    :data:`FIT` of the workspace's width and height less the wall clearance on both sides."""
    if spec.scale is not None:
        return spec.scale * min(width, height)
    strokes = formation_drawing(spec)
    if strokes is not None:
        w, h = np.ptp(bounds(strokes), axis=0)
    elif spec.text is not None:
        w, h = np.ptp(ink_points(text_glyphs(spec.text, spec.font).mask), axis=0)
    else:
        w, h = formation_box(spec.formation)
    longer = max(w, h)
    room = [FIT * (size - 2 * clearance) / (extent / longer)
            for size, extent in ((width, w), (height, h)) if extent > 1e-9 * longer]
    return float(max(min(room), 1e-9))


def default_count(spec, width: float, height: float, separation: float, clearance: float | None = None) -> int | None:
    """The robot count a spec implies when ``robots.count`` is not given, or None.

    Letters: the paper's Table I.  Text and strokes: as many robots as fit
    :data:`STROKE_SPACING` separations apart along the strokes at the
    requested size (``fill: area``: packed hexagonally :data:`AREA_SPACING`
    separations apart over the ink), at least 2 and at most
    :data:`MAX_DEFAULT_COUNT`.  Points: their number.  Line, ring, random
    and scatter: None.
    """
    if spec.points is not None:
        return len(spec.points)
    if spec.formation in DEFAULT_COUNTS:
        return DEFAULT_COUNTS[spec.formation]
    side = formation_side(spec, width, height, separation / 2 if clearance is None else clearance)
    strokes = formation_drawing(spec)
    if strokes is not None:
        per_unit = extent(strokes) / side  # drawing units per workspace unit
        n = count_at_spacing(strokes, STROKE_SPACING * separation * per_unit)
    elif spec.text is not None:  # fill: area
        ink = ink_points(text_glyphs(spec.text, spec.font).mask)
        per_unit = _extent(ink) / side
        cell = math.sqrt(3) / 2 * (AREA_SPACING * separation * per_unit) ** 2
        n = int(round(len(ink) / cell))
    else:
        return None
    return int(min(max(n, 2), MAX_DEFAULT_COUNT))


def make_shape(spec, m: int, side: float, separation: float, rng: np.random.Generator) -> np.ndarray:
    """The spec's ``(m, 2)`` shape centred on the origin (any kind but points and scatter).

    Only ``random`` and text with ``fill: area`` draw from ``rng``.
    """
    strokes = formation_drawing(spec)
    if strokes is not None:
        return strokes_shape(strokes, m, side, separation)
    if spec.text is not None:
        mask = text_glyphs(spec.text, spec.font).mask
        gap = separation * SPACING_SLACK * _extent(ink_points(mask)) / side
        return scaled_shape(area_points(mask, m, rng, gap), side, separation)
    return formation_shape(spec.formation, m, side, separation, rng)


def uses_rng(spec) -> bool:
    """Whether :func:`make_shape` draws from the generator for this spec."""
    return spec.formation == "random" or (spec.text is not None and spec.fill == "area")
