"""Execute a timed plan in pymunk and report every contact.

:func:`execute` builds the world (:mod:`sim.world`), puts each robot at its
first waypoint, and runs ``ceil((makespan + settle_time) / dt)`` control
steps.  Each control step computes the PD + feed-forward force of every
robot at once (:mod:`sim.control`), holds it for ``substeps`` physics
steps, and records the positions.  Two witnesses watch for contacts
(:mod:`sim.contacts`): pymunk's collision callbacks, at every physics step,
and an exact geometric monitor, at every recorded sample.  A run is
:attr:`SimReport.ok` when neither saw a contact and every robot ended
within ``tolerance`` of a distinct target.

All arrays of positions are workspace units, all times seconds.
"""

from __future__ import annotations

import math
import numbers
import time as _time
from dataclasses import dataclass
from typing import Callable

import numpy as np

from .contacts import Contact, GapMonitor, PymunkWitness
from .control import pd_acceleration, reference_chunk
from .world import build_world

__all__ = ["Contact", "SimReport", "execute"]

_CHUNK = 64  # control steps per reference batch, monitor batch and progress call
_LIST_MAX = 50  # contacts listed in full by SimReport.to_dict


@dataclass(frozen=True, eq=False)
class SimReport:
    """The outcome of one physics run.

    contacts: every touching episode, both witnesses, in time order.
    min_clearance: smallest gap seen by the monitor [units]: between two
        disc boundaries, or between a disc and an obstacle or wall
        (negative means overlap).
    min_clearance_time: when it occurred [s].
    max_tracking_error: the largest ``|x - x_ref|`` over robots and samples
        with ``t <= makespan`` [units].
    reached: after settling, every robot is within ``tolerance`` of a
        distinct target (minimum-cost matching of robots to targets).
    final_error: the largest matched robot-target distance at the end [units].
    sim_time_s: simulated time [s]; wall_time_s: wall-clock time of the run [s].
    times: ``(T,)`` sample times, one per control step, from 0.
    positions: ``(T, m, 2)`` body positions at those times.
    min_clearance_kind, min_clearance_pair: what attained ``min_clearance``
        (two robots; or a robot and an obstacle index, ``-1`` for the wall).
    step_time_s: wall-clock time spent inside ``space.step`` [s].
    """

    contacts: tuple[Contact, ...]
    min_clearance: float
    min_clearance_time: float
    max_tracking_error: float
    reached: bool
    final_error: float
    sim_time_s: float
    wall_time_s: float
    times: np.ndarray
    positions: np.ndarray
    min_clearance_kind: str = ""
    min_clearance_pair: tuple[int, int] = (-1, -1)
    step_time_s: float = 0.0

    @property
    def ok(self) -> bool:
        """No contact by either witness, and every target reached."""
        return not self.contacts and self.reached

    @property
    def realtime_factor(self) -> float:
        """Simulated seconds per wall-clock second."""
        return self.sim_time_s / self.wall_time_s if self.wall_time_s > 0 else math.inf

    def to_dict(self) -> dict:
        """JSON-ready summary (no per-sample arrays)."""
        return {
            "ok": self.ok,
            "contacts": len(self.contacts),
            "contacts_pymunk": sum(c.witness == "pymunk" for c in self.contacts),
            "contacts_monitor": sum(c.witness == "monitor" for c in self.contacts),
            "min_clearance": _finite(self.min_clearance),
            "min_clearance_time": _finite(self.min_clearance_time),
            "min_clearance_kind": self.min_clearance_kind,
            "min_clearance_pair": list(self.min_clearance_pair),
            "max_tracking_error": _finite(self.max_tracking_error),
            "reached": self.reached,
            "final_error": _finite(self.final_error),
            "sim_time_s": self.sim_time_s,
            "wall_time_s": self.wall_time_s,
            "realtime_factor": _finite(self.realtime_factor),
            "contact_list": [c.to_dict() for c in self.contacts[:_LIST_MAX]],
        }


def _finite(v: float):
    v = float(v)
    return v if math.isfinite(v) else None


def execute(problem, plan, params, *, progress: Callable[[float], None] | None = None) -> SimReport:
    """Run ``plan`` in ``problem``'s world with PD-controlled disc bodies.

    ``params`` is a :class:`sim.params.SimParams`.  ``progress``, if given,
    is called now and then with the fraction of simulated time done (ends
    with ``1.0``).  Raises ``ValueError`` naming the parameter when the
    inputs do not fit together.
    """
    _check(problem, plan, params)
    return _execute(problem, plan, params, progress)


