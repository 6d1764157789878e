"""What a checked scenario is: its frozen specs, its error, and the bounds its fields share."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from planner.inputfile import echo_path
from planner.params import PlannerParams
from planner.problem import Circle, Polygon

from .params import RenderParams, SimParams

__all__ = ["FormationSpec", "MAX_FILE_BYTES", "PaperRef", "RandomObstacles", "Scenario", "ScenarioError"]


MAX_FILE_BYTES = 2 << 20
"""The largest scenario file read [bytes]: 2 MiB, room for 5000 explicit start and target
points at full precision (5000 of each with three decimals take 195 KB and read in 0.2 s)."""

# Bounds shared by several fields (see the README's input table).
_MAX_SIDE = 1000.0  # workspace side [units]
_MAX_MAP_SIDE = 4000.0  # side of a workspace read from a map [units]: orz900d (1491 cells) at cell 2.4 is 3578
_MAX_ROBOTS = 5000  # measured: 5000 scattered to scattered at 10 % coverage plan in 31 s, 1.2 GB
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
    #: the world position of a map's lower-left corner (``map.origin`` or a ROS map's own), else None
    map_origin: tuple[float, float] | None = None

    @property
    def legs(self) -> tuple[FormationSpec, ...]:
        """The targets in the order they are reached (``target`` alone unless chained)."""
        return self.targets or (self.target,)

    def describe(self) -> str:
        """``start -> target`` (every target of a chain)."""
        return " -> ".join(spec.describe() for spec in (self.start, *self.legs))

    def planner_params(self, time_limit: float | None = None, spent: float = 0.0) -> PlannerParams:
        """The planner's parameters for a run: its time limit ``time_limit`` (a
        ``--time-limit``) or the scenario's, less ``spent``, the seconds that reading
        the scenario, its map and its formations took, so that the run as a whole keeps
        to the limit; never under a twentieth of it (the planner always gets a try)."""
        from dataclasses import replace

        limit = self.planner.time_limit if time_limit is None else float(time_limit)
        limit = max(limit - max(float(spent), 0.0), limit / 20.0)
        return replace(self.planner, time_limit=limit)

    def generator(self, seed: int | None = None) -> np.random.Generator:
        """The run's one generator, seeded with ``seed`` (default: the scenario's).

        Every random choice of a run (random obstacles, rotations, centres, scatter,
        the planner, the physics' streams) draws from it, in a fixed order; this is the
        only place a run's generator is made.
        """
        return np.random.default_rng(self.seed if seed is None else seed)


# ----------------------------------------------------------------------------
# field readers
