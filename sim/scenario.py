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

from planner.formations import DEFAULT_COUNTS, formation_shape, place_formation
from planner.geometry import Environment
from planner.inputfile import HugeInt, UnreadableFile, echo, echo_key, echo_path, read_text
from planner.params import PlannerParams
from planner.problem import Circle, Polygon, Problem, ProblemError, check_placement

from .params import RenderParams, SimParams
from .yamlfile import YamlRefused, load_yaml

__all__ = [
    "FormationSpec",
    "MAX_FILE_BYTES",
    "PaperRef",
    "RandomObstacles",
    "Scenario",
    "ScenarioError",
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
# obstacle counts as 8, the most it has).  The planner's corner-visibility
# graph holds temporaries of about (corners^2 x edges) floats: 32 random
# obstacles of up to 8 vertices peaked at 1.1 GB in dense workspaces.
_MAX_OBSTACLES = 32
_MAX_VERTICES = 192
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
    """Either a named formation (with scale, rotation, centre) or explicit points.

    rotation ``None`` and center ``None`` mean random.
    """

    formation: str | None = None
    scale: float = 0.3
    rotation: float | None = None
    center: tuple[float, float] | None = None
    points: tuple[tuple[float, float], ...] | None = None

    def describe(self) -> str:
        return "points" if self.points is not None else str(self.formation)


@dataclass(frozen=True)
class PaperRef:
    """Where a scenario comes from in the paper: table, row and reported time [s]."""

    table: str
    row: int
    time_s: float


@dataclass(frozen=True)
class Scenario:
    """A checked scenario file.  Lengths in workspace units, speeds in units/s."""

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
        return " (text; write a number such as 1.0e+3 without quotes)"
    return ""


def _kind(value: Any) -> str:
    """The value received, for a message: at most about 80 characters."""
    return echo(value)


_TOP = ("name", "seed", "workspace", "robots", "obstacles", "start", "target", "planner", "sim", "render", "paper")
_NAME_RE = re.compile(r"[A-Za-z0-9][A-Za-z0-9._-]*")


def read_scenario(path: str | Path) -> Scenario:
    """Parse and check a scenario file; raise :class:`ScenarioError` when it is wrong."""
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
    doc = r.mapping(doc, "", _TOP)
    for key in ("start", "target"):
        if key not in doc:
            r.fail(key, "is required")

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
    start = _read_placement(r, doc["start"], "start", width, height)
    target = _read_placement(r, doc["target"], "target", width, height)
    count = _resolve_count(r, count, start, target)
    sim = _read_sim(r, doc.get("sim"))
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
    """A simple polygon of 3 to 192 vertices in the workspace (checked in O(k log k))."""
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


def _read_placement(r: _Reader, value, f: str, width, height) -> FormationSpec:
    if not isinstance(value, dict):
        r.fail(f, f"must be a mapping with formation or points, got {_kind(value)}")
    if "points" in value:
        r.mapping(value, f, ("points",))
        pts = value["points"]
        if not isinstance(pts, list) or not 1 <= len(pts) <= _MAX_ROBOTS:
            r.fail(f"{f}.points", f"must be a list of 1 to {_MAX_ROBOTS} points [x, y], got {_kind(pts)}")
        return FormationSpec(points=tuple(r.pair(p, f"{f}.points[{i}]") for i, p in enumerate(pts)))
    v = r.mapping(value, f, ("formation", "scale", "rotation", "center"))
    if "formation" not in v:
        r.fail(f, "needs formation or points")
    name = v["formation"]
    if not isinstance(name, str) or name not in DEFAULT_COUNTS:
        r.fail(f"{f}.formation", f"unknown formation (known: {', '.join(DEFAULT_COUNTS)}), got {_kind(name)}")
    scale = r.number(v.get("scale", 0.3), f"{f}.scale", gt=0, le=1)
    rot = v.get("rotation", "random")
    rotation = None if rot == "random" else r.number(rot, f"{f}.rotation", ge=-360, le=360)
    cen = v.get("center", "random")
    center = None
    if cen != "random":
        center = r.inside(cen, f"{f}.center", width, height)
    return FormationSpec(formation=name, scale=scale, rotation=rotation, center=center)


def _resolve_count(r: _Reader, count, start: FormationSpec, target: FormationSpec) -> int:
    sizes = {}
    for key, spec in (("start", start), ("target", target)):
        if spec.points is not None:
            sizes[key] = (len(spec.points), f"{key}.points")
    if len(sizes) == 2 and sizes["start"][0] != sizes["target"][0]:
        r.fail(
            "target.points",
            f"has {sizes['target'][0]} robots but start.points has {sizes['start'][0]}",
        )
    if sizes:
        key, (n, where) = next(iter(sizes.items()))
        if count is not None and count != n:
            r.fail("robots.count", f"is {count} but {where} has {n} points")
        count = n
    if count is None:
        defaults = {}
        for key, spec in (("start", start), ("target", target)):
            d = DEFAULT_COUNTS[spec.formation]
            if d is not None:
                defaults[key] = d
        if not defaults:
            r.fail(
                "robots.count",
                f"is required: {start.formation} -> {target.formation} has no default count",
            )
        if len(set(defaults.values())) > 1:
            r.fail(
                "robots.count",
                f"count mismatch: start {start.formation} has {defaults['start']} robots, "
                f"target {target.formation} has {defaults['target']}; set robots.count",
            )
        count = next(iter(defaults.values()))
    if count < 2 and (start.points is None or target.points is None):
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
    )


