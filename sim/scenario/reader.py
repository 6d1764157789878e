"""Scenario files: strict YAML loading into frozen specs, then a Problem.

``read_scenario(path)`` parses and checks the file (unknown keys, wrong
types and values outside each field's documented range are rejected with
a :class:`ScenarioError` naming the file, the field and the reason, with
the value received echoed in at most about 80 characters).  The file is
read only when it is a regular file of at most :data:`MAX_FILE_BYTES`; its
YAML may not use anchors, aliases, tags or nesting deeper than
:data:`sim.scenario.yamlfile.MAX_DEPTH` (:mod:`sim.scenario.yamlfile`).  Every field's range
is chosen so that time and memory stay bounded; the README's input table
lists them (unit, default, range), and a test holds it to this code.  ``build_problem(scenario,
rng)`` turns the spec into a :class:`planner.Problem`: it draws the random
obstacles, the formations' rotations and centres from ``rng`` and checks
the placements (robot index and what it hits).
"""


from __future__ import annotations

import re
from pathlib import Path

from planner.inputfile import UnreadableFile, read_text

from .fields import _kind, _Reader
from .formation_fields import _read_placement, _resolve_count
from .model import (
    _MAX_NAME,
    _MAX_ROBOTS,
    _MAX_SEED,
    _MAX_SIDE,
    MAX_FILE_BYTES,
    FormationSpec,
    PaperRef,
    Scenario,
    ScenarioError,
)
from .obstacles import _read_map, _read_obstacles
from .params import SimParams
from .settings import _read_planner, _read_render, _read_sim
from .yamlfile import YamlRefused, load_yaml

__all__ = ["MAX_TARGETS", "read_scenario"]


_TOP = ("name", "seed", "workspace", "map", "robots", "obstacles", "start", "target", "targets", "planner", "sim",
        "render", "paper")
MAX_TARGETS = 16  # legs of a chained scenario
_NAME_RE = re.compile(r"[A-Za-z0-9][A-Za-z0-9._-]*")


def read_scenario(path: str | Path, overrides: dict | None = None) -> Scenario:
    """Parse and check a scenario file; raise :class:`ScenarioError` when it is wrong.

    ``overrides`` (``{"robots.margin": 0.2}``, see :mod:`sim.scenario.overrides`) are set in the
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
    grid_map = None
    if "map" in doc:
        if "workspace" in doc:
            r.fail("workspace", "is set by map (columns x cell by rows x cell); give workspace or map, not both")
        grid_map = _read_map(r, doc["map"], path.parent)
        width, height = grid_map.width, grid_map.height
    else:
        width, height = r.pair(doc.get("workspace", [40, 40]), "workspace", ge=1, le=_MAX_SIDE)

    rob = r.mapping(doc.get("robots"), "robots", ("radius", "margin", "count", "max_speed", "max_accel"))
    radius = r.number(rob.get("radius", 1.0), "robots.radius", ge=0.01, le=100)
    margin = r.number(rob.get("margin", 0.1), "robots.margin", ge=0, le=100)
    count = None if rob.get("count") is None else r.integer(rob["count"], "robots.count", ge=1, le=_MAX_ROBOTS)
    max_speed = r.number(rob.get("max_speed", 2.0), "robots.max_speed", ge=0.001, le=1000)
    max_accel = r.number(rob.get("max_accel", 2.0), "robots.max_accel", ge=0.001, le=10000)

    obstacles = _read_obstacles(r, doc.get("obstacles", []), width, height)
    if grid_map is not None:
        obstacles = grid_map.obstacles + obstacles
    _check_scen_counts(r, doc, count)
    base = path.parent
    start = _read_placement(r, doc["start"], "start", width, height, base, grid=grid_map)
    targets: tuple[FormationSpec, ...] = ()
    if "targets" in doc:
        legs = doc["targets"]
        if not isinstance(legs, list) or not 1 <= len(legs) <= MAX_TARGETS:
            r.fail("targets", f"must be a list of 1 to {MAX_TARGETS} formations, got {_kind(legs)}")
        targets = tuple(_read_placement(r, v, f"targets[{i}]", width, height, base, chained=True, grid=grid_map)
                        for i, v in enumerate(legs))
        target = targets[-1]
    else:
        target = _read_placement(r, doc["target"], "target", width, height, base, grid=grid_map)
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
        map_origin=None if grid_map is None else grid_map.origin,
    )


def _check_scen_counts(r: _Reader, doc: dict, count: int | None) -> None:
    """``robots.count``, when given, equals the ``count`` of every placement taken from a .scen."""
    legs = [("start", doc["start"])] + ([("target", doc["target"])] if "target" in doc else [])
    if isinstance(doc.get("targets"), list):
        legs += [(f"targets[{i}]", v) for i, v in enumerate(doc["targets"])]
    for key, v in legs:
        if count is not None and isinstance(v, dict) and "scen" in v and v.get("count") != count:
            n = v.get("count")
            shown = n if isinstance(n, int) and not isinstance(n, bool) else _kind(n)
            r.fail("robots.count", f"is {count} but {key}.count takes {shown} agents from its .scen")


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
