"""The realistic loop: one :class:`_Run` state and the small steps that advance it.

Each control step of ``dt`` runs ``substeps`` physics steps.  At each physics
step the events that fall due are applied (:func:`_apply_events`), the
controller updates when its clock says so, from a noisy measurement or a
filter's estimate (:mod:`sim.execute.estimate`), and puts its force into the
delay line (:func:`_control`), the held force goes out with friction and the
brakes of failed robots (:func:`_actuate`), and pymunk steps.  After each control step the sample is recorded, then recovery looks
at it (:func:`_check_trigger`): a failure or a tracking error above the
trigger brakes the swarm on a stop profile, the robots' positions are
averaged, and the planner plans again from there (:func:`_replan`).
"""

from __future__ import annotations

import math
import time as _time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .contacts import PymunkWitness
from .control import PlanReference, pd_acceleration
from .drive import drive_report, make_drive
from .estimate import failure_delay, make_estimator
from .guard import SpeedGuard
from .monitor import GapMonitor
from .outcome import SimReport, _finite, assemble, filled, reached
from .realism import ControlClock, DelayLine, Events, G, Resistance, Sensor, phase_margin, real_masses, streams
from .recovery import AVERAGE, SETTLE, RecoveryFailed, Replan, StopReference, replan, replan_world
from .world import World, build_world

__all__ = ["CHUNK", "execute_real"]

CHUNK = 64  # control steps per reference batch, monitor batch and progress call
_EPS_T = 1e-9


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
        if len(self.times) - self._seen >= CHUNK:
            self.flush()

    def flush(self) -> None:
        if self._seen < len(self.times):
            sl = slice(self._seen, len(self.times))
            self.monitor.observe(np.array(self.times[sl]), np.array(self.positions[sl]))
            self._seen = len(self.times)


@dataclass(eq=False)
class _Run:
    """Everything the realistic loop carries from one step to the next."""

    # fixed for the run
    problem: Any
    params: Any
    world: World
    witness: PymunkWitness
    samples: _Samples
    gens: dict
    masses: np.ndarray
    sensor: Sensor
    clock: ControlClock
    line: DelayLine
    events: Events
    friction: np.ndarray  # (m,) largest friction force [N]
    replan_params: Any
    resistance: Resistance
    # the reference and what it aims at
    ref: Any
    targets: np.ndarray
    n_end: int  # control steps to run (grows with a replan)
    # robots
    working: np.ndarray
    failed: list = field(default_factory=list)
    disturbances: list = field(default_factory=list)
    replans: list = field(default_factory=list)
    # the bodies' state and the controller's
    state: np.ndarray | None = None
    valid: bool = True  # ``state`` is the bodies' state now
    last_meas_t: float = 0.0
    last_meas: np.ndarray | None = None
    cmd: np.ndarray | None = None  # actuator forces being applied (held)
    act: np.ndarray | None = None  # ... with failed robots' zeroed
    cmd_dirty: bool = True
    resist: bool = False
    memo: list = field(default_factory=lambda: [None, math.nan, None])  # reference, time, (pos, vel, acc)
    # recovery
    mode: str = "track"  # "track" a plan, or "brake" on a stop profile before a replan
    new_failure: str = ""
    trigger_time: float = 0.0
    trigger_reason: str = ""
    avg_from: float = math.inf
    replan_at: float = math.inf
    avg_sum: np.ndarray | None = None
    avg_n: int = 0
    # estimation (:mod:`sim.execute.estimate`) and what recovery knows
    estimator: Any = None  # the filter, or None: the controller measures the true state
    known: np.ndarray | None = None  # (m,) robots recovery believes working
    declared: list = field(default_factory=list)  # failed robots recovery has been told of
    pending: list = field(default_factory=list)  # (time told, robot) of failures not told yet
    budget_used: int = 0  # replans for tracking errors
    budget_exhausted_at: float | None = None
    # bookkeeping
    k: int = 0
    stopped: str = ""
    step_time: float = 0.0
    last_progress: float = 0.0
    drive: Any = None  # a :class:`sim.execute.drive.Drive`, or None for holonomic robots
    guard: Any = None  # a :class:`sim.execute.contacts.SpeedGuard`: watches steps fast enough to tunnel

    @property
    def m(self) -> int:
        return len(self.working)

    @property
    def dt(self) -> float:
        return float(self.params.dt)

    @property
    def h(self) -> float:
        return self.dt / int(self.params.substeps)

    @property
    def a_lim(self) -> float:
        return float(self.params.force_limit) / float(self.params.mass)

    def ref_at(self, t: float):
        """The reference's (pos, vel, acc) at ``t``, computed once per time."""
        memo = self.memo
        if memo[0] is not self.ref or memo[1] != t:
            memo[0], memo[1], memo[2] = self.ref, t, self.ref.at(t)
        return memo[2]

    def fresh_state(self) -> np.ndarray:
        if not self.valid:
            self.state, self.valid = self.world.state(), True
        return self.state


