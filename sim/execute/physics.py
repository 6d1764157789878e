"""Execute a timed plan in pymunk and report what happened.

:func:`execute` builds the world (:mod:`sim.execute.world`), puts each robot at its
first waypoint, and runs ``ceil((makespan + settle_time) / dt)`` control
steps.  Each control step computes the PD + feed-forward force of every
robot at once (:mod:`sim.execute.control`), holds it for ``substeps`` physics
steps, and records the positions.  Two witnesses watch for contacts
(:mod:`sim.execute.contacts`): pymunk's collision callbacks, at every physics step,
and an exact geometric monitor, at every recorded sample.

Ideal robots (every realism knob of :class:`sim.scenario.params.SimParams` off) run
in a tight loop.  Otherwise the realistic loop runs: at every physics step
the disturbances that fall due are applied, the controller updates when its
clock says so (from a noisy measurement; the force goes through the delay
line), and friction and the brakes of failed robots act (:mod:`sim.execute.realism`).
With recovery on, a tracking error above the trigger or a failure stops the
swarm and the planner plans again (:mod:`sim.execute.recovery`).  Both loops give
the same bytes when nothing realistic is on.

A run is :attr:`SimReport.ok` when neither witness saw a contact and every
working robot ended within ``tolerance`` of a distinct target (a failed
robot's target may stay empty).  Tracking error is measured over the whole
run, settling included.

All arrays of positions are workspace units, all times seconds.
"""

from __future__ import annotations

import math
import numbers
import time as _time
from typing import Callable

import numpy as np

from .contacts import Contact, PymunkWitness
from .control import pd_acceleration, reference_chunk
from .drive import check_drive
from .guard import SpeedGuard
from .monitor import GapMonitor
from .outcome import SimReport, assemble, filled, reached
from .real import CHUNK as _CHUNK
from .real import execute_real
from .realism import Disturbance, phase_margin
from .recovery import Replan
from .world import build_world

__all__ = ["Contact", "Disturbance", "Replan", "SimReport", "execute"]


def execute(problem, plan, params, rng: np.random.Generator | None = None, *,
            planner_params=None, progress: Callable[[float], None] | None = None) -> SimReport:
    """Run ``plan`` in ``problem``'s world with PD-controlled disc bodies.

    ``params`` is a :class:`sim.scenario.params.SimParams`.  ``rng`` is the run's
    generator; every random draw of the run (masses, noise, pushes,
    replanning) comes from streams derived from it
    (:func:`sim.execute.realism.streams`); a realistic run needs it (there
    is no default seed: a run made with ``Scenario.generator`` repeats).
    ``planner_params`` (:class:`planner.PlannerParams`) are used by
    replans.  ``progress``, if given, is called now and then with the
    fraction of simulated time done (ends with ``1.0``).  Raises
    ``ValueError`` naming the parameter when the inputs do not fit together.
    """
    _check(problem, plan, params)
    if not params.realistic:
        return _execute(problem, plan, params, progress)
    if rng is None:
        raise ValueError("rng: a realistic run draws noise, masses and pushes from the run's generator; "
                         "pass it (numpy.random.Generator, e.g. Scenario.generator())")
    return execute_real(problem, plan, params, rng, planner_params, progress)


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
        ("latency", 0.0, False),
        ("mass_error", 0.0, False),
        ("friction", 0.0, False),
    ):
        v = getattr(params, name)
        number = isinstance(v, numbers.Real) and not isinstance(v, bool) and math.isfinite(v)
        if not (number and (v > low if strict else v >= low)):
            rng = f"({low:g}, inf)" if strict else f"[{low:g}, inf)"
            raise ValueError(f"sim.{name}: must be a number in the range {rng}, got {v!r}")
    if not (isinstance(params.substeps, numbers.Integral) and int(params.substeps) >= 1):
        raise ValueError(f"sim.substeps: must be an int in the range [1, inf), got {params.substeps!r}")
    if params.mass_error >= 1:
        raise ValueError(f"sim.mass_error: must be a number in the range [0, 1), got {params.mass_error!r}")
    rate = params.control_rate
    if rate is not None and not (isinstance(rate, numbers.Real) and math.isfinite(rate) and float(rate) >= 0):
        raise ValueError(f"sim.control_rate: must be a number >= 0 or None, got {rate!r}")
    for k, d in enumerate(params.disturbances):
        if not 0 <= d.robot < problem.m:
            raise ValueError(f"sim.disturbances[{k}].robot: must be in the range [0, {problem.m}), got {d.robot!r}")
    for k, f in enumerate(params.failures):
        if not 0 <= f.robot < problem.m:
            raise ValueError(f"sim.failures[{k}].robot: must be in the range [0, {problem.m}), got {f.robot!r}")
    check_drive(params.drive)


def _execute(problem, plan, params, progress) -> SimReport:
    """The loop of ideal robots: exact PD force held over each control step."""
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
    kp, kd, limit = float(params.kp), float(params.kd), float(params.force_limit) / mass
    total = plan.makespan + float(params.settle_time)
    n_steps = max(0, math.ceil(total / dt - 1e-9))
    times = np.arange(n_steps + 1) * dt
    m = plan.m
    positions = np.empty((n_steps + 1, m, 2))
    tracking = np.zeros((n_steps + 1, m))

    state = world.state()
    positions[0] = state[:, :2]
    monitor.observe(times[:1], positions[:1])
    forces = world.forces
    step_time = 0.0
    perf = _time.perf_counter
    guard = SpeedGuard(world, witness, monitor, problem.radius, np.full(m, mass), float(params.force_limit), dt, h)

    for k0 in range(0, n_steps, _CHUNK):
        count = min(_CHUNK, n_steps - k0)
        ref = reference_chunk(plan, k0, count, dt)
        for j in range(count):
            acc = pd_acceleration(
                state[:, :2], state[:, 2:], ref.pos[j], ref.vel[j], ref.acc_ff[j], kp, kd, limit
            )
            np.multiply(acc, mass, out=forces)
            t0 = times[k0 + j]
            watch = guard.begin(t0, state)
            for s in range(1, n_sub + 1):
                witness.now = t0 + s * h
                world.apply_forces()
                c0 = perf()
                guard.step(t0 + s * h) if watch else space.step(h)
                step_time += perf() - c0
            state = world.state()
            positions[k0 + j + 1] = state[:, :2]
            if watch:
                guard.end()
        sl = slice(k0 + 1, k0 + count + 1)
        monitor.observe(times[sl], positions[sl])
        err = positions[sl] - ref.pos[1:]
        tracking[sl] = np.sqrt(np.einsum("tik,tik->ti", err, err))
        if progress is not None:
            progress(min(1.0, (k0 + count) / n_steps))
    if progress is not None and n_steps == 0:
        progress(1.0)

    working = np.ones(m, bool)
    ok, final_error, per_robot = reached(positions[-1], problem.target, float(params.tolerance), working)
    return assemble(
        witness, monitor, times, positions, tracking, ok, final_error, per_robot,
        sim_time=float(n_steps * dt), wall0=wall0, step_time=step_time,
        masses=np.full(m, mass), failed=(), disturbances=(), replans=(), stopped="",
        targets_filled=filled(positions[-1], problem.target, float(params.tolerance)),
        phase_margin_deg=phase_margin(kp, kd, 0.5 * dt),
        accept=params.accept, targets_total=len(problem.target),
        targets_working=filled(positions[-1], problem.target, float(params.tolerance)),
    )

