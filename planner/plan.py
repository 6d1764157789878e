"""Timed plans: straight-line steps under one shared minimum-jerk time scaling.

Step ``k`` lasts ``durations[k]`` seconds and moves every robot on a straight
segment from ``waypoints[k]`` to ``waypoints[k + 1]``; all robots follow
``s(t / T_k)`` with ``s(u) = 10u^3 - 15u^4 + 6u^5`` (``s(0) = 0``, ``s(1) = 1``,
zero velocity and acceleration at both ends).  Position, velocity and
acceleration are therefore analytic at any time, and the exact collision
test of a step is the closest approach of linearly interpolated points
(:func:`planner.geometry.closest_approach`).

A step's duration is the shortest that keeps every robot within the speed
and acceleration limits: with ``D`` the longest displacement in the step,
``max s' = 15/8`` and ``max s'' = 10/sqrt(3)``,
``T = max(15/8 * D / v_max, sqrt(10/sqrt(3) * D / a_max))``.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .planfile import (
    MAX_COORDINATE,
    MAX_DURATION,
    MAX_PLAN_BYTES,
    MAX_ROBOTS,
    MAX_STEPS,
    MIN_DURATION,
    PLAN_KEYS,
    PlanFileError,
    _integer,
    _json_int,
    _number,
    _plan_from_dict,
)
from .profile import _S1_MAX, _S2_MAX, PROFILE, min_jerk, min_jerk_s, step_duration
from .stats import PlanStats

__all__ = [
    "LIMIT_RTOL",
    "MAX_COORDINATE",
    "MAX_DURATION",
    "MAX_PLAN_BYTES",
    "MAX_ROBOTS",
    "MAX_STEPS",
    "MIN_DURATION",
    "PROFILE",
    "Plan",
    "PlanFileError",
    "PlanStats",
    "min_jerk",
    "min_jerk_s",
    "note_ignored",
    "read_plan_file",
    "step_duration",
]

LIMIT_RTOL = 1e-6
"""Relative tolerance on max_speed and max_accel when a plan file's steps are checked."""


