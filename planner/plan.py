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
    "read_plan_file",
    "step_duration",
]

PROFILE = "minimum_jerk"
_S1_MAX = 15.0 / 8.0  # max of s'(u), at u = 1/2
_S2_MAX = 10.0 / math.sqrt(3.0)  # max of |s''(u)|, at u = (3 -+ sqrt 3) / 6

MAX_PLAN_BYTES = 64 << 20
"""The largest plan file read [bytes] (64 MiB)."""
PLAN_KEYS = frozenset({"scenario", "seed", "radius", "margin", "profile", "durations", "waypoints",
                       "max_speed", "max_accel", "stats"})
"""The top-level keys of a plan file (what :meth:`Plan.to_json` and ``swarmform plan`` write)."""
MAX_STEPS = 100_000
"""The most steps a plan file may hold."""
MAX_ROBOTS = 1000
"""The most robots a plan file may move."""
MIN_DURATION = 1e-3
"""The shortest step a plan file may hold [s]."""
MAX_DURATION = 1e5
"""The longest step a plan file may hold [s]."""
MAX_COORDINATE = 1e6
"""The largest absolute waypoint coordinate or length a plan file may hold [units]."""
LIMIT_RTOL = 1e-6
"""Relative tolerance on max_speed and max_accel when a plan file's steps are checked."""


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
        from .inputfile import echo_path

        self.path, self.field, self.reason = str(path), field, reason
        super().__init__(f"{echo_path(path)}: {field}: {reason}")


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

_STAT_TYPES = {
    "found": (bool,), "planning_time_s": (int, float), "g": (int,), "q": (int,), "graphs": (int,),
    "connections": (int,), "steps": (int,), "makespan_s": (int, float), "path_length": (int, float),
    "min_clearance": (int, float), "makespan_lower_bound_s": (int, float),
    "path_length_lower_bound": (int, float),
}


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
    repeated; a top-level key not in :data:`PLAN_KEYS` is refused; at most
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
    if isinstance(d, dict):
        for key in d:
            if key not in PLAN_KEYS:
                raise PlanFileError(source, echo_key(key), "is not a plan file key (known: "
                                    + ", ".join(sorted(PLAN_KEYS)) + ")")
    p = _plan_from_dict(Plan, d, source)
    extra = {}
    if "seed" in d:
        extra["seed"] = _integer(d["seed"], source, "seed", 0, 2**63 - 1)
    if "scenario" in d:
        extra["scenario"] = d["scenario"]
    return p, extra


def _json_int(literal: str):
    """A JSON integer, or a :class:`planner.inputfile.HugeInt` when it has over 30 digits."""
    if len(literal) <= 30:
        return int(literal)
    from .inputfile import HugeInt

    return HugeInt(literal)


def _fail(source, field, reason):
    raise PlanFileError(source, field, reason)


def _is_number(v) -> bool:
    return type(v) is float or type(v) is int


def _number(v, source, field, lo, hi, *, lo_open=False) -> float:
    from .inputfile import echo

    span = f"in {'(' if lo_open else '['}{lo:g}, {hi:g}]"
    if not _is_number(v):
        _fail(source, field, f"must be a number {span}, got {echo(v)}")
    x = float(v) if abs(v) < 1e300 else math.inf
    if not math.isfinite(x) or x > hi or x < lo or (lo_open and x == lo):
        _fail(source, field, f"must be a number {span}, got {echo(v)}")
    return x


def _integer(v, source, field, lo, hi) -> int:
    from .inputfile import echo

    if type(v) is not int or not lo <= v <= hi:
        top = "2^63 - 1" if hi == 2**63 - 1 else str(hi)
        _fail(source, field, f"must be an integer in [{lo}, {top}], got {echo(v)}")
    return v


