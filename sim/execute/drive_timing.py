"""Whether a plan's timing can be kept by a drive model (:mod:`sim.execute.drive`), from the plan alone.

A plan stops every robot at every waypoint (minimum-jerk steps) and starts
the next step at once.  A differential robot that must leave a waypoint in
a new direction first turns on the spot, at most at
``2 wheel_speed / wheel_base`` [rad/s] (wheels at full speed in opposite
directions), so it falls behind by ``angle / max_turn_rate`` at that corner.
Every robot of a step moves on one clock, so the plan loses, at each step
boundary, the longest turn of any robot there; ``turn_time_lost_s`` is
their sum.  A straight move of length ``L`` in ``T`` seconds peaks at
``15 L / (8 T)`` (minimum jerk); a drive whose top speed (``wheel_speed``,
or ``max_speed`` of a velocity robot) is below the plan's peak lags too.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["drive_timing", "timing_notes"]

_PEAK = 15.0 / 8.0  # peak of the minimum-jerk s'(u)
_TURN_EPS = 1e-6  # [rad] smaller turns are not corners


def drive_timing(plan, d) -> dict | None:
    """The timing that ``plan`` asks of the drive ``d`` (:class:`sim.scenario.params.DriveParams`).

    Returns ``None`` for holonomic robots, else a JSON-ready dict:
    ``model``; ``plan_peak_speed`` [units/s]; ``drive_max_speed``
    [units/s]; ``speed_exceeded``; for a differential drive also
    ``max_turn_rate`` [rad/s], ``corners`` (robot turns > 1e-6 rad),
    ``turn_time_lost_s`` [s] and ``worst_corner`` (``step`` the turn comes
    before, ``robot``, ``angle_deg``, ``turn_time_s``; ``None`` without
    corners).
    """
    if d.model == "holonomic":
        return None
    w = np.asarray(plan.waypoints, float)
    delta = np.diff(w, axis=0)  # (K, m, 2)
    length = np.hypot(delta[..., 0], delta[..., 1]) if len(delta) else np.zeros((0, plan.m))
    durations = np.asarray(plan.durations, float)
    with np.errstate(divide="ignore", invalid="ignore"):
        speed = np.where(durations[:, None] > 0, _PEAK * length / durations[:, None], 0.0)
    peak = float(speed.max()) if speed.size else 0.0
    top = float(d.wheel_speed if d.model == "differential" else d.max_speed)
    out = {"model": d.model, "plan_peak_speed": peak, "drive_max_speed": top,
           "speed_exceeded": bool(peak > top * (1 + 1e-9))}
    if d.model != "differential":
        return out
    rate = 2.0 * float(d.wheel_speed) / float(d.wheel_base)
    last = np.full((plan.m, 2), np.nan)  # each robot's last direction of motion
    lost, corners, worst = 0.0, 0, None
    for k in range(len(delta)):
        moving = length[k] > 1e-12
        if not moving.any():
            continue
        u = np.zeros_like(last)
        u[moving] = delta[k][moving] / length[k][moving, None]
        seen = moving & ~np.isnan(last[:, 0])
        if seen.any():
            cos = np.clip(np.einsum("ij,ij->i", u[seen], last[seen]), -1.0, 1.0)
            angle = np.arccos(cos)
            turning = angle > _TURN_EPS
            corners += int(turning.sum())
            j = int(np.argmax(angle))
            if angle[j] > _TURN_EPS:
                t = float(angle[j]) / rate
                lost += t
                if worst is None or t > worst["turn_time_s"]:
                    worst = {"step": k, "robot": int(np.flatnonzero(seen)[j]),
                             "angle_deg": math.degrees(float(angle[j])), "turn_time_s": t}
        last[moving] = u[moving]
    out.update(max_turn_rate=rate, corners=corners, turn_time_lost_s=lost, worst_corner=worst)
    return out


def timing_notes(timing: dict | None) -> list[str]:
    """Verdict notes when the drive cannot keep the plan's timing (none when it can, or for holonomic robots)."""
    if not isinstance(timing, dict):
        return []
    notes = []
    model = timing.get("model", "")
    lost = timing.get("turn_time_lost_s") or 0.0
    worst = timing.get("worst_corner")
    if lost > 0 and isinstance(worst, dict):
        notes.append(
            f"the {model} drive cannot keep the plan's timing: it loses {lost:.2f} s turning on the spot at "
            f"{timing.get('corners')} corners (worst {worst['turn_time_s']:.2f} s, robot {worst['robot']} "
            f"turning {worst['angle_deg']:.0f} deg before step {worst['step'] + 1})")
    if timing.get("speed_exceeded"):
        notes.append(f"the plan's peak speed {timing['plan_peak_speed']:.3g} exceeds the {model} drive's "
                     f"top speed {timing['drive_max_speed']:.3g}")
    return notes
