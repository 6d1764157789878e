"""Two independent contact witnesses for a physics run.

* :class:`PymunkWitness` listens to pymunk's collision callbacks
  (``Space.on_collision``) for robot-robot, robot-obstacle and robot-wall
  pairs.  A *touching episode* of a pair (two robots, or a robot and one
  obstacle or the wall, however many convex pieces it touches) opens with
  the first ``begin`` and closes when its last arbiter separates; each
  episode is one :class:`Contact`, timed at the end of the physics step in
  which it began, with the deepest penetration seen during the episode
  (``-ContactPoint.distance``).
* :class:`GapMonitor` measures, at every recorded sample, the exact gap
  between every pair of disc boundaries and between every disc and every
  obstacle and the walls (signed: negative means overlap).  Work is
  skipped only where a bound proves it cannot matter: robot pairs too far
  apart to touch or to set a new minimum (a Verlet list per few samples),
  polygons whose bounding box is farther than the nearest wall or circle.  It keeps the
  smallest gap and where it occurred, and opens one :class:`Contact` per
  pair and touching episode (the first sample with a gap ``< 0``; the depth
  is the largest overlap during the episode).  It also keeps the smallest
  gap of every sample (:attr:`GapMonitor.series`), exact up to a cap of one
  robot diameter (:data:`SERIES_CAP` radii): larger gaps are recorded as
  the cap.

A run is clean only when neither witness saw anything.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .kernels import circle_clearance, polygon_signed_distance, wall_clearance
from .world import OBSTACLE, ROBOT, WALL

__all__ = [
    "ROBOT_OBSTACLE",
    "ROBOT_ROBOT",
    "ROBOT_WALL",
    "Contact",
    "PymunkWitness",
    "static_clearances",
]

ROBOT_ROBOT = "robot-robot"
ROBOT_OBSTACLE = "robot-obstacle"
ROBOT_WALL = "robot-wall"


@dataclass(frozen=True)
class Contact:
    """One touching episode seen by one witness.

    time: when it began [s].
    kind: ``robot-robot``, ``robot-obstacle`` or ``robot-wall``.
    a: robot index (the smaller one for ``robot-robot``).
    b: the other robot (``robot-robot``), the obstacle index
        (``robot-obstacle``) or ``-1`` (``robot-wall``).
    depth: the deepest overlap during the episode, ``>= 0`` [workspace units].
    witness: ``pymunk`` or ``monitor``.
    swept: seen only between two samples, by the monitor's swept check
        (``time`` is then the closest approach and ``depth`` the overlap there).
    """

    time: float
    kind: str
    a: int
    b: int
    depth: float
    witness: str
    swept: bool = False

    def to_dict(self) -> dict:
        d = {
            "time": self.time,
            "kind": self.kind,
            "a": self.a,
            "b": self.b,
            "depth": self.depth,
            "witness": self.witness,
        }
        if self.swept:
            d["swept"] = True
        return d

    def describe(self) -> str:
        if self.kind == ROBOT_ROBOT:
            who = f"robots {self.a} and {self.b}"
        elif self.kind == ROBOT_WALL:
            who = f"robot {self.a} and the wall"
        else:
            who = f"robot {self.a} and obstacle {self.b}"
        between = ", between samples" if self.swept else ""
        return f"{who} touch at t = {self.time:.3f} s, depth {self.depth:.3g} ({self.witness}{between})"


def _contacts(records: list[list], witness: str) -> list[Contact]:
    """Records ``[time, kind, a, b, depth]``, with ``True`` appended for a swept one."""
    return [Contact(float(r[0]), r[1], int(r[2]), int(r[3]), float(r[4]), witness, len(r) > 5) for r in records]


# -- pymunk's witness -------------------------------------------------------------


class PymunkWitness:
    """Records pymunk's ``begin`` events as touching episodes.

    ``now`` must hold the time at the end of the physics step about to run
    (the executor sets it before every ``space.step``); a ``begin`` during
    that step is stamped with it.
    """

    def __init__(self, world):
        self.now = 0.0
        self._robot_of = world.robot_of
        self._obstacle_of = world.obstacle_of
        self._records: list[list] = []  # [time, kind, a, b, depth]
        self.speed_warnings: list[str] = []  # physics steps in which a body could tunnel (SpeedGuard)
        self._open: dict[tuple, list] = {}  # key -> [arbiter count, record]
        space = world.space
        for other in (ROBOT, OBSTACLE, WALL):
            space.on_collision(
                ROBOT,
                other,
                begin=self._begin,
                pre_solve=self._pre_solve,
                separate=self._separate,
            )

    def _key(self, arbiter) -> tuple[str, int, int]:
        sa, sb = arbiter.shapes
        ra = self._robot_of.get(sa)
        rb = self._robot_of.get(sb)
        if ra is not None and rb is not None:
            return (ROBOT_ROBOT, min(ra, rb), max(ra, rb))
        if ra is None:
            ra, sb = rb, sa
        ob = self._obstacle_of[sb]
        return (ROBOT_WALL, ra, -1) if ob < 0 else (ROBOT_OBSTACLE, ra, ob)

    @staticmethod
    def _depth(arbiter) -> float:
        pts = arbiter.contact_point_set.points
        return max([0.0] + [-p.distance for p in pts])

    def _begin(self, arbiter, space, data) -> None:
        key = self._key(arbiter)
        entry = self._open.get(key)
        depth = self._depth(arbiter)
        if entry is None:
            record = [self.now, key[0], key[1], key[2], depth]
            self._records.append(record)
            self._open[key] = [1, record]
        else:
            entry[0] += 1
            entry[1][4] = max(entry[1][4], depth)

    def _pre_solve(self, arbiter, space, data) -> None:
        entry = self._open.get(self._key(arbiter))
        if entry is not None:
            entry[1][4] = max(entry[1][4], self._depth(arbiter))

    def _separate(self, arbiter, space, data) -> None:
        key = self._key(arbiter)
        entry = self._open.get(key)
        if entry is not None:
            entry[0] -= 1
            if entry[0] <= 0:
                del self._open[key]

    def contacts(self) -> list[Contact]:
        return _contacts(self._records, "pymunk")


# -- the geometric monitor -------------------------------------------------------------


def static_clearances(env, points: np.ndarray, n_obstacles: int, below: float | None = None) -> np.ndarray:
    """Signed clearance of centres to every obstacle and to the walls.

    Returns ``(N, n_obstacles + 1)``: column ``k`` is obstacle ``k``, the
    last column the walls.  Distances are from the centre to the obstacle
    set (a polygon's edges, a circle's rim, the nearest wall line),
    negative when the centre is inside it; subtract the radius for the gap
    of a disc.  Where a centre is outside every obstacle, the row minimum
    equals :meth:`planner.geometry.Environment.point_clearance` (computed
    here with the witnesses' own kernels, :mod:`sim.execute.kernels`).

    With ``below`` given (a number, or one per point), a polygon entry is
    exact only where it is less than ``below``; elsewhere it may be any
    lower bound that is at least ``below`` (the distance to the polygon's
    bounding box), which is all a search for the minimum or for overlaps
    needs.
    """
    pts = np.asarray(points, float).reshape(-1, 2)
    out = np.empty((len(pts), n_obstacles + 1))
    out[:, -1] = wall_clearance(pts, env.width, env.height)
    if len(env.circle_radii):
        out[:, list(env.circle_ids)] = circle_clearance(pts, env.circle_centers, env.circle_radii)
    for i, poly in enumerate(env.polygons):
        col = env.polygon_ids[i]
        if below is None:
            sel = slice(None)
        else:
            lo, hi = poly.min(axis=0), poly.max(axis=0)
            gap = np.maximum(np.maximum(lo - pts, pts - hi), 0.0)
            bound = np.sqrt(np.einsum("nk,nk->n", gap, gap))
            sel = np.flatnonzero(bound < below)
            out[:, col] = bound
            if len(sel) == 0:
                continue
        out[sel, col] = polygon_signed_distance(pts[sel], poly)
    return out


# -- speed: what both witnesses need between samples ---------------------------------------