def execute_real(problem, plan, params, rng, planner_params, progress) -> SimReport:
    """The realistic loop (see the module docstring and :mod:`sim.execute.realism`)."""
    wall0 = _time.perf_counter()
    run = _start(problem, plan, params, rng, planner_params)
    err = _record(run, 0.0)
    while run.k < run.n_end:
        _control_step(run)
        run.k += 1
        t_now = run.k * run.dt
        run.state = run.world.state()
        err = _record(run, t_now)
        _check_trigger(run, t_now, err)
        run.new_failure = ""
        if run.mode == "brake" and t_now >= run.replan_at - _EPS_T and not _replan(run, t_now):
            break
        if progress is not None and (run.k % CHUNK == 0 or run.k >= run.n_end):
            run.last_progress = max(run.last_progress, min(1.0, run.k / max(run.n_end, 1)))
            progress(run.last_progress)
    run.samples.flush()
    if progress is not None and run.last_progress < 1.0:
        progress(1.0)
    return _finish(run, wall0)


def _start(problem, plan, params, rng, planner_params) -> _Run:
    """The world with every robot at its first waypoint, and the loop's state at t = 0."""
    import pymunk

    from planner import PlannerParams

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
    dt = float(params.dt)
    friction = float(params.friction) * masses * G
    run = _Run(
        problem=problem, params=params, world=world, witness=PymunkWitness(world),
        samples=_Samples(GapMonitor(problem), m), gens=gens, masses=masses,
        sensor=Sensor(params.noise.position, params.noise.velocity, gens["noise"]),
        clock=ControlClock(params.control_rate, dt), line=DelayLine(params.latency),
        events=Events(params, m, gens["pushes"]), friction=friction,
        replan_params=planner_params if planner_params is not None else PlannerParams(),
        resistance=Resistance(masses, dt / int(params.substeps), friction),
        ref=PlanReference(plan), targets=np.asarray(problem.target, float),
        n_end=max(0, math.ceil((plan.makespan + float(params.settle_time)) / dt - 1e-9)),
        working=np.ones(m, bool), resist=params.friction > 0, avg_sum=np.zeros((m, 2)),
    )
    run.cmd = np.zeros((m, 2))
    run.act = run.cmd
    run.state = world.state()
    run.last_meas = run.state.copy()
    run.drive = make_drive(world, params, plan)
    run.estimator = make_estimator(params, run.state[:, :2], gens, dt)
    run.known = np.ones(m, bool)
    run.guard = SpeedGuard(world, run.witness, run.samples.monitor, radius, masses,
                           2.0 * float(params.force_limit) + float(friction.max(initial=0.0)), dt, run.h)
    return run


def _record(run: _Run, t: float) -> np.ndarray:
    """Record the sample at ``t``; returns each robot's tracking error (NaN when failed)."""
    pos = run.state[:, :2].copy()
    d = pos - run.ref_at(t)[0]
    err = np.sqrt(np.einsum("ik,ik->i", d, d))
    err[~run.working] = np.nan
    run.samples.add(t, pos, err)
    return err