def _check(problem, plan, params) -> None:
    if plan.m != problem.m:
        raise ValueError(f"plan: moves {plan.m} robots, the problem has {problem.m}")
    for name, low, strict in (
        ("mass", 0.0, True),
        ("kp", 0.0, False),
        ("kd", 0.0, False),
        ("dt", 0.0, True),
        ("force_limit", 0.0, True),
        ("settle_time", 0.0, False),
        ("tolerance", 0.0, False),
    ):
        v = getattr(params, name)
        number = isinstance(v, numbers.Real) and not isinstance(v, bool) and math.isfinite(v)
        if not (number and (v > low if strict else v >= low)):
            rng = f"({low:g}, inf)" if strict else f"[{low:g}, inf)"
            raise ValueError(f"sim.{name}: must be a number in the range {rng}, got {v!r}")
    if not (isinstance(params.substeps, numbers.Integral) and params.substeps >= 1):
        raise ValueError(f"sim.substeps: must be an int in the range [1, inf), got {params.substeps!r}")


def _execute(problem, plan, params, progress) -> SimReport:
    wall0 = _time.perf_counter()
    world = build_world(problem, params)
    for body, p in zip(world.bodies, plan.start):
        body.position = (float(p[0]), float(p[1]))
    space = world.space
    witness = PymunkWitness(world)
    monitor = GapMonitor(problem)

    dt = float(params.dt)
    n_sub = int(params.substeps)
    h = dt / n_sub
    mass = float(params.mass)
    kp, kd, limit = float(params.kp), float(params.kd), float(params.force_limit)
    makespan = plan.makespan
    total = makespan + float(params.settle_time)
    n_steps = max(0, math.ceil(total / dt - 1e-9))
    times = np.arange(n_steps + 1) * dt
    m = plan.m
    positions = np.empty((n_steps + 1, m, 2))

    state = world.state()
    positions[0] = state[:, :2]
    monitor.observe(times[:1], positions[:1])
    track = 0.0
    forces = world.forces
    step_time = 0.0
    perf = _time.perf_counter

    for k0 in range(0, n_steps, _CHUNK):
        count = min(_CHUNK, n_steps - k0)
        ref = reference_chunk(plan, k0, count, dt)
        for j in range(count):
            acc = pd_acceleration(
                state[:, :2], state[:, 2:], ref.pos[j], ref.vel[j], ref.acc_ff[j], kp, kd, limit
            )
            np.multiply(acc, mass, out=forces)
            t0 = times[k0 + j]
            for s in range(1, n_sub + 1):
                witness.now = t0 + s * h
                world.apply_forces()
                c0 = perf()
                space.step(h)
                step_time += perf() - c0
            state = world.state()
            positions[k0 + j + 1] = state[:, :2]
        sl = slice(k0 + 1, k0 + count + 1)
        monitor.observe(times[sl], positions[sl])
        during = times[sl] <= makespan + 1e-9
        if during.any():
            err = positions[sl][during] - ref.pos[1:][during]
            track = max(track, float(np.sqrt(np.einsum("tik,tik->ti", err, err).max())))
        if progress is not None:
            progress(min(1.0, (k0 + count) / n_steps))
    if progress is not None and n_steps == 0:
        progress(1.0)

    reached, final_error = _reached(positions[-1], problem.target, float(params.tolerance))
    contacts = sorted(
        witness.contacts() + monitor.contacts(),
        key=lambda c: (c.time, c.witness != "pymunk", c.kind, c.a, c.b),
    )
    times.setflags(write=False)
    positions.setflags(write=False)
    return SimReport(
        contacts=tuple(contacts),
        min_clearance=monitor.min_gap,
        min_clearance_time=monitor.min_time,
        max_tracking_error=track,
        reached=reached,
        final_error=final_error,
        sim_time_s=float(n_steps * dt),
        wall_time_s=_time.perf_counter() - wall0,
        times=times,
        positions=positions,
        min_clearance_kind=monitor.min_kind,
        min_clearance_pair=monitor.min_pair,
        step_time_s=step_time,
    )


def _reached(final: np.ndarray, target: np.ndarray, tolerance: float) -> tuple[bool, float]:
    """Match robots to distinct targets at least total distance; the worst match."""
    from scipy.optimize import linear_sum_assignment

    target = np.asarray(target, float).reshape(-1, 2)
    if len(target) != len(final):
        return False, math.inf
    cost = np.linalg.norm(final[:, None, :] - target[None, :, :], axis=2)
    rows, cols = linear_sum_assignment(cost)
    worst = float(cost[rows, cols].max()) if len(rows) else 0.0
    return bool(worst <= tolerance), worst