def _read_sim(r: _Reader, value) -> SimParams:
    v = r.mapping(value, "sim", tuple(f.name for f in fields(SimParams)))
    d = SimParams()
    return SimParams(
        mass=r.number(v.get("mass", d.mass), "sim.mass", ge=0.001, le=1000),
        kp=r.number(v.get("kp", d.kp), "sim.kp", gt=0, le=1e5),
        kd=r.number(v.get("kd", d.kd), "sim.kd", ge=0, le=1e4),
        dt=r.number(v.get("dt", d.dt), "sim.dt", ge=1e-4, le=0.1),
        substeps=r.integer(v.get("substeps", d.substeps), "sim.substeps", ge=1, le=100),
        force_limit=r.number(v.get("force_limit", d.force_limit), "sim.force_limit", gt=0, le=1e6),
        settle_time=r.number(v.get("settle_time", d.settle_time), "sim.settle_time", ge=0, le=600),
        tolerance=r.number(v.get("tolerance", d.tolerance), "sim.tolerance", ge=1e-4, le=100),
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
    fps = r.integer(v.get("fps", d.fps), "render.fps", ge=1, le=120)
    if fps > 50 and "gif" in formats:
        r.fail("render.fps", f"must be <= 50 for a GIF (frame delays are whole hundredths of a second), got {fps}")
    return RenderParams(
        fps=fps,
        size=r.integer(v.get("size", d.size), "render.size", ge=64, le=2048),
        trails=r.boolean(v.get("trails", d.trails), "render.trails"),
        formats=tuple(dict.fromkeys(formats)),
        speedup=None if speed == "auto" else r.number(speed, "render.speedup", ge=0.01, le=10_000),
        video_seconds=r.number(v.get("video_seconds", d.video_seconds), "render.video_seconds", ge=1, le=600),
    )


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

    Raises :class:`ScenarioError` (with the file) for placements that do not
    fit or overlap.
    """
    s = scenario
    try:
        clearance = s.radius + s.margin
        sep = 2 * s.radius + s.margin
        explicit = [np.asarray(p.points, float) for p in (s.start, s.target) if p.points is not None]
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
        # Letters and lines do not depend on the generator: build them first
        # so that one that cannot fit at any rotation fails before any
        # random placement is drawn.
        shapes = {}
        reach = float(np.hypot(s.width - 2 * clearance, s.height - 2 * clearance))
        for key in ("start", "target"):
            spec = getattr(s, key)
            if spec.points is None and spec.formation != "random":
                side = spec.scale * min(s.width, s.height)
                shape = formation_shape(spec.formation, s.count, side, sep, rng)
                span = float(np.max(np.linalg.norm(shape[:, None] - shape[None], axis=2)))
                if span > reach:
                    raise ProblemError(
                        key,
                        f"formation {spec.formation} of {s.count} robots spans {span:.3g} and does not fit "
                        f"the {s.width:g} x {s.height:g} workspace at any rotation; lower robots.count",
                    )
                shapes[key] = shape
        placed = {}
        for key in ("start", "target"):
            spec = getattr(s, key)
            if spec.points is not None:
                pts = np.asarray(spec.points, float)
                check_placement(shell, pts, f"{key}.points")
            else:
                side = spec.scale * min(s.width, s.height)
                shape = shapes.get(key)
                if shape is None:
                    shape = formation_shape(spec.formation, s.count, side, sep, rng)
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
            placed[key] = pts
        problem = Problem(
            s.width,
            s.height,
            tuple(obstacles),
            s.radius,
            s.margin,
            placed["start"],
            placed["target"],
            max_speed=s.max_speed,
            max_accel=s.max_accel,
        )
        return problem.validate()
    except ProblemError as exc:
        raise ScenarioError(s.path, exc.field, exc.reason) from None
