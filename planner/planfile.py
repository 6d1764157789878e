"""The field checks of plan files: the limits a plan file must keep, and the
checked conversion of its JSON object into a plan (see
:func:`planner.plan.read_plan_file`)."""

from __future__ import annotations

import math

import numpy as np

from .profile import PROFILE
from .stats import PlanStats

__all__ = [
    "MAX_COORDINATE",
    "MAX_DURATION",
    "MAX_PLAN_BYTES",
    "MAX_ROBOTS",
    "MAX_STEPS",
    "MIN_DURATION",
    "PLAN_KEYS",
    "PlanFileError",
]


MAX_PLAN_BYTES = 64 << 20
"""The largest plan file read [bytes] (64 MiB)."""
PLAN_KEYS = frozenset({"scenario", "seed", "radius", "margin", "profile", "durations", "waypoints",
                       "max_speed", "max_accel", "stats", "origin"})
"""The top-level keys of a plan file (what :meth:`Plan.to_json` and ``swarmform plan`` write)."""
MAX_STEPS = 100_000
"""The most steps a plan file may hold."""
MAX_ROBOTS = 5000
"""The most robots a plan file may move (as many as a scenario may have)."""
MIN_DURATION = 1e-3
"""The shortest step a plan file may hold [s]."""
MAX_DURATION = 1e5
"""The longest step a plan file may hold [s]."""
MAX_COORDINATE = 1e6
"""The largest absolute waypoint coordinate or length a plan file may hold [units]."""


class PlanFileError(ValueError):
    """A plan file that cannot be read; ``str()`` names the file, field and reason."""

    def __init__(self, path, field: str, reason: str):
        from .inputfile import echo_path

        self.path, self.field, self.reason = str(path), field, reason
        super().__init__(f"{echo_path(path)}: {field}: {reason}")


_STAT_TYPES = {
    "found": (bool,), "planning_time_s": (int, float), "g": (int,), "q": (int,), "graphs": (int,),
    "connections": (int,), "steps": (int,), "makespan_s": (int, float), "path_length": (int, float),
    "min_clearance": (int, float), "makespan_lower_bound_s": (int, float),
    "path_length_lower_bound": (int, float), "makespan_lower_bound_geo_s": (int, float),
    "makespan_lower_bound_cut_s": (int, float),
}


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


def _plan_from_dict(cls, d, source: str):
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
    values: dict = {}
    for key, types in _STAT_TYPES.items():
        if key not in s:
            continue
        v = s[key]
        if v is None and key != "found":
            values[key] = float("nan")
            continue
        ok = type(v) in types or (types == (int, float) and type(v) in (int, float))
        if not ok or (type(v) in (int, float) and type(v) is not bool and not abs(v) <= 1e300):
            _fail(source, f"stats.{key}", f"must be {'a boolean' if types == (bool,) else 'a number'}, got {echo(v)}")
        values[key] = v
    return PlanStats(**values, extra={k: v for k, v in s.items() if k not in _STAT_TYPES and k != "extra"})
