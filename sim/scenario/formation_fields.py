"""The ``start:``, ``target:`` and ``targets:`` sections: formations, points, text, strokes, scatter."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from planner.formations import DEFAULT_COUNTS

from .fields import _kind, _Reader
from .model import _MAX_ROBOTS, FormationSpec

__all__ = ["MAX_HOLD"]

_SCATTER = "scatter"
MAX_HOLD = 60.0  # [s]


def _read_placement(r: _Reader, value, f: str, width, height, base: Path = Path("."), *,
                    chained: bool = False, grid=None) -> FormationSpec:
    if not isinstance(value, dict):
        r.fail(f, f"must be a mapping with formation or points, got {_kind(value)}")
    extra = ("hold",) if chained else ()
    hold = 0.0
    if chained:
        hold = r.number(value.get("hold", 2.0), f"{f}.hold", ge=0, le=MAX_HOLD)
    if "scen" in value:
        r.mapping(value, f, ("scen", "count") + extra)
        return FormationSpec(points=_read_scen_cells(r, value, f, base, grid), hold=hold)
    if "points" in value:
        r.mapping(value, f, ("points",) + extra)
        pts = value["points"]
        if not isinstance(pts, list) or not 1 <= len(pts) <= _MAX_ROBOTS:
            r.fail(f"{f}.points", f"must be a list of 1 to {_MAX_ROBOTS} points [x, y], got {_kind(pts)}")
        return FormationSpec(points=tuple(r.pair(p, f"{f}.points[{i}]") for i, p in enumerate(pts)), hold=hold)
    v = r.mapping(value, f, ("formation", "scale", "rotation", "center", "region") + extra)
    if "formation" not in v:
        r.fail(f, "needs formation or points")
    name = v["formation"]
    text = font = strokes = None
    fill = "strokes"
    if isinstance(name, dict):
        text, font, fill, strokes = _read_drawing(r, name, f"{f}.formation", base)
        name = "text" if text is not None else "strokes"
    elif not isinstance(name, str) or name not in DEFAULT_COUNTS and name != _SCATTER:
        known = ", ".join([*DEFAULT_COUNTS, _SCATTER])
        r.fail(f"{f}.formation", f"unknown formation (known: {known}; or a mapping "
                                 f"{{text: ...}} or {{strokes: ...}}), got {_kind(name)}")
    if name == _SCATTER:
        for key in ("scale", "rotation", "center"):
            if key in v:
                r.fail(f"{f}.{key}", "does not apply to scatter, which spreads over the free space "
                                     "(use region: [x0, y0, x1, y1])")
        region = None
        if "region" in v:
            region = _read_region(r, v["region"], f"{f}.region", width, height)
        return FormationSpec(formation=name, region=region, hold=hold)
    if "region" in v:
        r.fail(f"{f}.region", "applies to scatter only")
    drawn = name in ("text", "strokes")
    sc = v.get("scale", "fit" if drawn else 0.3)
    scale = None if sc == "fit" else r.number(sc, f"{f}.scale", gt=0, le=1)
    rot = v.get("rotation", 0.0 if drawn else "random")
    rotation = None if rot == "random" else r.number(rot, f"{f}.rotation", ge=-360, le=360)
    cen = v.get("center", "random")
    center = None
    if cen != "random":
        center = r.inside(cen, f"{f}.center", width, height)
    return FormationSpec(formation=name, scale=scale, rotation=rotation, center=center, text=text, font=font,
                         fill=fill, strokes=strokes, hold=hold)


def _read_scen_cells(r: _Reader, value: dict, f: str, base: Path, grid) -> tuple[tuple[float, float], ...]:
    """``{scen: FILE, count: N}``: the centres of the first N agents' start cells (goal cells for a target)."""
    from .maps import MapError, resolve
    from .scen import read_scen

    if grid is None:
        r.fail(f"{f}.scen", "needs a map: (a .scen names cells of a map's grid)")
    if "count" not in value:
        r.fail(f"{f}.count", "is required: how many of the .scen's agents to take")
    n = r.integer(value["count"], f"{f}.count", ge=1, le=_MAX_ROBOTS)
    name = value["scen"]
    if not isinstance(name, str) or not name or len(name) > 4096 or "\x00" in name:
        r.fail(f"{f}.scen", f"must be a path to a MovingAI .scen file, got {_kind(name)}")
    path = resolve(name, base)
    try:
        cells = read_scen(path, n, grid.grid, goal=f != "start")
    except MapError as exc:
        r.fail(f"{f}.{'count' if exc.key == 'count' else 'scen'}", exc.reason)
    return tuple(grid.grid.centre(int(c), int(rw), grid.cell) for c, rw in cells)