@dataclass(frozen=True, eq=False)
class Plan:
    """A timed multi-robot plan (see the module docstring for the contract)."""

    radius: float
    margin: float
    durations: np.ndarray  # (K,)
    waypoints: np.ndarray  # (K + 1, m, 2)
    max_speed: float | None = None
    max_accel: float | None = None
    stats: PlanStats | None = None

    def __post_init__(self):
        w = np.array(self.waypoints, dtype=float)
        if w.ndim == 2:
            w = w[None]
        d = np.array(self.durations, dtype=float).reshape(-1)
        if w.ndim != 3 or w.shape[-1] != 2:
            raise ValueError(f"waypoints must be (K+1, m, 2), got {w.shape}")
        if len(d) != len(w) - 1:
            raise ValueError(f"{len(d)} durations for {len(w)} waypoints")
        w.setflags(write=False)
        d.setflags(write=False)
        object.__setattr__(self, "waypoints", w)
        object.__setattr__(self, "durations", d)

    # -- construction ---------------------------------------------------------
    @classmethod
    def from_waypoints(cls, waypoints, radius, margin, max_speed, max_accel, stats=None):
        """Time a waypoint sequence with the fastest durations the limits allow."""
        w = np.asarray(waypoints, float)
        if len(w) > 1:
            disp = np.linalg.norm(np.diff(w, axis=0), axis=2).max(axis=1)
            durations = step_duration(disp, max_speed, max_accel)
        else:
            durations = np.zeros(0)
        return cls(radius, margin, durations, w, max_speed, max_accel, stats)

    # -- derived ----------------------------------------------------------------
    @property
    def m(self) -> int:
        return self.waypoints.shape[1]

    @property
    def steps(self) -> int:
        return len(self.durations)

    @property
    def times(self) -> np.ndarray:
        """Start time of every step, and the end time last: ``(K + 1,)``."""
        return np.concatenate([[0.0], np.cumsum(self.durations)])

    @property
    def makespan(self) -> float:
        return float(self.durations.sum())

    @property
    def path_length(self) -> float:
        return float(np.linalg.norm(np.diff(self.waypoints, axis=0), axis=2).sum())

    @property
    def start(self) -> np.ndarray:
        return self.waypoints[0]

    @property
    def end(self) -> np.ndarray:
        return self.waypoints[-1]

    def state(self, t):
        """Reference position, velocity and acceleration ``(m, 2)`` each at time ``t``."""
        pos, vel, acc = self.sample(np.array([t], float))
        return pos[0], vel[0], acc[0]

    def sample(self, ts: np.ndarray):
        """Positions, velocities, accelerations ``(T, m, 2)`` at times ``ts``."""
        ts = np.asarray(ts, float).reshape(-1)
        times = self.times
        if self.steps == 0:
            pos = np.broadcast_to(self.waypoints[0], (len(ts), self.m, 2)).copy()
            z = np.zeros_like(pos)
            return pos, z, z.copy()
        k = np.clip(np.searchsorted(times, ts, side="right") - 1, 0, self.steps - 1)
        dur = self.durations[k]
        u = np.where(dur > 0, (ts - times[k]) / np.where(dur > 0, dur, 1.0), 1.0)
        s, ds, dds = min_jerk(u)
        delta = self.waypoints[k + 1] - self.waypoints[k]
        with np.errstate(divide="ignore", invalid="ignore"):
            inv = np.where(dur > 0, 1.0 / np.where(dur > 0, dur, 1.0), 0.0)
        pos = self.waypoints[k] + s[:, None, None] * delta
        vel = (ds * inv)[:, None, None] * delta
        acc = (dds * inv * inv)[:, None, None] * delta
        return pos, vel, acc

    # -- files ------------------------------------------------------------------
    def to_dict(self) -> dict:
        d = {
            "radius": self.radius,
            "margin": self.margin,
            "profile": PROFILE,
            "durations": self.durations.tolist(),
            "waypoints": self.waypoints.tolist(),
        }
        if self.max_speed is not None:
            d["max_speed"] = self.max_speed
            d["max_accel"] = self.max_accel
        if self.stats is not None:
            d["stats"] = self.stats.to_dict()
        return d

    def to_json(self, extra: dict | None = None) -> str:
        """The plan as JSON; ``extra`` keys (e.g. scenario and seed) come first."""
        d = dict(extra or {})
        d.update(self.to_dict())
        return json.dumps(d, separators=(",", ":")) + "\n"

    def save(self, path: str | Path, extra: dict | None = None) -> Path:
        """Write the plan JSON atomically (a temporary file moved into place)."""
        import os
        import tempfile

        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}-", suffix=".json", dir=path.parent)
        try:
            mask = os.umask(0)
            os.umask(mask)
            os.fchmod(fd, 0o666 & ~mask)  # mkstemp makes owner-only files
            with os.fdopen(fd, "w", encoding="utf-8") as fh:
                fh.write(self.to_json(extra))
            os.replace(tmp, path)
        except BaseException:
            Path(tmp).unlink(missing_ok=True)
            raise
        return path

    @classmethod
    def from_dict(cls, d: dict, source: str = "<plan>") -> "Plan":
        """A plan from its JSON object, every field checked (see :func:`read_plan_file`)."""
        return _plan_from_dict(cls, d, str(source))

    @classmethod
    def load(cls, path: str | Path) -> "Plan":
        """Read a plan file (see :func:`read_plan_file`)."""
        return read_plan_file(path)[0]

    def limit_violation(self, max_speed: float, max_accel: float, rtol: float = LIMIT_RTOL):
        """The first step that needs more than ``max_speed`` or ``max_accel``, or None.

        Under the minimum-jerk scaling a robot moving ``d`` in ``T`` seconds
        peaks at ``15/8 d/T`` [units/s] and ``10/sqrt(3) d/T^2`` [units/s^2].
        Returns ``(step, robot, "speed" or "acceleration", needed, limit)``
        for the first step (and its farthest-moving robot) over a limit by
        more than the relative tolerance ``rtol``.
        """
        if self.steps == 0:
            return None
        disp = np.linalg.norm(np.diff(self.waypoints, axis=0), axis=2)  # (K, m)
        far = disp.argmax(axis=1)
        d = disp[np.arange(self.steps), far]
        speed = _S1_MAX * d / self.durations
        accel = _S2_MAX * d / self.durations**2
        bad = (speed > max_speed * (1 + rtol)) | (accel > max_accel * (1 + rtol))
        if not bad.any():
            return None
        k = int(np.flatnonzero(bad)[0])
        if speed[k] > max_speed * (1 + rtol):
            return k, int(far[k]), "speed", float(speed[k]), float(max_speed)
        return k, int(far[k]), "acceleration", float(accel[k]), float(max_accel)


