"""Drive models of the realistic loop: differential-drive (unicycle) and velocity-tracking robots.

``sim.drive.model`` picks how a robot moves (:class:`sim.scenario.params.DriveParams`):

* ``holonomic`` (default): a disc pushed by a force in any direction, the
  PD + feed-forward of :mod:`sim.execute.control`.  No :class:`Drive` object;
  the run is byte for byte what it was before drive models existed.
* ``differential``: two wheels ``wheel_base`` apart on the disc's axle.  The
  body has a heading (``body.angle``, 0 along +x, counter-clockwise
  positive) and the disc's moment of inertia.  With wheel speeds ``v_l``,
  ``v_r`` [units/s] the robot moves at ``v = (v_r + v_l) / 2`` along its
  heading and turns at ``omega = (v_r - v_l) / wheel_base`` [rad/s].
  No lateral slip: before every physics step the sideways velocity is
  cancelled (the impulse ``-m (v . n) n``, ``n`` the heading's normal, as in
  pymunk's top-down examples; it is written back with the forward speed and
  turn rate through :mod:`pymunk.batch`).  The wheels are velocity
  controlled: each physics step of ``h`` a wheel's speed moves towards its
  command by at most ``wheel_accel * h`` and never beyond ``wheel_speed``;
  the wheels' present speeds are read back from the body, so a contact or
  a push that slows the robot also slows its wheels.  Floor friction is
  the wheels' business and not applied.
* ``velocity``: a holonomic body that tracks velocity set-points to first
  order, like a quadrotor's inner loop: ``v' = (v_cmd - v) / time_constant``
  (applied as the force of the exact zero-order-hold step,
  ``F = mass (v_cmd - v) (1 - exp(-h / tau)) / h``, at most ``force_limit``,
  from the body's own velocity at every physics step).

Tracking.  The velocity set-point of robot ``i`` is the single-integrator
command ``U = v_ref + kp_v (p_ref - p)``, at most ``max_speed``
(``velocity``) or ``wheel_speed`` (``differential``) in norm, computed at the
controller's rate from the measured position and sent through the delay
line.  A velocity robot takes ``v_cmd = U``.  A differential robot maps ``U``
to ``(v, omega)`` by feedback linearisation of the point ``lookahead`` ahead
of its axle (the near-identity diffeomorphism ``y = p + l (cos th, sin th)``)::

    v = cos(th) U_x + sin(th) U_y,      omega = (-sin(th) U_x + cos(th) U_y) / l

Siciliano, Sciavicco, Villani, Oriolo, "Robotics: Modelling, Planning and
Control", Springer 2009, sec. 11.6.2 ("input/output linearization"); the
same mapping as the Robotarium's ``create_si_to_uni_dynamics``.  The
reference of the look-ahead point is carried with the heading
(``y_ref = p_ref + l (cos th, sin th)``), so ``U`` steers the centre, which is
what the tracking error and the targets measure.  The wheel speeds
``v -/+ omega wheel_base / 2`` are scaled down together to ``wheel_speed``
(same curvature).  The heading is measured without noise.

A differential robot starts facing its first motion in the plan (0 when
it never moves).  :func:`drive_timing` tells how far the plan's timing is
from what the drive can do (:mod:`sim.execute.drive_timing`).
"""

from __future__ import annotations

import math

import numpy as np
import pymunk.batch as _batch

from .drive_timing import drive_timing, timing_notes

__all__ = ["DIFFERENTIAL", "HOLONOMIC", "MODELS", "VELOCITY", "Drive", "check_drive", "drive_report", "drive_timing",
           "initial_headings", "make_drive", "saturate", "timing_notes", "unicycle_wheels"]

HOLONOMIC, DIFFERENTIAL, VELOCITY = "holonomic", "differential", "velocity"
MODELS = (HOLONOMIC, DIFFERENTIAL, VELOCITY)
_EPS_T = 1e-9
_F = _batch.BodyFields
_SPIN = _F.ANGLE | _F.VELOCITY | _F.ANGULAR_VELOCITY  # rows [th, vx, vy, omega]
_SET = _F.VELOCITY | _F.ANGULAR_VELOCITY  # rows [vx, vy, omega]


def check_drive(d) -> None:
    """Raise ``ValueError`` naming ``sim.drive.X``, its range and the value, when ``d`` is out of range."""
    if d.model not in MODELS:
        raise ValueError(f"sim.drive.model: must be one of {', '.join(MODELS)}, got {d.model!r}")
    for name, low, high in (("wheel_base", 0.0, 100.0), ("wheel_speed", 0.0, 1000.0), ("wheel_accel", 0.0, 1e5),
                            ("lookahead", 0.0, 100.0), ("time_constant", 0.0, 10.0), ("max_speed", 0.0, 1000.0),
                            ("kp_v", -1.0, 1000.0)):
        v = getattr(d, name)
        ok = isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
        if not (ok and (v >= 0 if low < 0 else v > low) and v <= high):
            span = f"[0, {high:g}]" if low < 0 else f"({low:g}, {high:g}]"
            raise ValueError(f"sim.drive.{name}: must be a number in {span}, got {v!r}")