def _read_drawing(r: _Reader, value: dict, f: str, base: Path):
    """``{text, font, fill}`` or ``{strokes}``: (text, font path, fill, strokes)."""
    from planner.strokes import MAX_POINTS, MAX_STROKES, check_polylines

    from .glyphs import GlyphError, check_text
    from .placements import text_glyphs

    if "strokes" in value:
        r.mapping(value, f, ("strokes",))
        lines = value["strokes"]
        if not isinstance(lines, list) or not 1 <= len(lines) <= MAX_STROKES:
            r.fail(f"{f}.strokes", f"must be a list of 1 to {MAX_STROKES} strokes (polylines), got {_kind(lines)}")
        out = []
        for i, line in enumerate(lines):
            if not isinstance(line, list) or not 2 <= len(line) <= MAX_POINTS:
                r.fail(f"{f}.strokes[{i}]", f"must be a list of 2 to {MAX_POINTS} points [x, y], got {_kind(line)}")
            pts = []
            for j, p in enumerate(line):
                x, y = r.pair(p, f"{f}.strokes[{i}][{j}]")
                if not (0 <= x <= 1 and 0 <= y <= 1):
                    r.fail(f"{f}.strokes[{i}][{j}]", f"({x:g}, {y:g}) lies outside the unit box [0, 1] x [0, 1]")
                pts.append((x, y))
            out.append(tuple(pts))
        try:
            check_polylines(out, f"{f}.strokes")
        except ValueError as exc:
            where, _, why = str(exc).partition(": ")
            r.fail(where, why)
        return None, None, "strokes", tuple(out)
    r.mapping(value, f, ("text", "font", "fill"))
    if "text" not in value:
        r.fail(f, "needs text (with optional font and fill) or strokes")
    text = value["text"]
    if not isinstance(text, str):
        hint = f' (write it in quotes: text: "{text}")' if isinstance(text, (int, float)) else ""
        r.fail(f"{f}.text", f"must be a string, got {_kind(text)}{hint}")
    fill = value.get("fill", "strokes")
    if fill not in ("strokes", "area"):
        r.fail(f"{f}.fill", f"must be strokes or area, got {_kind(fill)}")
    font = value.get("font")
    if font is not None:
        if not isinstance(font, str) or not font or len(font) > 4096:
            r.fail(f"{f}.font", f"must be a path to a TrueType font file, got {_kind(font)}")
        if "\x00" in font:
            r.fail(f"{f}.font", "holds a NUL character (\\0), which no file path can hold")
        font = str(base / Path(font).expanduser()) if not Path(font).expanduser().is_absolute() else font
    try:
        check_text(text)
        text_glyphs(text, font)
    except GlyphError as exc:
        r.fail(f"{f}.{exc.field}", exc.reason)
    if fill == "strokes" and not _traced_extent(text, font) > 0:
        r.fail(f"{f}.text", f"{_short_text(text)} traces to a single point, no line to place robots "
               "along; use fill: area, or characters with strokes")
    return text, font, fill, None


def _traced_extent(text: str, font: str | None) -> float:
    """The longer side of the box of ``text``'s traced strokes [pixels of the glyph mask]."""
    from planner.strokes import bounds

    from .placements import text_strokes

    return float(np.ptp(bounds(text_strokes(text, font)), axis=0).max())


def _short_text(text: str) -> str:
    return repr(text if len(text) <= 24 else text[:21] + "...")


def _read_region(r: _Reader, value, f: str, width, height) -> tuple[float, float, float, float]:
    if not isinstance(value, (list, tuple)) or len(value) != 4:
        r.fail(f, f"must be [x0, y0, x1, y1], got {_kind(value)}")
    x0, y0, x1, y1 = (r.number(v, f"{f}[{i}]") for i, v in enumerate(value))
    if not (0 <= x0 < x1 <= width and 0 <= y0 < y1 <= height):
        r.fail(f, f"[{x0:g}, {y0:g}, {x1:g}, {y1:g}] must satisfy 0 <= x0 < x1 <= {width:g} "
                  f"and 0 <= y0 < y1 <= {height:g} (inside the workspace)")
    return (x0, y0, x1, y1)


def _resolve_count(r: _Reader, count, specs: list[tuple[str, FormationSpec]], width, height, sep,
                   clearance) -> int:
    from .placements import default_count

    sizes = [(key, len(spec.points)) for key, spec in specs if spec.points is not None]
    for key, n in sizes[1:]:
        if n != sizes[0][1]:
            r.fail(f"{key}.points", f"has {n} robots but {sizes[0][0]}.points has {sizes[0][1]}")
    if sizes:
        key, n = sizes[0]
        if count is not None and count != n:
            r.fail("robots.count", f"is {count} but {key}.points has {n} points")
        count = n
    if count is None:
        defaults = [(key, spec, default_count(spec, width, height, sep, clearance)) for key, spec in specs]
        defaults = [d for d in defaults if d[2] is not None]
        if not defaults:
            chain = " -> ".join(spec.describe() for _, spec in specs)
            r.fail("robots.count", f"is required: {chain} has no default count")
        for key, spec, n in defaults[1:]:
            k0, s0, n0 = defaults[0]
            if n != n0:
                r.fail(
                    "robots.count",
                    f"count mismatch: {k0} {s0.describe()} has {n0} robots, "
                    f"{key} {spec.describe()} has {n}; set robots.count",
                )
        count = defaults[0][2]
    if count < 2 and any(spec.points is None for _, spec in specs):
        r.fail("robots.count", f"a formation needs at least 2 robots, got {count}")
    return count