# ----------------------------------------------------------------------------
# plan files


def _origin(value, source: str) -> tuple[float, float]:
    """A plan file's ``origin``: ``[x, y]``, numbers in [-1e9, 1e9] (the world position of the
    workspace's lower-left corner, which ``swarmform export`` adds)."""
    from .inputfile import echo

    if not isinstance(value, list) or len(value) != 2:
        raise PlanFileError(source, "origin", f"must be a pair [x, y], got {echo(value)}")
    return (_number(value[0], source, "origin[0]", -1e9, 1e9), _number(value[1], source, "origin[1]", -1e9, 1e9))


#: Unknown top-level keys of a plan file named in the note that they were ignored.
IGNORED_SHOWN = 8


def note_ignored(path, extra: dict, stream=None) -> None:
    """One line on ``stream`` (stderr) naming the top-level keys of a plan file that
    :func:`read_plan_file` did not read, when there were any."""
    import sys

    keys = extra.get("ignored")
    if keys:
        print(f"note: {path}: keys this version does not read were ignored: {', '.join(keys)}",
              file=sys.stderr if stream is None else stream)


def read_plan_file(path: str | Path) -> tuple["Plan", dict]:
    """A plan file and its other top-level values (``seed``, ``scenario``), every field checked.

    The file must be a regular file of at most :data:`MAX_PLAN_BYTES`
    holding one JSON object with ``radius`` (> 0), ``margin`` (>= 0),
    ``durations`` (K numbers in [:data:`MIN_DURATION`, :data:`MAX_DURATION`]
    seconds, K <= :data:`MAX_STEPS`) and ``waypoints`` (K + 1 lists of the
    same m <= :data:`MAX_ROBOTS` pairs [x, y] of finite numbers, not
    strings or booleans, of absolute value <= :data:`MAX_COORDINATE`);
    optionally ``profile`` (``minimum_jerk``), ``max_speed`` and
    ``max_accel`` (numbers > 0), ``seed`` (an integer in [0, 2^63 - 1]) and
    ``stats`` (the PlanStats fields, each of its type).  A key may not be
    repeated; a top-level key not in :data:`PLAN_KEYS` is ignored (the plan file
    contract: other keys may follow) and named, in file order and at most
    :data:`IGNORED_SHOWN` of them, under ``"ignored"`` of the returned values; at most
    :data:`planner.inputfile.MAX_JSON_CONTAINERS` lists and objects.  Raises :class:`PlanFileError` naming the file, the field and
    the reason, with the value received cut to about 80 characters.
    """
    from .inputfile import JsonRefused, UnreadableFile, echo_key, load_json, read_text

    source = str(path)
    try:
        text = read_text(path, MAX_PLAN_BYTES)
    except UnreadableFile as exc:
        raise PlanFileError(source, "file", str(exc)) from None
    try:
        d = load_json(text, parse_int=_json_int)
    except JsonRefused as exc:
        raise PlanFileError(source, exc.where, exc.reason) from None
    del text
    unknown = [k for k in d if k not in PLAN_KEYS] if isinstance(d, dict) else []
    p = _plan_from_dict(Plan, d, source)
    extra: dict = {}
    if unknown:
        extra["ignored"] = [echo_key(k) for k in unknown[:IGNORED_SHOWN]] + (
            [f"and {len(unknown) - IGNORED_SHOWN} more"] if len(unknown) > IGNORED_SHOWN else [])
    if "seed" in d:
        extra["seed"] = _integer(d["seed"], source, "seed", 0, 2**63 - 1)
    if "scenario" in d:
        extra["scenario"] = d["scenario"]
    if "origin" in d:
        extra["origin"] = _origin(d["origin"], source)
    return p, extra
