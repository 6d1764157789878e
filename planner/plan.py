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
import math
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

__all__ = [
    "PROFILE",
    "Plan",
    "PlanFileError",
    "PlanStats",
    "min_jerk",
    "min_jerk_s",
    "step_duration",
]

PROFILE = "minimum_jerk"
_S1_MAX = 15.0 / 8.0  # max of s'(u), at u = 1/2
_S2_MAX = 10.0 / math.sqrt(3.0)  # max of |s''(u)|, at u = (3 -+ sqrt 3) / 6


def min_jerk_s(u):
    """``s(u) = 10 u^3 - 15 u^4 + 6 u^5`` for ``u`` in [0, 1], on floats or arrays alike."""
    u2 = u * u
    return u2 * u * (10.0 - 15.0 * u + 6.0 * u2)


def min_jerk(u):
    """``(s, s', s'')`` of the minimum-jerk scaling at ``u`` in [0, 1]."""
    u = np.clip(np.asarray(u, float), 0.0, 1.0)
    s = min_jerk_s(u)
    ds = 30.0 * (u * u) * (1.0 - u) ** 2
    dds = 60.0 * u * (1.0 - u) * (1.0 - 2.0 * u)
    return s, ds, dds


def step_duration(distance, max_speed: float, max_accel: float):
    """Shortest duration of a straight move of ``distance`` from rest to rest."""
    d = np.asarray(distance, float)
    t = np.maximum(_S1_MAX * d / max_speed, np.sqrt(_S2_MAX * d / max_accel))
    return t if t.ndim else float(t)


class PlanFileError(ValueError):
    """A plan file that cannot be read; ``str()`` names the file, field and reason."""

    def __init__(self, path, field: str, reason: str):
        self.path, self.field, self.reason = str(path), field, reason
        super().__init__(f"{path}: {field}: {reason}")


@dataclass
class PlanStats:
    """What a planning run did.  Times in seconds, lengths in workspace units.

    ``min_clearance`` is the exact smallest gap between two disc boundaries,
    or between a disc and an obstacle or wall, over the whole plan (a plan
    is valid when it is at least the margin).
    """

    found: bool = False
    planning_time_s: float = 0.0
    g: int = 0
    q: int = 0
    graphs: int = 0
    connections: int = 0
    steps: int = 0
    makespan_s: float = 0.0
    path_length: float = 0.0
    min_clearance: float = float("nan")
    makespan_lower_bound_s: float = float("nan")
    path_length_lower_bound: float = float("nan")
    extra: dict = field(default_factory=dict)

    def to_dict(self) -> dict:
        d = asdict(self)
        extra = d.pop("extra")
        d.update(extra)
        return {k: _jsonable(v) for k, v in d.items()}


def _jsonable(v):
    if isinstance(v, float) and not math.isfinite(v):
        return None
    if isinstance(v, (np.floating,)):
        return _jsonable(float(v))
    if isinstance(v, (np.integer,)):
        return int(v)
    return v


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
        if not isinstance(d, dict):
            raise PlanFileError(source, "file", "must hold a JSON object")
        for key in ("radius", "margin", "durations", "waypoints"):
            if key not in d:
                raise PlanFileError(source, key, "is missing")
        profile = d.get("profile", PROFILE)
        if profile != PROFILE:
            raise PlanFileError(source, "profile", f"unknown profile {profile!r} (known: {PROFILE})")
        try:
            w = np.asarray(d["waypoints"], float)
        except (TypeError, ValueError):
            raise PlanFileError(source, "waypoints", "must be a [K+1][m][2] array of numbers") from None
        try:
            dur = np.asarray(d["durations"], float).reshape(-1)
        except (TypeError, ValueError):
            raise PlanFileError(source, "durations", "must be a list of numbers") from None
        if w.ndim != 3 or w.shape[2] != 2 or w.shape[0] < 1 or w.shape[1] < 1:
            raise PlanFileError(source, "waypoints", f"must be a [K+1][m][2] array, got shape {w.shape}")
        if len(dur) != len(w) - 1:
            raise PlanFileError(source, "durations", f"has {len(dur)} entries for {len(w)} waypoints")
        if not np.all(np.isfinite(w)):
            raise PlanFileError(source, "waypoints", "holds a non-finite number")
        if not np.all(np.isfinite(dur)) or np.any(dur <= 0):
            bad = int(np.flatnonzero(~(np.isfinite(dur) & (dur > 0)))[0])
            raise PlanFileError(source, f"durations[{bad}]", "must be a finite number > 0")
        for key in ("radius", "margin"):
            v = d[key]
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not v >= 0:
                raise PlanFileError(source, key, f"must be a number >= 0, got {v!r}")
        stats = None
        if isinstance(d.get("stats"), dict):
            known = set(PlanStats.__dataclass_fields__) - {"extra"}
            s = d["stats"]
            stats = PlanStats(
                **{k: (float("nan") if s[k] is None else s[k]) for k in known if k in s},
                extra={k: v for k, v in s.items() if k not in known},
            )
        return cls(
            float(d["radius"]),
            float(d["margin"]),
            dur,
            w,
            d.get("max_speed"),
            d.get("max_accel"),
            stats,
        )

    @classmethod
    def load(cls, path: str | Path) -> "Plan":
        path = Path(path)
        try:
            d = json.loads(path.read_text(encoding="utf-8"))
        except FileNotFoundError:
            raise PlanFileError(path, "file", "no such file") from None
        except (OSError, UnicodeDecodeError) as exc:
            raise PlanFileError(path, "file", f"cannot be read ({exc})") from None
        except json.JSONDecodeError as exc:
            raise PlanFileError(path, f"line {exc.lineno}", f"invalid JSON: {exc.msg}") from None
        return cls.from_dict(d, str(path))