def _control_step(run: _Run) -> None:
    """One control step of ``dt``: ``substeps`` physics steps with events, control and actuation."""
    h = run.h
    t0 = run.k * run.dt
    run.valid = True
    space, perf, drive = run.world.space, _time.perf_counter, run.drive
    watch = run.guard.begin(t0, run.state, run.events.next_time() < t0 + run.dt - _EPS_T)
    for s in range(int(run.params.substeps)):
        t = t0 + s * h
        if run.events.next_time() <= t + _EPS_T:
            _apply_events(run, t)
        if run.estimator is not None and run.estimator.clock.due(t):
            run.estimator.sample(t, run.fresh_state()[:, :2])
        if run.clock.due(t):
            (_control if drive is None else drive.control)(run, t)
        (_actuate if drive is None else drive.actuate)(run, t)
        run.witness.now = t + h
        run.world.apply_forces()
        c0 = perf()
        run.guard.step(t + h) if watch else space.step(h)
        run.step_time += perf() - c0
        run.valid = False
    run.guard.end()


def _apply_events(run: _Run, t: float) -> None:
    """Impulses, pushes and failures that fall due at ``t``."""
    brake = float(run.params.force_limit)  # a failed robot's brake [N]
    for ev in run.events.due(t):
        run.disturbances.append(ev)
        if ev.kind == "failure":
            if run.working[ev.robot]:
                run.working[ev.robot] = False
                run.failed.append(ev.robot)
                run.pending.append((t + failure_delay(run.params), ev.robot))
                run.cmd_dirty = run.resist = True
                run.resistance.set_limit(run.friction + np.where(run.working, 0.0, brake))
        else:
            run.world.bodies[ev.robot].apply_impulse_at_local_point(ev.impulse)
            run.valid = False


def _control(run: _Run, t: float) -> None:
    """The controller's update: measure (or estimate), PD plus feed-forward, into the delay line."""
    if run.estimator is None:
        meas = run.sensor.measure(run.fresh_state())
    else:
        meas = run.estimator.update(t)
    run.last_meas_t, run.last_meas = t, meas
    rp, rv, _ = run.ref_at(t)
    p = run.params
    acc = pd_acceleration(meas[:, :2], meas[:, 2:], rp, rv, run.ref.at(t + 0.5 * run.clock.period)[2],
                          float(p.kp), float(p.kd), run.a_lim)
    run.line.put(t, acc * float(p.mass))
    if run.estimator is not None:
        run.estimator.command(t + run.line.latency, acc)
    if run.mode == "brake" and t >= run.avg_from - _EPS_T:
        run.avg_sum += meas[:, :2]
        run.avg_n += 1


def _actuate(run: _Run, t: float) -> None:
    """The force that acts now: the delayed command (zero for failed robots) plus resistance."""
    new = run.line.take(t)
    if new is not None:
        run.cmd = new
        run.cmd_dirty = True
    forces = run.world.forces
    if run.cmd_dirty:
        run.act = run.cmd * run.working[:, None]
        run.cmd_dirty = False
        if not run.resist:
            forces[:] = run.act
    if run.resist:
        np.add(run.act, run.resistance(run.fresh_state()[:, 2:], run.act), out=forces)