def _plan_from_dict(cls, d, source: str) -> "Plan":
    from .inputfile import echo

    if not isinstance(d, dict):
        _fail(source, "file", f"must hold a JSON object, got {echo(d)}")
    for key in ("radius", "margin", "durations", "waypoints"):
        if key not in d:
            _fail(source, key, "is missing")
    profile = d.get("profile", PROFILE)
    if profile != PROFILE:
        _fail(source, "profile", f"unknown profile: {echo(profile)} (known: {PROFILE})")
    radius = _number(d["radius"], source, "radius", 0, MAX_COORDINATE, lo_open=True)
    margin = _number(d["margin"], source, "margin", 0, MAX_COORDINATE)
    limits = []
    for key in ("max_speed", "max_accel"):
        v = d.get(key)
        limits.append(None if v is None else _number(v, source, key, 0, 1e9, lo_open=True))

    dur = d["durations"]
    if not isinstance(dur, list):
        _fail(source, "durations", f"must be a list of numbers, got {echo(dur)}")
    if len(dur) > MAX_STEPS:
        _fail(source, "durations", f"must hold at most {MAX_STEPS} steps, got {len(dur)}")
    for k, v in enumerate(dur):
        _number(v, source, f"durations[{k}]", MIN_DURATION, MAX_DURATION)

    w = d["waypoints"]
    if not isinstance(w, list) or not w:
        _fail(source, "waypoints", f"must be a [K+1][m][2] list of numbers, got {echo(w)}")
    if len(w) != len(dur) + 1:
        _fail(source, "durations", f"has {len(dur)} entries for {len(w)} waypoints (needs one fewer)")
    m = None
    for k, row in enumerate(w):
        if not isinstance(row, list) or not row or not all(isinstance(p, list) for p in row):
            _fail(source, "waypoints", f"must be a [K+1][m][2] list: waypoints[{k}] must be a list of "
                  f"pairs [x, y], got {echo(row)}")
        if m is None:
            m = len(row)
            if m > MAX_ROBOTS:
                _fail(source, "waypoints[0]", f"must move at most {MAX_ROBOTS} robots, got {m}")
        elif len(row) != m:
            _fail(source, f"waypoints[{k}]", f"moves {len(row)} robot{'s' * (len(row) != 1)}, waypoints[0] {m}")
        for i, p in enumerate(row):
            if len(p) != 2 or not (_is_number(p[0]) and _is_number(p[1])):
                bad = next((j for j in (0, 1) if j < len(p) and not _is_number(p[j])), None)
                where = f"waypoints[{k}][{i}]" + ("" if bad is None or len(p) != 2 else f"[{bad}]")
                got = echo(p) if len(p) != 2 else echo(p[bad])
                _fail(source, where, f"must be a pair [x, y] of numbers, got {got}")
    for k, row in enumerate(w):
        for i, p in enumerate(row):
            for j in (0, 1):
                v = p[j]
                if not (abs(v) <= MAX_COORDINATE) or (type(v) is float and not math.isfinite(v)):
                    _number(v, source, f"waypoints[{k}][{i}][{j}]", -MAX_COORDINATE, MAX_COORDINATE)
    stats = None
    if d.get("stats") is not None:
        stats = _stats(d["stats"], source)
    return cls(radius, margin, np.asarray(dur, float), np.asarray(w, float), limits[0], limits[1], stats)


def _stats(s, source: str) -> PlanStats:
    from .inputfile import echo

    if not isinstance(s, dict):
        _fail(source, "stats", f"must be an object, got {echo(s)}")
    values = {}
    for key, types in _STAT_TYPES.items():
        if key not in s:
            continue
        v = s[key]
        if v is None and key != "found":
            values[key] = float("nan")
            continue
        ok = type(v) in types or (types == (int, float) and type(v) in (int, float))
        if not ok or (type(v) in (int, float) and not type(v) is bool and not abs(v) <= 1e300):
            _fail(source, f"stats.{key}", f"must be {'a boolean' if types == (bool,) else 'a number'}, got {echo(v)}")
        values[key] = v
    return PlanStats(**values, extra={k: v for k, v in s.items() if k not in _STAT_TYPES and k != "extra"})