def saturate(u: np.ndarray, limit: float) -> np.ndarray:
    """Rows of ``u`` ``(m, 2)`` scaled down to norm ``limit`` where longer (a new array)."""
    u = np.array(u, float)
    n = np.sqrt(np.einsum("ij,ij->i", u, u))
    over = n > limit
    if over.any():
        u[over] *= (limit / n[over])[:, None]
    return u


def unicycle_wheels(u: np.ndarray, theta: np.ndarray, lookahead: float, wheel_base: float,
                    wheel_speed: float) -> np.ndarray:
    """Wheel speeds ``(m, 2)`` ``[v_l, v_r]`` that move the look-ahead point at ``u`` (``(m, 2)``).

    ``v = u . (cos th, sin th)``, ``omega = u . (-sin th, cos th) / lookahead``;
    both wheels are scaled by one factor so that neither exceeds
    ``wheel_speed`` (the curvature ``omega / v`` is kept).
    """
    c, s = np.cos(theta), np.sin(theta)
    v = c * u[:, 0] + s * u[:, 1]
    omega = (c * u[:, 1] - s * u[:, 0]) / lookahead
    half = 0.5 * wheel_base * omega
    wheels = np.stack([v - half, v + half], axis=1)
    peak = np.abs(wheels).max(axis=1)
    over = peak > wheel_speed
    if over.any():
        wheels[over] *= (wheel_speed / peak[over])[:, None]
    return wheels


def initial_headings(plan) -> np.ndarray:
    """``(m,)`` heading of each robot's first move in ``plan`` [rad]; 0 for a robot that never moves."""
    d = np.diff(np.asarray(plan.waypoints, float), axis=0)  # (K, m, 2)
    m = plan.m
    out = np.zeros(m)
    if len(d) == 0:
        return out
    moving = np.hypot(d[..., 0], d[..., 1]) > 1e-12
    has = moving.any(axis=0)
    first = np.argmax(moving, axis=0)
    rows = np.flatnonzero(has)
    first_d = d[first[rows], rows]
    out[rows] = np.arctan2(first_d[:, 1], first_d[:, 0])
    return out


def make_drive(world, params, plan):
    """The :class:`Drive` of ``params.drive`` for a realistic run, or ``None`` for holonomic robots.

    A differential drive turns every body to its :func:`initial_headings`.
    """
    d = params.drive
    if d.model == HOLONOMIC:
        return None
    cls = DifferentialDrive if d.model == DIFFERENTIAL else VelocityDrive
    return cls(world, params, plan)


def drive_report(drive, samples: int) -> dict:
    """The :func:`sim.execute.outcome.assemble` keywords of a run's ``drive`` (none for holonomic robots)."""
    if drive is None:
        return {}
    return {"headings": drive.headings(samples), "drive": drive.d.model, "drive_timing": drive.timing}


class Drive:
    """The command and actuation of one non-holonomic run (state kept between steps).

    :meth:`control` is the controller update (instead of the PD of
    :func:`sim.execute.real._control`), :meth:`actuate` the per-physics-step
    actuation (instead of :func:`sim.execute.real._actuate`).  ``run`` is the
    realistic loop's ``_Run``.  A drive with headings keeps them at the start
    of every control step (every ``substeps``-th actuation), which is where
    the loop records its samples.
    """

    has_headings = False

    def __init__(self, world, params, plan):
        self.world = world
        self.params = params
        self.d = params.drive
        self.m = world.m
        self.timing = drive_timing(plan, self.d)
        self.cmd = np.zeros((self.m, 2))
        self._headings: list[np.ndarray] = []
        self._substeps = int(params.substeps)
        self._calls = 0  # actuations so far

    def control(self, run, t: float) -> None:
        """Measure, compute the command from the reference, put it into the delay line."""
        estimator = getattr(run, "estimator", None)
        if estimator is None:
            meas = run.sensor.measure(run.fresh_state())
        else:  # a filter's estimate (:mod:`sim.execute.estimate`), with no acceleration input
            meas = estimator.update(t)
        run.last_meas_t, run.last_meas = t, meas
        rp, rv, _ = run.ref_at(t)
        u = rv + float(self.d.kp_v) * (rp - meas[:, :2])
        run.line.put(t, self.command(u))
        if run.mode == "brake" and t >= run.avg_from - _EPS_T:
            run.avg_sum += meas[:, :2]
            run.avg_n += 1

    def take(self, run, t: float) -> None:
        new = run.line.take(t)
        if new is not None:
            self.cmd = new

    def headings(self, samples: int) -> np.ndarray | None:
        """``(samples, m)`` heading of each robot at each sample [rad] (the last one now), or ``None``."""
        if not self.has_headings:
            return None
        kept = self._headings[: samples - 1] + [self.angles()]
        if len(kept) != samples:
            raise RuntimeError(f"drive kept {len(kept)} headings for {samples} samples")
        return np.array(kept).reshape(samples, self.m)

    def command(self, u: np.ndarray) -> np.ndarray:  # pragma: no cover - overridden
        raise NotImplementedError


