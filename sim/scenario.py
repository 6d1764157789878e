"""Scenario files: strict YAML loading into frozen specs, then a Problem.

``read_scenario(path)`` parses and checks the file (unknown keys, wrong
types and values outside each field's documented range are rejected with
a :class:`ScenarioError` naming the file, the field and the reason, with
the value received echoed in at most about 80 characters).  The file is
read only when it is a regular file of at most :data:`MAX_FILE_BYTES`; its
YAML may not use anchors, aliases, tags or nesting deeper than
:data:`sim.yamlfile.MAX_DEPTH` (:mod:`sim.yamlfile`).  Every field's range
is chosen so that time and memory stay bounded; the README's input table
lists them (unit, default, range), and a test holds it to this code.  ``build_problem(scenario,
rng)`` turns the spec into a :class:`planner.Problem`: it draws the random
obstacles, the formations' rotations and centres from ``rng`` and checks
the placements (robot index and what it hits).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any

import numpy as np

from planner.formations import DEFAULT_COUNTS, place_formation
from planner.geometry import Environment
from planner.inputfile import UnreadableFile, echo, echo_key, echo_path, read_text
from planner.params import PlannerParams
from planner.problem import Circle, Polygon, Problem, ProblemError, check_placement

from .params import MAX_FPS, MAX_RENDER_SIZE, Failure, Impulse, Noise, Pushes, Recovery, RenderParams, SimParams
from .yamlfile import YamlRefused, load_yaml

__all__ = [
    "FormationSpec",
    "MAX_FILE_BYTES",
    "MAX_HOLD",
    "MAX_TARGETS",
    "PaperRef",
    "RandomObstacles",
    "Scenario",
    "ScenarioError",
    "build_legs",
    "build_problem",
    "read_scenario",
]


MAX_FILE_BYTES = 256 << 10
"""The largest scenario file read [bytes]: 256 KiB, room for 1000 explicit start and target
points and 4096 polygon vertices (the biggest shipped scenario is under 1 KiB)."""

# Bounds shared by several fields (see the README's input table).
_MAX_SIDE = 1000.0  # workspace side [units]
_MAX_ROBOTS = 1000
# Obstacles of a scenario (random ones included), and their vertices (a random
# obstacle counts as 8, the most it has).  The planner's clearance and
# visibility kernels are indexed (memory about linear in edges); at these caps
# (64 random obstacles, 169 triangles, a 512-gon, 256 circles, with 30 to 50
# robots) a run plans in under 3 s and peaks under 200 MB.
_MAX_OBSTACLES = 256
_MAX_VERTICES = 512
_RANDOM_VERTICES = 8
_MAX_SEED = 2**63 - 1
_MAX_NAME = 64  # characters


class ScenarioError(ValueError):
    """A bad scenario file: ``str()`` is one line ``FILE: FIELD: reason``."""

    def __init__(self, path: str | Path, field: str, reason: str):
        self.path = str(path)
        self.field = field
        self.reason = reason
        super().__init__(f"{echo_path(self.path)}: {field}: {reason}")


@dataclass(frozen=True)
class RandomObstacles:
    """``count`` random convex polygons with diameters in ``size``."""

    count: int
    size: tuple[float, float]
    seed: int | None = None


@dataclass(frozen=True)
class FormationSpec:
    """One placement of the swarm: a formation (with scale, rotation, centre) or explicit points.

    formation: a name of :data:`planner.FORMATIONS`, ``scatter``, ``text``
        (then ``text``, ``font``, ``fill``) or ``strokes`` (then ``strokes``).
    scale: the longer side of the robots' bounding box as a fraction of
        ``min(W, H)`` (enlarged when robots would come closer than
        ``2 r + margin``); ``None`` means ``fit``: as large as fits 90 % of
        the workspace (less the wall clearance) unrotated.
    rotation: degrees counter-clockwise; ``None`` means random.
    center: the bounding box's centre [units]; ``None`` means random.
    region: ``(x0, y0, x1, y1)`` that scatter spreads the centres over.
    hold: seconds the swarm rests in this formation before the next leg
        starts (chained ``targets`` only).
    """

    formation: str | None = None
    scale: float | None = 0.3
    rotation: float | None = None
    center: tuple[float, float] | None = None
    points: tuple[tuple[float, float], ...] | None = None
    text: str | None = None
    font: str | None = None
    fill: str = "strokes"
    strokes: tuple[tuple[tuple[float, float], ...], ...] | None = None
    region: tuple[float, float, float, float] | None = None
    hold: float = 0.0

    def describe(self) -> str:
        if self.points is not None:
            return "points"
        if self.text is not None:
            shown = self.text if len(self.text) <= 24 else self.text[:21] + "..."
            return f"text {shown!r}" + (" (area)" if self.fill == "area" else "")
        if self.strokes is not None:
            return f"strokes ({len(self.strokes)})"
        return str(self.formation)


@dataclass(frozen=True)
class PaperRef:
    """Where a scenario comes from in the paper: table, row and reported time [s]."""

    table: str
    row: int
    time_s: float


@dataclass(frozen=True)
class Scenario:
    """A checked scenario file.  Lengths in workspace units, speeds in units/s.

    ``target`` is the last target; ``targets`` holds every target of a
    chained scenario (empty when the file gives one ``target``).
    """

    path: str
    name: str
    seed: int
    width: float
    height: float
    radius: float
    margin: float
    count: int
    max_speed: float
    max_accel: float
    obstacles: tuple[Polygon | Circle | RandomObstacles, ...]
    start: FormationSpec
    target: FormationSpec
    planner: PlannerParams
    sim: SimParams
    render: RenderParams
    paper: PaperRef | None = None
    targets: tuple[FormationSpec, ...] = ()

    @property
    def legs(self) -> tuple[FormationSpec, ...]:
        """The targets in the order they are reached (``target`` alone unless chained)."""
        return self.targets or (self.target,)

    def describe(self) -> str:
        """``start -> target`` (every target of a chain)."""
        return " -> ".join(spec.describe() for spec in (self.start, *self.legs))


# ----------------------------------------------------------------------------
# field readers


class _Reader:
    def __init__(self, path: str):
        self.path = path

    def fail(self, field: str, reason: str):
        raise ScenarioError(self.path, field, reason)

    def mapping(self, value, field: str, allowed: tuple[str, ...]) -> dict:
        if value is None:
            value = {}
        if not isinstance(value, dict):
            self.fail(field, f"must be a mapping, got {_kind(value)}")
        for key in value:
            if key not in allowed:
                hint = ", ".join(allowed)
                where = f"{field}.{echo_key(key)}" if field else echo_key(key)
                self.fail(where, f"unknown key; allowed here: {hint}")
        return value

    def number(self, value, field, *, gt=None, ge=None, le=None, lt=None) -> float:
        """A finite number (not a boolean) within the given bounds."""
        span = _span(gt, ge, le, lt)
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            self.fail(field, f"must be a number{span}, got {_kind(value)}{_numeric_text_hint(value)}")
        if isinstance(value, int) and value.bit_length() > 1000:
            self.fail(field, f"must be a number{span}, got {_kind(value)}")
        value = float(value)
        if not math.isfinite(value):
            self.fail(field, f"must be a finite number{span}, got {value}")
        if ((gt is not None and not value > gt) or (ge is not None and not value >= ge)
                or (le is not None and not value <= le) or (lt is not None and not value < lt)):
            self.fail(field, f"must be a number{span}, got {value:g}")
        return value

    def integer(self, value, field, *, ge=None, le=None) -> int:
        """An integer (not a boolean, not a float) within ``[ge, le]``."""
        span = _span(None, ge, le, None)
        if isinstance(value, bool) or not isinstance(value, int):
            self.fail(field, f"must be an integer{span}, got {_kind(value)}")
        if (ge is not None and value < ge) or (le is not None and value > le):
            self.fail(field, f"must be an integer{span}, got {_kind(value).removeprefix('number ')}")
        return int(value)

    def int_or_auto(self, value, field, *, ge=1, le=None) -> int | None:
        if value == "auto":
            return None
        if isinstance(value, bool) or not isinstance(value, int):
            self.fail(field, f"must be 'auto' or an integer{_span(None, ge, le, None)}, got {_kind(value)}")
        return self.integer(value, field, ge=ge, le=le)

    def boolean(self, value, field) -> bool:
        if not isinstance(value, bool):
            self.fail(field, f"must be true or false, got {_kind(value)}")
        return value

    def pair(self, value, field, **bounds) -> tuple[float, float]:
        """``[x, y]``: two numbers, each within ``bounds`` (as for :meth:`number`)."""
        if not isinstance(value, (list, tuple)) or len(value) != 2:
            self.fail(field, f"must be a pair [x, y], got {_kind(value)}")
        return (
            self.number(value[0], f"{field}[0]", **bounds),
            self.number(value[1], f"{field}[1]", **bounds),
        )

    def inside(self, value, field, width, height) -> tuple[float, float]:
        """A point ``[x, y]`` of the workspace ``[0, width] x [0, height]``."""
        x, y = self.pair(value, field)
        if not (0 <= x <= width and 0 <= y <= height):
            self.fail(field, f"({x:g}, {y:g}) lies outside the {width:g} x {height:g} workspace")
        return x, y


def _bound(v) -> str:
    return "2^63 - 1" if v == _MAX_SEED else f"{v:g}"


def _span(gt, ge, le, lt) -> str:
    """`` in [a, b]``, `` > a`` and the like: the allowed range, for a message."""
    low = f"({_bound(gt)}" if gt is not None else f"[{_bound(ge)}" if ge is not None else None
    high = f"{_bound(le)}]" if le is not None else f"{_bound(lt)})" if lt is not None else None
    if low and high:
        return f" in {low}, {high}"
    if low:
        return f" {'>' if gt is not None else '>='} {low[1:]}"
    if high:
        return f" {'<=' if le is not None else '<'} {high[:-1]}"
    return ""


def _numeric_text_hint(value) -> str:
    """For text that reads as a number (YAML takes ``1e3`` for text): how to write it."""
    if isinstance(value, str) and len(value) <= 40:
        try:
            float(value)
        except ValueError:
            return ""
        if re.fullmatch(r"\s*[-+]?(?:(?:0|[1-9][0-9]*)(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][-+]?[0-9]+)?\s*", value):
            return " (text; write a number such as 1.0e+3 without quotes)"
        if value.strip().lower().lstrip("+-") in ("inf", "infinity", "nan"):
            return ""
        return " (numbers are written in decimal only: 1000, 0.5, 1.0e+3)"
    return ""


def _kind(value: Any) -> str:
    """The value received, for a message: at most about 80 characters."""
    return echo(value)


_TOP = ("name", "seed", "workspace", "robots", "obstacles", "start", "target", "targets", "planner", "sim",
        "render", "paper")
MAX_TARGETS = 16  # legs of a chained scenario
_NAME_RE = re.compile(r"[A-Za-z0-9][A-Za-z0-9._-]*")


def read_scenario(path: str | Path, overrides: dict | None = None) -> Scenario:
    """Parse and check a scenario file; raise :class:`ScenarioError` when it is wrong.

    ``overrides`` (``{"robots.margin": 0.2}``, see :mod:`sim.overrides`) are set in the
    YAML document before it is checked; an error they cause names their ``--set`` option.
    """
    if not overrides:
        return _read_scenario(path, None)
    from .overrides import blame

    try:
        return _read_scenario(path, overrides)
    except ScenarioError as exc:
        raise blame(exc, overrides) from None


def _read_scenario(path: str | Path, overrides: dict | None) -> Scenario:
    path = Path(path)
    r = _Reader(str(path))
    try:
        text = read_text(path, MAX_FILE_BYTES)
    except UnreadableFile as exc:
        r.fail("file", str(exc))
    try:
        doc = load_yaml(text)
    except YamlRefused as exc:
        r.fail(exc.where, exc.reason)
    if doc is None:
        r.fail("file", "is empty; expected a mapping with at least start and target")
    if not isinstance(doc, dict):
        r.fail("file", f"must hold a mapping with at least start and target, got {_kind(doc)}")
    if overrides:
        from .overrides import apply_overrides

        doc = apply_overrides(doc, overrides)
    doc = r.mapping(doc, "", _TOP)
    if "start" not in doc:
        r.fail("start", "is required")
    if "target" in doc and "targets" in doc:
        r.fail("targets", "give either target (one) or targets (a chain), not both")
    if "target" not in doc and "targets" not in doc:
        r.fail("target", "is required (or targets, a list of formations reached in turn)")

    name = doc["name"] if "name" in doc else path.stem
    if not isinstance(name, str) or not _NAME_RE.fullmatch(name) or len(name) > _MAX_NAME:
        r.fail("name", f"must be 1 to {_MAX_NAME} letters, digits, '.', '_', '-' (a letter or digit "
               f"first), got {_kind(name)}")
    seed = r.integer(doc.get("seed", 0), "seed", ge=0, le=_MAX_SEED)
    width, height = r.pair(doc.get("workspace", [40, 40]), "workspace", ge=1, le=_MAX_SIDE)

    rob = r.mapping(doc.get("robots"), "robots", ("radius", "margin", "count", "max_speed", "max_accel"))
    radius = r.number(rob.get("radius", 1.0), "robots.radius", ge=0.01, le=100)
    margin = r.number(rob.get("margin", 0.1), "robots.margin", ge=0, le=100)
    count = None if rob.get("count") is None else r.integer(rob["count"], "robots.count", ge=1, le=_MAX_ROBOTS)
    max_speed = r.number(rob.get("max_speed", 2.0), "robots.max_speed", ge=0.001, le=1000)
    max_accel = r.number(rob.get("max_accel", 2.0), "robots.max_accel", ge=0.001, le=10000)

    obstacles = _read_obstacles(r, doc.get("obstacles", []), width, height)
    base = path.parent
    start = _read_placement(r, doc["start"], "start", width, height, base)
    targets: tuple[FormationSpec, ...] = ()
    if "targets" in doc:
        legs = doc["targets"]
        if not isinstance(legs, list) or not 1 <= len(legs) <= MAX_TARGETS:
            r.fail("targets", f"must be a list of 1 to {MAX_TARGETS} formations, got {_kind(legs)}")
        targets = tuple(_read_placement(r, v, f"targets[{i}]", width, height, base, chained=True)
                        for i, v in enumerate(legs))
        target = targets[-1]
    else:
        target = _read_placement(r, doc["target"], "target", width, height, base)
    specs = [("start", start)] + ([(f"targets[{i}]", t) for i, t in enumerate(targets)] or [("target", target)])
    count = _resolve_count(r, count, specs, width, height, 2 * radius + margin, radius + margin)
    sim = _read_sim(r, doc.get("sim"), count)
    _check_sampling(r, radius, max_speed, sim)

    return Scenario(
        path=str(path),
        name=name,
        seed=seed,
        width=width,
        height=height,
        radius=radius,
        margin=margin,
        count=count,
        max_speed=max_speed,
        max_accel=max_accel,
        obstacles=obstacles,
        start=start,
        target=target,
        planner=_read_planner(r, doc.get("planner")),
        sim=sim,
        render=_read_render(r, doc.get("render")),
        paper=_read_paper(r, doc.get("paper")),
        targets=targets,
    )


def _read_paper(r: _Reader, value) -> PaperRef | None:
    if value is None:
        return None
    v = r.mapping(value, "paper", ("table", "row", "time_s"))
    for key in ("table", "row", "time_s"):
        if key not in v:
            r.fail(f"paper.{key}", "is required")
    if v["table"] not in ("II", "III"):
        r.fail("paper.table", f"must be II or III, got {_kind(v['table'])}")
    return PaperRef(
        table=v["table"],
        row=r.integer(v["row"], "paper.row", ge=1, le=1000),
        time_s=r.number(v["time_s"], "paper.time_s", gt=0, le=1e6),
    )


def _check_sampling(r: _Reader, radius: float, max_speed: float, sim: SimParams) -> None:
    """A robot at full speed moves at most half its radius between two monitor samples."""
    if max_speed * sim.dt > radius / 2:
        r.fail("sim.dt", f"must be <= robots.radius / (2 max_speed) = {radius / (2 * max_speed):.3g} s "
               f"(the monitor samples every dt), got {sim.dt:g}")


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


_SCATTER = "scatter"
MAX_HOLD = 60.0  # [s]


def _read_placement(r: _Reader, value, f: str, width, height, base: Path = Path("."), *,
                    chained: bool = False) -> FormationSpec:
    if not isinstance(value, dict):
        r.fail(f, f"must be a mapping with formation or points, got {_kind(value)}")
    extra = ("hold",) if chained else ()
    hold = 0.0
    if chained:
        hold = r.number(value.get("hold", 2.0), f"{f}.hold", ge=0, le=MAX_HOLD)
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


def _read_planner(r: _Reader, value) -> PlannerParams:
    v = r.mapping(value, "planner", tuple(f.name for f in fields(PlannerParams)))
    d = PlannerParams()
    return PlannerParams(
        g=r.int_or_auto(v.get("g", "auto"), "planner.g", le=100),
        q=r.int_or_auto(v.get("q", "auto"), "planner.q", le=100_000),
        time_limit=r.number(v.get("time_limit", d.time_limit), "planner.time_limit", gt=0, le=3600),
        n=r.int_or_auto(v.get("n", "auto"), "planner.n", ge=2, le=2000),
        extra=r.int_or_auto(v.get("extra", "auto"), "planner.extra", ge=0, le=1000),
        concurrent=r.boolean(v.get("concurrent", d.concurrent), "planner.concurrent"),
        margin_extra=r.number(v.get("margin_extra", d.margin_extra), "planner.margin_extra", ge=0, le=100),
    )


def _read_sim(r: _Reader, value, count: int) -> SimParams:
    v = r.mapping(value, "sim", tuple(f.name for f in fields(SimParams)))
    d = SimParams()
    rate = v.get("control_rate", d.control_rate)
    rate = None if rate is None or (rate == 0 and not isinstance(rate, bool)) else rate
    return SimParams(
        mass=r.number(v.get("mass", d.mass), "sim.mass", ge=0.001, le=1000),
        kp=r.number(v.get("kp", d.kp), "sim.kp", gt=0, le=1e5),
        kd=r.number(v.get("kd", d.kd), "sim.kd", ge=0, le=1e4),
        dt=r.number(v.get("dt", d.dt), "sim.dt", ge=1e-4, le=0.1),
        substeps=r.integer(v.get("substeps", d.substeps), "sim.substeps", ge=1, le=100),
        force_limit=r.number(v.get("force_limit", d.force_limit), "sim.force_limit", gt=0, le=1e6),
        settle_time=r.number(v.get("settle_time", d.settle_time), "sim.settle_time", ge=0, le=600),
        tolerance=r.number(v.get("tolerance", d.tolerance), "sim.tolerance", ge=1e-4, le=100),
        control_rate=None if rate is None else r.number(rate, "sim.control_rate", ge=1, le=10000),
        latency=r.number(v.get("latency", d.latency), "sim.latency", ge=0, le=1),
        noise=_read_noise(r, v.get("noise")),
        mass_error=r.number(v.get("mass_error", d.mass_error), "sim.mass_error", ge=0, le=0.9),
        friction=r.number(v.get("friction", d.friction), "sim.friction", ge=0, le=10),
        disturbances=_read_impulses(r, v.get("disturbances"), count),
        pushes=_read_pushes(r, v.get("pushes")),
        failures=_read_failures(r, v.get("failures"), count),
        recovery=_read_recovery(r, v.get("recovery")),
    )


_MAX_EVENTS = 10_000  # scheduled disturbances or failures in one scenario
_MAX_TIME = 1e5  # [s] latest time of a scheduled event


def _read_noise(r: _Reader, value) -> Noise:
    v = r.mapping(value, "sim.noise", ("position", "velocity"))
    return Noise(
        position=r.number(v.get("position", 0.0), "sim.noise.position", ge=0, le=10),
        velocity=r.number(v.get("velocity", 0.0), "sim.noise.velocity", ge=0, le=10),
    )


def _event_list(r: _Reader, value, field: str) -> list:
    if value is None:
        return []
    if not isinstance(value, list):
        r.fail(field, f"must be a list, got {_kind(value)}")
    if len(value) > _MAX_EVENTS:
        r.fail(field, f"has {len(value)} entries, at most {_MAX_EVENTS} allowed")
    return value


def _robot(r: _Reader, value, field: str, count: int) -> int:
    i = r.integer(value, field, ge=0)
    if i >= count:
        r.fail(field, f"must be a robot index below {count} (robots.count), got {i}")
    return i


def _read_impulses(r: _Reader, value, count: int) -> tuple[Impulse, ...]:
    out = []
    for k, item in enumerate(_event_list(r, value, "sim.disturbances")):
        f = f"sim.disturbances[{k}]"
        e = r.mapping(item, f, ("robot", "time", "impulse"))
        for key in ("robot", "time", "impulse"):
            if key not in e:
                r.fail(f"{f}.{key}", "is required")
        imp = r.pair(e["impulse"], f"{f}.impulse")
        if max(abs(imp[0]), abs(imp[1])) > 1e4:
            r.fail(f"{f}.impulse", f"components must be within [-1e4, 1e4] N s, got [{imp[0]:g}, {imp[1]:g}]")
        out.append(Impulse(_robot(r, e["robot"], f"{f}.robot", count),
                           r.number(e["time"], f"{f}.time", ge=0, le=_MAX_TIME), imp))
    return tuple(out)


def _read_pushes(r: _Reader, value) -> Pushes:
    v = r.mapping(value, "sim.pushes", ("rate", "impulse"))
    return Pushes(
        rate=r.number(v.get("rate", 0.0), "sim.pushes.rate", ge=0, le=100),
        impulse=r.number(v.get("impulse", 0.0), "sim.pushes.impulse", ge=0, le=1e4),
    )


def _read_failures(r: _Reader, value, count: int) -> tuple[Failure, ...]:
    out, seen = [], set()
    for k, item in enumerate(_event_list(r, value, "sim.failures")):
        f = f"sim.failures[{k}]"
        e = r.mapping(item, f, ("robot", "time"))
        for key in ("robot", "time"):
            if key not in e:
                r.fail(f"{f}.{key}", "is required")
        robot = _robot(r, e["robot"], f"{f}.robot", count)
        if robot in seen:
            r.fail(f"{f}.robot", f"robot {robot} already fails earlier in the list")
        seen.add(robot)
        out.append(Failure(robot, r.number(e["time"], f"{f}.time", ge=0, le=_MAX_TIME)))
    return tuple(out)


def _read_recovery(r: _Reader, value) -> Recovery:
    v = r.mapping(value, "sim.recovery", ("replan", "trigger", "time_limit", "max_replans"))
    d = Recovery()
    max_replans = r.integer(v.get("max_replans", d.max_replans), "sim.recovery.max_replans", ge=1)
    if max_replans > 100:
        r.fail("sim.recovery.max_replans", f"must be <= 100, got {max_replans}")
    return Recovery(
        replan=r.boolean(v.get("replan", d.replan), "sim.recovery.replan"),
        trigger=r.number(v.get("trigger", d.trigger), "sim.recovery.trigger", gt=0, le=100),
        time_limit=r.number(v.get("time_limit", d.time_limit), "sim.recovery.time_limit", gt=0, le=600),
        max_replans=max_replans,
    )


def _read_render(r: _Reader, value) -> RenderParams:
    v = r.mapping(value, "render", tuple(f.name for f in fields(RenderParams)))
    d = RenderParams()
    formats = v.get("formats", list(d.formats))
    if isinstance(formats, str):
        formats = [formats]
    if not isinstance(formats, list) or not 1 <= len(formats) <= 2:
        r.fail("render.formats", f"must be a list of gif and/or mp4, got {_kind(formats)}")
    for i, fm in enumerate(formats):
        if fm not in ("gif", "mp4"):
            r.fail(f"render.formats[{i}]", f"unknown format (known: gif, mp4), got {_kind(fm)}")
    speed = v.get("speedup", "auto")
    fps = r.integer(v.get("fps", d.fps), "render.fps", ge=1, le=MAX_FPS)
    if fps > 50 and "gif" in formats:
        r.fail("render.fps", f"must be <= 50 for a GIF (frame delays are whole hundredths of a second), got {fps}")
    return RenderParams(
        fps=fps,
        size=_render_size(r, v.get("size", "auto")),
        trails=r.boolean(v.get("trails", d.trails), "render.trails"),
        formats=tuple(dict.fromkeys(formats)),
        speedup=None if speed == "auto" else r.number(speed, "render.speedup", ge=0.01, le=10_000),
        video_seconds=r.number(v.get("video_seconds", d.video_seconds), "render.video_seconds", ge=1, le=600),
    )


def _render_size(r: _Reader, value) -> int | None:
    return r.int_or_auto(value, "render.size", ge=64, le=MAX_RENDER_SIZE)


# ----------------------------------------------------------------------------
# from spec to problem


def _random_obstacles(spec: RandomObstacles, width, height, rng, avoid, clearance):
    """Random convex polygons: vertices at sorted random angles on a circle."""
    gen = np.random.default_rng(spec.seed) if spec.seed is not None else rng
    out = []
    for _ in range(spec.count):
        for _attempt in range(1000):
            diameter = gen.uniform(spec.size[0], spec.size[1])
            k = int(gen.integers(3, 9))
            ang = np.sort(gen.uniform(0, 2 * np.pi, size=k))
            rad = diameter / 2
            c = gen.uniform([rad, rad], [width - rad, height - rad])
            poly = Polygon(c + rad * np.stack([np.cos(ang), np.sin(ang)], axis=1))
            x, y = poly.vertices[:, 0], poly.vertices[:, 1]
            area = 0.5 * abs(float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y)))
            if area < 0.05 * diameter**2:
                continue  # a sliver; draw again
            if len(avoid):
                env = Environment.build(width, height, [poly])
                if np.any(env.point_clearance(avoid) < clearance):
                    continue
            out.append(poly)
            break
        else:
            raise ProblemError("obstacles", "cannot place a random obstacle clear of the explicit points")
    return out


def build_problem(scenario: Scenario, rng: np.random.Generator) -> Problem:
    """Instantiate the scenario: random obstacles, formations, checks.

    The problem's target is the last target (of a chained scenario:
    :func:`build_legs` gives every one).  Raises :class:`ScenarioError`
    (with the file) for placements that do not fit or overlap.
    """
    return build_legs(scenario, rng)[0]


def build_legs(scenario: Scenario, rng: np.random.Generator) -> tuple[Problem, tuple[np.ndarray, ...]]:
    """The run's problem (start -> last target) and every target placement in order.

    Draws from ``rng`` in a fixed order: random obstacles, then each
    placement from the start on (a single-target scenario draws exactly as
    :func:`build_problem` always has).
    """
    from .placements import make_shape, uses_rng

    s = scenario
    specs = [("start", s.start)] + ([(f"targets[{i}]", t) for i, t in enumerate(s.targets)] or [("target", s.target)])
    try:
        # Formations are spaced for the margin the planner plans with
        # (planner.margin_extra inflates it), so that they fit it too.
        clearance = s.radius + s.margin + s.planner.margin_extra
        sep = 2 * s.radius + s.margin + s.planner.margin_extra
        explicit = [np.asarray(p.points, float) for _, p in specs if p.points is not None]
        avoid = np.concatenate(explicit) if explicit else np.zeros((0, 2))
        obstacles = []
        for ob in s.obstacles:
            if isinstance(ob, RandomObstacles):
                obstacles.extend(_random_obstacles(ob, s.width, s.height, rng, avoid, clearance))
            else:
                obstacles.append(ob)
        # m discs at the separation pack at best hexagonally: sqrt(3)/2 sep^2
        # each, within the workspace shrunk by the wall clearance.
        need = s.count * (np.sqrt(3) / 2) * sep**2
        have = max(s.width - 2 * clearance + sep, 0) * max(s.height - 2 * clearance + sep, 0)
        if need > have:
            raise ProblemError(
                "robots.count",
                f"{s.count} robots need at least {need:.0f} square units at their separation; "
                f"the {s.width:g} x {s.height:g} workspace offers {have:.0f}",
            )
        shell = Problem(s.width, s.height, tuple(obstacles), s.radius, s.margin, np.zeros((0, 2)), np.zeros((0, 2)))
        # Shapes that do not depend on the generator (letters, lines, rings,
        # text strokes, strokes) are built first, so that one that cannot fit
        # at any rotation fails before any random placement is drawn.
        shapes = {}
        reach = float(np.hypot(s.width - 2 * clearance, s.height - 2 * clearance))
        for key, spec in specs:
            if spec.points is None and spec.formation != _SCATTER and not uses_rng(spec):
                shape = _shape(make_shape, spec, s, sep, rng, key)
                span = float(np.max(np.linalg.norm(shape[:, None] - shape[None], axis=2)))
                if span > reach:
                    raise ProblemError(
                        key,
                        f"formation {spec.describe()} of {s.count} robots spans {span:.3g} and does not fit "
                        f"the {s.width:g} x {s.height:g} workspace at any rotation; lower robots.count",
                    )
                shapes[key] = shape
        placed = []
        for key, spec in specs:
            if spec.points is not None:
                pts = np.asarray(spec.points, float)
                check_placement(shell, pts, f"{key}.points")
            elif spec.formation == _SCATTER:
                from planner.scatter import scatter

                pts = scatter(shell.env, s.count, sep, clearance, rng, region=spec.region, field=key)
                check_placement(shell, pts, key)
            else:
                shape = shapes.get(key)
                if shape is None:
                    shape = _shape(make_shape, spec, s, sep, rng, key)
                pts = place_formation(
                    shape,
                    shell.env,
                    clearance,
                    rotation=spec.rotation,
                    center=spec.center,
                    rng=rng,
                    field=key,
                )
                check_placement(shell, pts, key)
            placed.append(pts)
        problem = Problem(
            s.width,
            s.height,
            tuple(obstacles),
            s.radius,
            s.margin,
            placed[0],
            placed[-1],
            max_speed=s.max_speed,
            max_accel=s.max_accel,
        )
        return problem.validate(), tuple(placed[1:])
    except ProblemError as exc:
        raise ScenarioError(s.path, exc.field, exc.reason) from None


def _shape(make_shape, spec: FormationSpec, s: Scenario, sep: float, rng, key: str) -> np.ndarray:
    """The spec's shape at its scale; a sampler's refusal becomes a :class:`ProblemError` on ``key``."""
    from .placements import formation_side

    try:
        side = formation_side(spec, s.width, s.height, s.radius + s.margin)
        return make_shape(spec, s.count, side, sep, rng)
    except ValueError as exc:
        raise ProblemError(f"{key}.formation", str(exc)) from None
