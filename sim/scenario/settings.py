"""The ``planner:``, ``sim:`` and ``render:`` sections: the run's settings and scheduled events."""

from __future__ import annotations

from dataclasses import fields

from planner.params import PlannerParams

from .fields import _kind, _Reader
from .params import (
    MAX_FPS,
    MAX_RENDER_SIZE,
    DriveParams,
    Failure,
    Impulse,
    Noise,
    Pushes,
    Recovery,
    RenderParams,
    Sensing,
    SimParams,
)

__all__: list[str] = []  # private to the scenario room


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
        sensing=_read_sensing(r, v.get("sensing")),
        accept=_choice(r, v.get("accept", d.accept), "sim.accept", ("targets", "working")),
        drive=_read_drive(r, v.get("drive")),
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
    v = r.mapping(value, "sim.recovery",
                  ("replan", "trigger", "replan_time_limit", "time_limit", "max_replans", "on_budget"))
    d = Recovery()
    max_replans = r.integer(v.get("max_replans", d.max_replans), "sim.recovery.max_replans", ge=1)
    if max_replans > 100:
        r.fail("sim.recovery.max_replans", f"must be <= 100, got {max_replans}")
    if "time_limit" in v and "replan_time_limit" in v:
        r.fail("sim.recovery.time_limit", "is the old name of sim.recovery.replan_time_limit; give only one")
    key = "time_limit" if "time_limit" in v else "replan_time_limit"
    return Recovery(
        replan=r.boolean(v.get("replan", d.replan), "sim.recovery.replan"),
        trigger=r.number(v.get("trigger", d.trigger), "sim.recovery.trigger", gt=0, le=100),
        replan_time_limit=r.number(v.get(key, d.replan_time_limit), f"sim.recovery.{key}", gt=0, le=600),
        max_replans=max_replans,
        on_budget=_choice(r, v.get("on_budget", d.on_budget), "sim.recovery.on_budget", ("fail", "continue")),
    )


def _choice(r: _Reader, value, field: str, allowed: tuple[str, ...]) -> str:
    if not isinstance(value, str) or value not in allowed:
        r.fail(field, f"must be one of {', '.join(allowed)}, got {_kind(value)}")
    return value


def _read_sensing(r: _Reader, value) -> Sensing | None:
    if value is None:
        return None
    keys = ("rate", "dropout", "latency_jitter", "bias_drift", "estimator", "process_noise", "failure_delay")
    v = r.mapping(value, "sim.sensing", keys)
    d = Sensing()
    rate, delay = v.get("rate"), v.get("failure_delay")
    return Sensing(
        rate=None if rate is None else r.number(rate, "sim.sensing.rate", gt=0, le=10000),
        dropout=r.number(v.get("dropout", d.dropout), "sim.sensing.dropout", ge=0, lt=1),
        latency_jitter=r.number(v.get("latency_jitter", d.latency_jitter), "sim.sensing.latency_jitter", ge=0, le=1),
        bias_drift=r.number(v.get("bias_drift", d.bias_drift), "sim.sensing.bias_drift", ge=0, le=10),
        estimator=_choice(r, v.get("estimator", d.estimator), "sim.sensing.estimator",
                          ("kalman", "alpha_beta", "oracle")),
        process_noise=r.number(v.get("process_noise", d.process_noise), "sim.sensing.process_noise", gt=0, le=1e8),
        failure_delay=None if delay is None else r.number(delay, "sim.sensing.failure_delay", ge=0, le=60),
    )


_DRIVE_KEYS = {"holonomic": (), "differential": ("wheel_base", "wheel_speed", "wheel_accel", "lookahead", "kp_v"),
               "velocity": ("time_constant", "max_speed", "kp_v")}


def _read_drive(r: _Reader, value) -> DriveParams:
    """``sim.drive``: a model name, or a mapping with ``model`` and that model's settings."""
    if isinstance(value, str):
        value = {"model": value}
    v = r.mapping(value, "sim.drive", tuple(f.name for f in fields(DriveParams)))
    d = DriveParams()
    model = _choice(r, v.get("model", d.model), "sim.drive.model", tuple(_DRIVE_KEYS))
    for key in v:
        if key != "model" and key not in _DRIVE_KEYS[model]:
            r.fail(f"sim.drive.{key}", f"is not a setting of the {model} drive (its settings: "
                   f"{', '.join(_DRIVE_KEYS[model]) or 'none'})")
    ranges = {"wheel_base": 100, "wheel_speed": 1000, "wheel_accel": 1e5, "lookahead": 100, "time_constant": 10,
              "max_speed": 1000}
    got = {k: r.number(v.get(k, getattr(d, k)), f"sim.drive.{k}", gt=0, le=high) for k, high in ranges.items()}
    got["kp_v"] = r.number(v.get("kp_v", d.kp_v), "sim.drive.kp_v", ge=0, le=1000)
    return DriveParams(model=model, **got)


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
