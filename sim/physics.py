"""Execute a timed plan in pymunk and report what happened.

:func:`execute` builds the world (:mod:`sim.world`), puts each robot at its
first waypoint, and runs ``ceil((makespan + settle_time) / dt)`` control
steps.  Each control step computes the PD + feed-forward force of every
robot at once (:mod:`sim.control`), holds it for ``substeps`` physics
steps, and records the positions.  Two witnesses watch for contacts
(:mod:`sim.contacts`): pymunk's collision callbacks, at every physics step,
and an exact geometric monitor, at every recorded sample.

Ideal robots (every realism knob of :class:`sim.params.SimParams` off) run
in a tight loop.  Otherwise the realistic loop runs: at every physics step
the disturbances that fall due are applied, the controller updates when its
clock says so (from a noisy measurement; the force goes through the delay
line), and friction and the brakes of failed robots act (:mod:`sim.realism`).
With recovery on, a tracking error above the trigger or a failure stops the
swarm and the planner plans again (:mod:`sim.recovery`).  Both loops give
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
from dataclasses import dataclass
from typing import Callable

import numpy as np

from .contacts import Contact, GapMonitor, PymunkWitness
from .control import PlanReference, pd_acceleration, reference_chunk
from .realism import (
    G,
    ControlClock,
    DelayLine,
    Disturbance,
    Events,
    Resistance,
    Sensor,
    phase_margin,
    real_masses,
    streams,
)
from .recovery import AVERAGE, SETTLE, RecoveryFailed, Replan, StopReference, replan
from .words import plural, reached_phrase, run_notes
from .world import build_world

__all__ = ["Contact", "Disturbance", "Replan", "SimReport", "execute"]

_CHUNK = 64  # control steps per reference batch, monitor batch and progress call
_LIST_MAX = 1000  # contacts and disturbances listed in full by SimReport.to_dict
_EPS_T = 1e-9


@dataclass(frozen=True, eq=False)
class SimReport:
    """The outcome of one physics run.

    contacts: every touching episode, both witnesses, in time order.
    min_clearance: smallest gap seen by the monitor [units]: between two
        disc boundaries, or between a disc and an obstacle or wall
        (negative means overlap).
    min_clearance_time: when it occurred [s].
    max_tracking_error: the largest ``|x - x_ref|`` over working robots and
        all samples, settling included [units].
    reached: after settling, every working robot is within ``tolerance`` of
        a distinct target (minimum-cost matching of robots to targets).
    final_error: the largest matched robot-target distance at the end [units].
    sim_time_s: simulated time [s]; wall_time_s: wall-clock time of the run [s].
    times: ``(T,)`` sample times, one per control step, from 0.
    positions: ``(T, m, 2)`` body positions at those times.
    min_clearance_kind, min_clearance_pair: what attained ``min_clearance``
        (two robots; or a robot and an obstacle index, ``-1`` for the wall).
    step_time_s: wall-clock time spent inside ``space.step`` [s].
    min_gap: ``(T,)`` smallest gap of each sample over all robot pairs,
        obstacles and walls [units], exact up to one robot diameter
        (larger gaps are recorded as ``2 * radius``).
    tracking_error: ``(T, m)`` distance of each robot from its reference
        [units]; NaN for a failed robot.  The reference is the plan, the
        stop profile while braking for a replan, then the new plan.
    max_tracking_error_time, max_tracking_error_robot: where the largest
        tracking error was [s], robot index.
    reached_robots: ``(m,)`` whether each robot ended within ``tolerance``
        of its matched target (``False`` for a failed robot).
    masses: ``(m,)`` the bodies' real masses.
    failed: the failed robots, in the order they failed.
    disturbances: every impulse, push and failure as applied.
    replans: every replan (:class:`sim.recovery.Replan`).
    stopped: why the run ended early (a replan found no way on), or ``""``.
    targets_filled: how many of the problem's targets have a robot (working
        or failed) within ``tolerance`` at the end (matching).
    phase_margin_deg: the controller's phase margin with its delays
        (:func:`sim.realism.phase_margin`; latency plus half the hold);
        at or below zero the loop is unstable and the verdict says so.
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
    min_gap: np.ndarray | None = None
    tracking_error: np.ndarray | None = None
    max_tracking_error_time: float = float("nan")
    max_tracking_error_robot: int = -1
    reached_robots: np.ndarray | None = None
    masses: np.ndarray | None = None
    failed: tuple[int, ...] = ()
    disturbances: tuple[Disturbance, ...] = ()
    replans: tuple[Replan, ...] = ()
    stopped: str = ""
    targets_filled: int = -1
    phase_margin_deg: float = float("nan")

    @property
    def ok(self) -> bool:
        """No contact by either witness, and every working robot on a distinct target."""
        return not self.contacts and self.reached and not self.stopped

    @property
    def parked(self) -> int:
        """Working robots that end on a parking place (failed robots block their targets)."""
        return len(getattr(self.replans[-1], "parked", ())) if self.replans else 0

    @property
    def first_contact(self) -> Contact | None:
        return self.contacts[0] if self.contacts else None

    def series(self, max_samples: int = 2000) -> dict | None:
        """``times``, ``min_gap`` and ``tracking_error`` thinned for plots (:func:`sim.series.thin`), or None."""
        if self.min_gap is None or self.tracking_error is None:
            return None
        from .series import thin

        arrays = {"times": self.times, "min_gap": self.min_gap, "tracking_error": self.tracking_error}
        return thin(arrays, max_samples)

    @property
    def realtime_factor(self) -> float:
        """Simulated seconds per wall-clock second."""
        return self.sim_time_s / self.wall_time_s if self.wall_time_s > 0 else math.inf

    @property
    def verdict(self) -> str:
        """One line: what happened."""
        parts = []
        if self.contacts:
            c = self.contacts[0]
            parts.append(f"{plural(len(self.contacts), 'contact')}, the first: {c.describe()}")
        if self.stopped:
            parts.append(f"stopped: {self.stopped}")
        if self.reached_robots is not None and not self.reached and not self.stopped:
            working = [i for i in range(len(self.reached_robots)) if i not in self.failed]
            missed = [i for i in working if not self.reached_robots[i]]
            who = ", ".join(str(i) for i in missed[:10]) + (" ..." if len(missed) > 10 else "")
            parts.append(f"robots {who} end off target (worst {self.final_error:.3g})")
        m = 0 if self.reached_robots is None else len(self.reached_robots)
        if not self.contacts and not self.stopped and self.reached:
            parts.insert(0, "no contact, " + reached_phrase(bool(self.failed), self.parked))
        parts += run_notes(self.failed, self.parked, self.targets_filled, m, len(self.replans),
                           self.phase_margin_deg, advice=True)
        return "; ".join(parts)

    def to_dict(self) -> dict:
        """JSON-ready summary (no per-sample arrays)."""
        d = {
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
        if len(self.contacts) > _LIST_MAX:
            d["contact_list_truncated"] = True
        d["first_contact"] = self.contacts[0].to_dict() if self.contacts else None
        d["max_tracking_error_time"] = _finite(self.max_tracking_error_time)
        d["max_tracking_error_robot"] = self.max_tracking_error_robot
        if self.reached_robots is not None:
            d["reached_robots"] = [bool(v) for v in self.reached_robots]
        if self.masses is not None and len(self.masses):
            d["mass_range"] = [float(self.masses.min()), float(self.masses.max())]
        d["failed"] = list(self.failed)
        kinds = [x.kind for x in self.disturbances]
        d["disturbances"] = {
            "impulses": kinds.count("impulse"),
            "pushes": kinds.count("push"),
            "failures": kinds.count("failure"),
            "list": [x.to_dict() for x in self.disturbances[:_LIST_MAX]],
        }
        if len(self.disturbances) > _LIST_MAX:
            d["disturbances"]["list_truncated"] = True
        d["replans"] = [r.to_dict() for r in self.replans]
        d["stopped"] = self.stopped or None
        d["targets_filled"] = self.targets_filled
        d["phase_margin_deg"] = _finite(self.phase_margin_deg)
        d["verdict"] = self.verdict
        return d


def _finite(v: float):
    v = float(v)
    return v if math.isfinite(v) else None


def execute(problem, plan, params, rng: np.random.Generator | None = None, *,
            planner_params=None, progress: Callable[[float], None] | None = None) -> SimReport:
    """Run ``plan`` in ``problem``'s world with PD-controlled disc bodies.

    ``params`` is a :class:`sim.params.SimParams`.  ``rng`` is the run's
    generator; every random draw of the run (masses, noise, pushes,
    replanning) comes from streams derived from it
    (:func:`sim.realism.streams`); default: seeded with 0.
    ``planner_params`` (:class:`planner.PlannerParams`) are used by
    replans.  ``progress``, if given, is called now and then with the
    fraction of simulated time done (ends with ``1.0``).  Raises
    ``ValueError`` naming the parameter when the inputs do not fit together.
    """
    _check(problem, plan, params)
    if not params.realistic:
        return _execute(problem, plan, params, progress)
    rng = rng if rng is not None else np.random.default_rng(0)
    return _execute_real(problem, plan, params, rng, planner_params, progress)


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
    if not (isinstance(params.substeps, numbers.Integral) and params.substeps >= 1):
        raise ValueError(f"sim.substeps: must be an int in the range [1, inf), got {params.substeps!r}")
    if params.mass_error >= 1:
        raise ValueError(f"sim.mass_error: must be a number in the range [0, 1), got {params.mass_error!r}")
    rate = params.control_rate
    if rate is not None and not (isinstance(rate, numbers.Real) and math.isfinite(rate) and rate >= 0):
        raise ValueError(f"sim.control_rate: must be a number >= 0 or None, got {rate!r}")
    for k, d in enumerate(params.disturbances):
        if not 0 <= d.robot < problem.m:
            raise ValueError(f"sim.disturbances[{k}].robot: must be in the range [0, {problem.m}), got {d.robot!r}")
    for k, f in enumerate(params.failures):
        if not 0 <= f.robot < problem.m:
            raise ValueError(f"sim.failures[{k}].robot: must be in the range [0, {problem.m}), got {f.robot!r}")


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
        err = positions[sl] - ref.pos[1:]
        tracking[sl] = np.sqrt(np.einsum("tik,tik->ti", err, err))
        if progress is not None:
            progress(min(1.0, (k0 + count) / n_steps))
    if progress is not None and n_steps == 0:
        progress(1.0)

    working = np.ones(m, bool)
    reached, final_error, per_robot = _reached(positions[-1], problem.target, float(params.tolerance), working)
    return _report(
        witness, monitor, times, positions, tracking, reached, final_error, per_robot,
        sim_time=float(n_steps * dt), wall0=wall0, step_time=step_time,
        masses=np.full(m, mass), failed=(), disturbances=(), replans=(), stopped="",
        targets_filled=_filled(positions[-1], problem.target, float(params.tolerance)),
        phase_margin_deg=phase_margin(kp, kd, 0.5 * dt),
    )


def _report(witness, monitor, times, positions, tracking, reached, final_error, per_robot,
            *, sim_time, wall0, step_time, masses, failed, disturbances, replans, stopped,
            targets_filled, phase_margin_deg) -> SimReport:
    contacts = sorted(
        witness.contacts() + monitor.contacts(),
        key=lambda c: (c.time, c.witness != "pymunk", c.kind, c.a, c.b),
    )
    if np.isfinite(tracking).any():
        flat = int(np.nanargmax(tracking))
        s, i = divmod(flat, tracking.shape[1])
        track, track_time, track_robot = float(tracking[s, i]), float(times[s]), int(i)
    else:
        track, track_time, track_robot = 0.0, float("nan"), -1
    min_gap = monitor.series
    for a in (times, positions, tracking, min_gap, per_robot, masses):
        a.setflags(write=False)
    return SimReport(
        contacts=tuple(contacts),
        min_clearance=monitor.min_gap,
        min_clearance_time=monitor.min_time,
        max_tracking_error=track,
        reached=reached,
        final_error=final_error,
        sim_time_s=sim_time,
        wall_time_s=_time.perf_counter() - wall0,
        times=times,
        positions=positions,
        min_clearance_kind=monitor.min_kind,
        min_clearance_pair=monitor.min_pair,
        step_time_s=step_time,
        min_gap=min_gap,
        tracking_error=tracking,
        max_tracking_error_time=track_time,
        max_tracking_error_robot=track_robot,
        reached_robots=per_robot,
        masses=masses,
        failed=tuple(failed),
        disturbances=tuple(disturbances),
        replans=tuple(replans),
        stopped=stopped,
        targets_filled=targets_filled,
        phase_margin_deg=phase_margin_deg,
    )


class _Samples:
    """Recorded samples, handed to the monitor in batches."""

    def __init__(self, monitor: GapMonitor, m: int):
        self.monitor = monitor
        self.times: list[float] = []
        self.positions: list[np.ndarray] = []
        self.tracking: list[np.ndarray] = []
        self._seen = 0

    def add(self, t: float, pos: np.ndarray, err: np.ndarray) -> None:
        self.times.append(t)
        self.positions.append(pos)
        self.tracking.append(err)
        if len(self.times) - self._seen >= _CHUNK:
            self.flush()

    def flush(self) -> None:
        if self._seen < len(self.times):
            sl = slice(self._seen, len(self.times))
            self.monitor.observe(np.array(self.times[sl]), np.array(self.positions[sl]))
            self._seen = len(self.times)


def _execute_real(problem, plan, params, rng, planner_params, progress) -> SimReport:
    """The realistic loop (see the module docstring and :mod:`sim.realism`)."""
    import pymunk

    from planner import PlannerParams

    wall0 = _time.perf_counter()
    perf = _time.perf_counter
    gens = streams(rng)
    world = build_world(problem, params)
    m = plan.m
    radius = float(problem.radius)
    masses = real_masses(float(params.mass), float(params.mass_error), m, gens["masses"])
    for body, p, mass_i in zip(world.bodies, plan.start, masses):
        if params.mass_error > 0:
            body.mass = float(mass_i)
            body.moment = pymunk.moment_for_circle(float(mass_i), 0.0, radius)
        body.position = (float(p[0]), float(p[1]))
    space = world.space
    witness = PymunkWitness(world)
    monitor = GapMonitor(problem)
    samples = _Samples(monitor, m)

    dt = float(params.dt)
    n_sub = int(params.substeps)
    h = dt / n_sub
    model_mass = float(params.mass)
    kp, kd = float(params.kp), float(params.kd)
    a_lim = float(params.force_limit) / model_mass
    sensor = Sensor(params.noise.position, params.noise.velocity, gens["noise"])
    clock = ControlClock(params.control_rate, dt)
    line = DelayLine(params.latency)
    events = Events(params, m, gens["pushes"])
    friction = float(params.friction) * masses * G  # (m,) largest friction force [N]
    brake = float(params.force_limit)  # a failed robot's brake [N]
    rec = params.recovery
    replan_params = planner_params if planner_params is not None else PlannerParams()
    forces = world.forces
    bodies = world.bodies

    working = np.ones(m, bool)
    failed: list[int] = []
    disturbances: list[Disturbance] = []
    replans: list[Replan] = []
    targets = np.asarray(problem.target, float)
    ref = PlanReference(plan)
    end = plan.makespan + float(params.settle_time)
    n_end = max(0, math.ceil(end / dt - 1e-9))
    stopped = ""
    step_time = 0.0

    cmd = np.zeros((m, 2))  # actuator forces being applied (held)
    cmd_dirty = True
    memo = [None, math.nan, None]  # reference object, time, its (pos, vel, acc) there
    half = 0.5 * clock.period

    def ref_at(t: float):
        if memo[0] is not ref or memo[1] != t:
            memo[0], memo[1], memo[2] = ref, t, ref.at(t)
        return memo[2]

    mode = "track"
    new_failure = ""
    trigger_time, trigger_reason = 0.0, ""
    avg_from = replan_at = math.inf
    avg_sum, avg_n = np.zeros((m, 2)), 0
    state = world.state()
    last_meas_t, last_meas = 0.0, state.copy()

    def record(t: float, state: np.ndarray) -> float:
        pos = state[:, :2].copy()
        rp = ref_at(t)[0]
        d = pos - rp
        err = np.sqrt(np.einsum("ik,ik->i", d, d))
        err[~working] = np.nan
        samples.add(t, pos, err)
        return err

    err = record(0.0, state)
    k = 0
    last_progress = 0.0
    resist = params.friction > 0
    resistance = Resistance(masses, h, friction)
    act = cmd
    while k < n_end:
        t0 = k * dt
        valid = True  # ``state`` is the bodies' state now
        for s in range(n_sub):
            t = t0 + s * h
            if events.next_time() <= t + _EPS_T:
                for ev in events.due(t):
                    disturbances.append(ev)
                    if ev.kind == "failure":
                        if working[ev.robot]:
                            working[ev.robot] = False
                            failed.append(ev.robot)
                            new_failure = new_failure or f"robot {ev.robot} failed"
                            cmd_dirty = resist = True
                            resistance.set_limit(friction + np.where(working, 0.0, brake))
                    else:
                        bodies[ev.robot].apply_impulse_at_local_point(ev.impulse)
                        valid = False
            if clock.due(t):
                if not valid:
                    state, valid = world.state(), True
                meas = sensor.measure(state)
                last_meas_t, last_meas = t, meas
                rp, rv, _ = ref_at(t)
                acc = pd_acceleration(meas[:, :2], meas[:, 2:], rp, rv, ref.at(t + half)[2], kp, kd, a_lim)
                line.put(t, acc * model_mass)
                if mode == "brake" and t >= avg_from - _EPS_T:
                    avg_sum += meas[:, :2]
                    avg_n += 1
            new = line.take(t)
            if new is not None:
                cmd = new
                cmd_dirty = True
            if cmd_dirty:
                act = cmd * working[:, None]
                cmd_dirty = False
                if not resist:
                    forces[:] = act
            if resist:
                if not valid:
                    state, valid = world.state(), True
                np.add(act, resistance(state[:, 2:], act), out=forces)
            witness.now = t + h
            world.apply_forces()
            c0 = perf()
            space.step(h)
            step_time += perf() - c0
            valid = False
        k += 1
        t_now = k * dt
        state = world.state()
        err = record(t_now, state)

        # -- recovery ---------------------------------------------------------
        if rec.replan and mode == "track" and len(replans) < rec.max_replans:
            reason = new_failure
            if not reason and working.any():
                worst = int(np.nanargmax(np.where(working, err, -np.inf)))
                if err[worst] > rec.trigger:
                    reason = f"tracking error {err[worst]:.3g} of robot {worst} > trigger {rec.trigger:g}"
            if reason and working.any():
                mode = "brake"
                trigger_time, trigger_reason = t_now, reason
                stop = StopReference(last_meas_t, last_meas[:, :2], last_meas[:, 2:], 0.5 * a_lim)
                ref = stop
                avg_from = max(stop.end, t_now) + SETTLE
                replan_at = avg_from + AVERAGE
                avg_sum[:] = 0.0
                avg_n = 0
                n_end = max(n_end, math.ceil(replan_at / dt - 1e-9) + 1)
        new_failure = ""
        if mode == "brake" and t_now >= replan_at - _EPS_T:
            start = avg_sum / avg_n if avg_n else last_meas[:, :2].copy()
            rows = np.flatnonzero(working)
            fixed = start[~working]
            wall = perf()
            try:
                found = replan(problem, start[rows], fixed, problem.target, replan_params, rec.time_limit,
                               gens["replan"])
            except RecoveryFailed as exc:
                replans.append(Replan(trigger_time, t_now, trigger_reason, len(rows), tuple(failed), (), False,
                                      False, 0, 0.0, None, perf() - wall, str(exc)))
                stopped = f"replan at t = {t_now:.3f} s found no way on: {exc}"
                break
            from planner import min_clearance

            new_plan = found.plan
            targets = found.targets
            gap = _finite(min_clearance(_replan_world(problem, fixed, start[rows], targets), new_plan).value)
            replans.append(Replan(trigger_time, t_now, trigger_reason, len(rows), tuple(failed),
                                  tuple(int(i) for i in found.dropped), found.separated, True, new_plan.steps,
                                  new_plan.makespan, gap, found.planning_time_s,
                                  parked=tuple((float(x), float(y)) for x, y in found.parked)))
            ref = PlanReference(new_plan, t_now, rows, start)
            mode = "track"
            avg_from = replan_at = math.inf
            n_end = k + max(0, math.ceil((new_plan.makespan + float(params.settle_time)) / dt - 1e-9))
        if progress is not None and (k % _CHUNK == 0 or k >= n_end):
            last_progress = max(last_progress, min(1.0, k / max(n_end, 1)))
            progress(last_progress)
    samples.flush()
    if progress is not None and last_progress < 1.0:
        progress(1.0)

    times = np.array(samples.times)
    positions = np.array(samples.positions).reshape(len(times), m, 2)
    tracking = np.array(samples.tracking).reshape(len(times), m)
    reached, final_error, per_robot = _reached(positions[-1], targets, float(params.tolerance), working)
    if stopped:
        reached = False
    return _report(
        witness, monitor, times, positions, tracking, reached, final_error, per_robot,
        sim_time=float(times[-1]), wall0=wall0, step_time=step_time, masses=masses, failed=failed,
        disturbances=disturbances, replans=replans, stopped=stopped,
        targets_filled=_filled(positions[-1], problem.target, float(params.tolerance)),
        phase_margin_deg=phase_margin(kp, kd, float(params.latency) + 0.5 * clock.period),
    )


def _replan_world(problem, fixed, start, targets):
    """The replan's world (failed robots as discs) for measuring the new plan's exact clearance."""
    from planner import Circle, Problem

    obstacles = tuple(problem.obstacles) + tuple(Circle((float(x), float(y)), problem.radius) for x, y in fixed)
    return Problem(problem.width, problem.height, obstacles, problem.radius, problem.margin, start, targets,
                   problem.max_speed, problem.max_accel)


def _filled(final: np.ndarray, target: np.ndarray, tolerance: float) -> int:
    """How many targets have a robot within ``tolerance`` (a largest matching of robots to targets)."""
    from scipy.optimize import linear_sum_assignment

    target = np.asarray(target, float).reshape(-1, 2)
    far = np.linalg.norm(final[:, None, :] - target[None, :, :], axis=2) > tolerance
    rows, cols = linear_sum_assignment(far.astype(float))
    return int((~far[rows, cols]).sum())


def _reached(final: np.ndarray, target: np.ndarray, tolerance: float, working: np.ndarray):
    """Match working robots to distinct targets at least total distance.

    Returns ``(all working robots within tolerance, worst matched distance,
    (m,) per-robot flags)``.
    """
    from scipy.optimize import linear_sum_assignment

    m = len(final)
    per = np.zeros(m, bool)
    target = np.asarray(target, float).reshape(-1, 2)
    rows_w = np.flatnonzero(working)
    if len(rows_w) == 0:
        return True, 0.0, per
    if len(target) < len(rows_w):
        return False, math.inf, per
    cost = np.linalg.norm(final[rows_w][:, None, :] - target[None, :, :], axis=2)
    rows, cols = linear_sum_assignment(cost)
    d = cost[rows, cols]
    per[rows_w[rows]] = d <= tolerance
    worst = float(d.max())  # rows_w is not empty, so neither is the matching
    return bool(worst <= tolerance), worst, per