def _check_trigger(run: _Run, t_now: float, err: np.ndarray) -> None:
    """Recovery's trigger: a new failure or a tracking error above the trigger starts braking."""
    while run.pending and run.pending[0][0] <= t_now + _EPS_T:  # told after the failure detection delay
        robot = run.pending.pop(0)[1]
        run.known[robot] = False
        run.declared.append(robot)
        run.new_failure = run.new_failure or f"robot {robot} failed"
        run.trigger_reason += f"; robot {robot} failed" if run.mode == "brake" else ""  # the coming replan
    rec = run.params.recovery
    if not (rec.replan and run.mode == "track"):
        return
    working = run.known
    reason = run.new_failure  # a failure is always answered: it does not use the budget
    if not reason and working.any():
        if run.estimator is not None:  # recovery sees the estimate, not the truth
            err = run.estimator.growing_error(t_now, *run.ref_at(t_now)[:2])
        worst = int(np.nanargmax(np.where(working, err, -np.inf)))
        if err[worst] > rec.trigger:
            if run.budget_used >= rec.max_replans:  # exhausted: named in the report
                run.budget_exhausted_at = t_now if run.budget_exhausted_at is None else run.budget_exhausted_at
                return
            run.budget_used += 1
            reason = f"tracking error {err[worst]:.3g} of robot {worst} > trigger {rec.trigger:g}"
    if reason and working.any():
        run.mode = "brake"
        run.trigger_time, run.trigger_reason = t_now, reason
        stop = StopReference(run.last_meas_t, run.last_meas[:, :2], run.last_meas[:, 2:], 0.5 * run.a_lim)
        run.ref = stop
        run.avg_from = max(stop.end, t_now) + SETTLE
        run.replan_at = run.avg_from + AVERAGE
        run.avg_sum[:] = 0.0
        run.avg_n = 0
        run.n_end = max(run.n_end, math.ceil(run.replan_at / run.dt - 1e-9) + 1)


def _replan(run: _Run, t_now: float) -> bool:
    """Plan again from the averaged positions; False when no plan was found (the run stops)."""
    from planner import min_clearance

    problem = run.problem
    start = run.avg_sum / run.avg_n if run.avg_n else run.last_meas[:, :2].copy()
    rows = np.flatnonzero(run.known)
    fixed = start[~run.known]
    wall = _time.perf_counter()
    try:
        found = replan(problem, start[rows], fixed, problem.target, run.replan_params,
                       run.params.recovery.replan_time_limit, run.gens["replan"])
    except RecoveryFailed as exc:
        run.replans.append(Replan(run.trigger_time, t_now, run.trigger_reason, len(rows), tuple(run.declared), (),
                                  False, False, 0, 0.0, None, _time.perf_counter() - wall, str(exc)))
        run.stopped = f"replan at t = {t_now:.3f} s found no way on: {exc}"
        return False
    new_plan = found.plan
    run.targets = found.targets
    gap = _finite(min_clearance(replan_world(problem, fixed, start[rows], run.targets), new_plan).value)
    run.replans.append(Replan(run.trigger_time, t_now, run.trigger_reason, len(rows), tuple(run.declared),
                              tuple(int(i) for i in found.dropped), found.separated, True, new_plan.steps,
                              new_plan.makespan, gap, found.planning_time_s,
                              parked=tuple((float(x), float(y)) for x, y in found.parked)))
    run.ref = PlanReference(new_plan, t_now, rows, start)
    run.mode = "track"
    run.avg_from = run.replan_at = math.inf
    run.n_end = run.k + max(0, math.ceil((new_plan.makespan + float(run.params.settle_time)) / run.dt - 1e-9))
    return True


def _finish(run: _Run, wall0: float) -> SimReport:
    """The run's report: samples, the end-of-run matching, the phase margin."""
    samples, m, p = run.samples, run.m, run.params
    times = np.array(samples.times)
    positions = np.array(samples.positions).reshape(len(times), m, 2)
    tracking = np.array(samples.tracking).reshape(len(times), m)
    ok, final_error, per_robot = reached(positions[-1], run.targets, float(p.tolerance), run.working)
    if run.stopped:
        ok = False
    return assemble(
        run.witness, samples.monitor, times, positions, tracking, ok, final_error, per_robot,
        sim_time=float(times[-1]), wall0=wall0, step_time=run.step_time, masses=run.masses, failed=run.failed,
        disturbances=run.disturbances, replans=run.replans, stopped=run.stopped,
        targets_filled=filled(positions[-1], run.problem.target, float(p.tolerance)),
        phase_margin_deg=phase_margin(float(p.kp), float(p.kd), float(p.latency) + 0.5 * run.clock.period),
        accept=p.accept, targets_total=len(run.problem.target), budget_exhausted_at=run.budget_exhausted_at,
        targets_working=filled(positions[-1][run.working], run.problem.target, float(p.tolerance)),
        on_budget=p.recovery.on_budget,
        **drive_report(run.drive, len(times)),
    )

