"""The physics budget: how much simulation a run may ask for, checked before it starts.

A run's physics cost is only known once the plan is: ``ceil((makespan +
settle_time) / dt)`` control steps of ``substeps`` physics steps for each of
the ``m`` robots.  :func:`check_physics_budget` refuses (exit 2, nothing
written) a run that would take more than :data:`MAX_BODY_STEPS` robot
physics steps (time: pymunk and the controller manage about 2 million a
second here, so the cap is under a minute) or record more than
:data:`MAX_SAMPLES` robot positions (memory: 16 bytes each, 160 MB at the
cap), and names the fields that change the cost.  A plan file's exact
validation is bounded too (:func:`check_validator_budget`).
"""

from __future__ import annotations

import math

import numpy as np

from planner.inputfile import echo_path

from ..errors import InputError

__all__ = [
    "MAX_BODY_STEPS",
    "MAX_SAMPLES",
    "MAX_VALIDATOR_PAIRS",
    "check_physics_budget",
    "check_validator_budget",
    "physics_cost",
]

MAX_BODY_STEPS = 50_000_000
"""Robots x control steps x substeps that one physics run may take."""

MAX_SAMPLES = 10_000_000
"""Robots x control steps (positions recorded) that one physics run may take."""

MAX_VALIDATOR_PAIRS = 200_000_000
"""Moves x robots that the exact validator may compare for a plan file (about 20 s here)."""


def physics_cost(m: int, makespan: float, sim) -> tuple[float, float]:
    """``(robot physics steps, recorded positions)`` of executing a ``makespan``-second plan."""
    total = float(makespan) + float(sim.settle_time)
    if not math.isfinite(total):
        return math.inf, math.inf
    steps = math.ceil(total / float(sim.dt) - 1e-9) + 1
    return float(m) * steps * int(sim.substeps), float(m) * steps


def check_physics_budget(m: int, makespan: float, sim, source: str) -> None:
    """Raise :class:`InputError` naming the fields to change when the run is over budget."""
    body, samples = physics_cost(m, makespan, sim)
    what = None
    if body > MAX_BODY_STEPS:
        what = f"{body:.3g} steps > {MAX_BODY_STEPS:.0e}"
    elif samples > MAX_SAMPLES:
        what = f"{samples:.3g} positions > {MAX_SAMPLES:.0e}"
    if what:
        raise InputError(
            f"{echo_path(source)}: physics budget: {m} robots x {makespan:.3g} s: {what}; raise "
            "robots.max_speed/max_accel or sim.dt; lower sim.substeps/settle_time"
        )


def check_validator_budget(plan, source: str) -> None:
    """Raise :class:`InputError` when checking ``plan`` exactly would take too long."""
    moves = int(np.count_nonzero(np.any(plan.waypoints[1:] != plan.waypoints[:-1], axis=2)))
    pairs = float(moves) * plan.m
    if pairs > MAX_VALIDATOR_PAIRS:
        raise InputError(
            f"{echo_path(source)}: waypoints: {moves} robot moves x {plan.m} robots = {pairs:.3g} closest "
            f"approaches to check exactly, over {MAX_VALIDATOR_PAIRS:.0e}; use fewer steps"
        )