class VelocityDrive(Drive):
    """First-order velocity tracking: ``v' = (v_cmd - v) / time_constant``, ``|v_cmd| <= max_speed``."""

    def command(self, u: np.ndarray) -> np.ndarray:
        return saturate(u, float(self.d.max_speed))

    def actuate(self, run, t: float) -> None:
        self.take(run, t)
        h = run.h
        gain = float(self.params.mass) * -math.expm1(-h / float(self.d.time_constant)) / h
        vel = run.fresh_state()[:, 2:]
        f = saturate(gain * (self.cmd - vel), float(self.params.force_limit)) * run.working[:, None]
        forces = run.world.forces
        if run.resist:
            np.add(f, run.resistance(vel, f), out=forces)
        else:
            forces[:] = f


class DifferentialDrive(Drive):
    """Two wheels, no lateral slip, wheel speed and acceleration limits; tracked by look-ahead linearisation.

    ``lateral`` (default on) cancels the sideways velocity at every physics
    step; tests turn it off to see that it matters.  ``wheels`` holds the
    ``(m, 2)`` ``[v_l, v_r]`` set at the last physics step.
    """

    has_headings = True

    def __init__(self, world, params, plan, lateral: bool = True):
        super().__init__(world, params, plan)
        self.lateral = lateral
        for body, th in zip(world.bodies, initial_headings(plan)):
            body.angle = float(th)
        self._get = _batch.Buffer()
        self._rows = self._read().shape[0]  # robots, then pymunk's static body
        self._out = np.zeros((self._rows, 3))
        self._set = _batch.Buffer()
        self._set.set_float_buf(self._out)
        self.wheels = np.zeros((self.m, 2))
        self._last: np.ndarray | None = None  # (m, 2) the headings the velocities were last set along

    def _read(self) -> np.ndarray:
        buf = self._get
        buf.clear()
        _batch.get_space_bodies(self.world.space, _SPIN, buf)
        return np.frombuffer(buf.float_buf(), dtype=np.float64).reshape(-1, 4)

    def angles(self) -> np.ndarray:
        """``(m,)`` the bodies' headings now [rad]."""
        return self._read()[: self.m, 0].copy()

    def command(self, u: np.ndarray) -> np.ndarray:
        d = self.d
        return unicycle_wheels(saturate(u, float(d.wheel_speed)), self.angles(), float(d.lookahead),
                               float(d.wheel_base), float(d.wheel_speed))

    def actuate(self, run, t: float) -> None:
        """Wheel speeds towards the command (rate and speed limited), then the body's velocity from them."""
        self.take(run, t)
        d = self.d
        rows = self._read()[: self.m]
        th, vel, omega = rows[:, 0], rows[:, 1:3], rows[:, 3]
        if self._calls % self._substeps == 0:  # a control step starts: the heading of its sample
            self._headings.append(th.copy())
        self._calls += 1
        c, s = np.cos(th), np.sin(th)
        # the wheels' speed now: the body's velocity along the heading it was last set on
        # (the body turned since, and the velocity turns with it: no slip)
        last = self._last if self._last is not None else np.stack([c, s], axis=1)
        forward = np.einsum("ij,ij->i", vel, last)
        half_b = 0.5 * float(d.wheel_base)
        now = np.stack([forward - omega * half_b, forward + omega * half_b], axis=1)
        step = float(d.wheel_accel) * run.h
        target = self.cmd * run.working[:, None]
        lim = float(d.wheel_speed)
        wheels = np.clip(now + np.clip(target - now, -step, step), -lim, lim)
        self.wheels = wheels
        v = 0.5 * (wheels[:, 0] + wheels[:, 1])
        out = self._out
        if self.lateral:
            out[: self.m, 0] = v * c
            out[: self.m, 1] = v * s
        else:  # the sideways velocity kept: the wheels slip
            lateral = c * vel[:, 1] - s * vel[:, 0]
            out[: self.m, 0] = v * c - lateral * s
            out[: self.m, 1] = v * s + lateral * c
        out[: self.m, 2] = (wheels[:, 1] - wheels[:, 0]) / float(d.wheel_base)
        self._last = np.stack([c, s], axis=1)
        _batch.set_space_bodies(self.world.space, _SET, self._set)
        run.valid = False
