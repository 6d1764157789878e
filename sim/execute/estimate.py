"""Estimated state: what the controller and recovery's trigger see when robots are measured, not known.

A sensor (:class:`PositionSensor`) measures every robot's position at its
own rate, at physics-step boundaries: the true position, plus a bias that
drifts as a random walk (``bias_drift`` units per square-root second, per
axis, unknown to the filter), plus white Gaussian noise of standard
deviation ``noise.position``.  Each robot's measurement is lost with
probability ``dropout`` and reaches the filter ``U(0, latency_jitter)``
seconds after it was taken.  Velocity is never measured.

The filter (:class:`Estimator`) is the constant-velocity Kalman filter of
Bar-Shalom, Li and Kirubarajan, "Estimation with Applications to Tracking and
Navigation" (Wiley, 2001), sections 5.2 and 6.2 (the continuous white noise
acceleration model), run per robot and per axis, with the robot's own
commanded acceleration ``u`` (its held actuator command over its model mass)
as the known input:

* predict over ``T``: ``p += v T + u T^2 / 2``, ``v += u T``,
  ``P = F P F' + q [[T^3/3, T^2/2], [T^2/2, T]]``, ``F = [[1, T], [0, 1]]``;
  ``q`` is ``sim.sensing.process_noise`` [units^2/s^3], the spectral density
  of what the model leaves out (pushes, friction, mass error, brakes);
* update with a position ``z`` taken ``d`` seconds before the filter's time:
  under the model ``z = p - v d + u d^2 / 2 + w``, so ``H = [1, -d]`` and
  ``R = sigma^2 + q d^3 / 3`` (the process noise over ``d``, a standard
  approximation for a delayed measurement); ``S = H P H' + R``,
  ``K = P H' / S``, ``x += K (z - H x)``, ``P -= K S K'``.

A measurement taken before the last one used for the same robot (jitter can
reorder them) is discarded: the simplest rule for out-of-sequence
measurements (retrodicting them is the better, costlier one).  Between measurements, or when one is
lost, the filter keeps predicting.  ``estimator: alpha_beta`` replaces the
gain by the steady-state gains of the alpha-beta filter (Kalata's tracking
index ``lambda = sqrt(q / T) T^2 / sigma``, Bar-Shalom et al. section 6.5),
with the same prediction.  The covariance is the same on both axes (they see
the same measurement times), so ``P`` is kept once per robot as
``(pp, pv, vv)``.

Every draw comes from the run's streams (:func:`sim.execute.realism.streams`):
the noise from ``noise``, the bias, dropouts and jitter from three children
of ``sensing`` (turning one on changes no other draw).
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np

from .realism import ControlClock

__all__ = ["DEFAULT_FAILURE_DELAY", "Estimator", "PositionSensor", "alpha_beta_gains", "failure_delay", "make_estimator"]

DEFAULT_FAILURE_DELAY = 0.5
"""Seconds from a failure until recovery is told, when a filter estimates the state [s]."""

_EPS_T = 1e-9
_MIN_SIGMA = 1e-4  # [units] the filter's noise floor when the measurement noise is 0


def alpha_beta_gains(q: float, period: float, sigma: float) -> tuple[float, float]:
    """Steady-state ``(alpha, beta)`` of the alpha-beta filter (Kalata's tracking index)."""
    lam = math.sqrt(q / period) * period * period / max(sigma, _MIN_SIGMA)
    r = (4.0 + lam - math.sqrt(8.0 * lam + lam * lam)) / 4.0
    alpha = 1.0 - r * r
    beta = 2.0 * (2.0 - alpha) - 4.0 * math.sqrt(1.0 - alpha)
    return alpha, beta


class PositionSensor:
    """Position measurements of all robots, waiting to reach the filter.

    :meth:`sample` takes one at ``t``; :meth:`arrived` hands the filter,
    oldest first, ``(t_taken, z (m, 2), mask (m,))`` for each robot whose
    measurement has arrived by ``t`` and not been handed before.
    """

    def __init__(self, m: int, sigma: float, dropout: float, jitter: float, bias_drift: float,
                 noise_rng: np.random.Generator | None, sensing_rng: np.random.Generator | None):
        self.m, self.sigma = m, float(sigma)
        self.dropout, self.jitter, self.drift = float(dropout), float(jitter), float(bias_drift)
        self._noise = noise_rng
        self._bias_rng, self._drop_rng, self._jitter_rng = (
            sensing_rng.spawn(3) if sensing_rng is not None else (None, None, None))
        self.bias = np.zeros((m, 2))
        self._last = 0.0
        self._pending: deque = deque()  # [t_taken, z, arrival (m,), left (m,)]

    def sample(self, t: float, pos: np.ndarray) -> None:
        m = self.m
        if self.drift > 0:
            self.bias += self._bias_rng.standard_normal((m, 2)) * (self.drift * math.sqrt(max(t - self._last, 0.0)))
        self._last = t
        z = pos + self.bias if self.drift > 0 else pos.copy()
        if self.sigma > 0:
            z += self._noise.standard_normal((m, 2)) * self.sigma
        left = self._drop_rng.random(m) >= self.dropout if self.dropout > 0 else np.ones(m, bool)
        arrival = t + self._jitter_rng.random(m) * self.jitter if self.jitter > 0 else np.full(m, t)
        if left.any():
            self._pending.append([t, z, arrival, left])

    def arrived(self, t: float):
        out = []
        keep: deque = deque()
        for item in self._pending:
            ts, z, arrival, left = item
            now = left & (arrival <= t + _EPS_T)
            if now.any():
                out.append((ts, z, now))
                item[3] = left & ~now
            if item[3].any():
                keep.append(item)
        self._pending = keep
        out.sort(key=lambda e: e[0])
        return out


class Estimator:
    """Per-robot constant-velocity filter over a :class:`PositionSensor` (see the module docstring).

    ``clock`` says when the sensor samples; :meth:`command` tells the filter
    when each commanded acceleration reaches the actuators (its known input,
    piecewise constant); :meth:`update` moves the filter to a controller
    update at ``t`` and returns the estimated ``(m, 4)`` state ``[x, y, vx, vy]``.
    """

    def __init__(self, sensor: PositionSensor, clock: ControlClock, start: np.ndarray, q: float,
                 kind: str = "kalman"):
        self.sensor, self.clock, self.q, self.kind = sensor, clock, float(q), kind
        m = len(start)
        self.t = 0.0
        self.x = np.zeros((m, 4))
        self.x[:, :2] = start
        sig = max(sensor.sigma, _MIN_SIGMA)
        self.r = sig * sig
        self.pp = np.full(m, self.r)
        self.pv = np.zeros(m)
        self.vv = np.full(m, 1e-2)
        self.u = np.zeros((m, 2))
        self._commands: deque = deque()
        self.last_taken = np.full(m, -math.inf)
        self.gains = alpha_beta_gains(self.q, clock.period, sensor.sigma) if kind == "alpha_beta" else None

    def sample(self, t: float, pos: np.ndarray) -> None:
        """The sensor measures the true positions ``pos`` at ``t``."""
        self.sensor.sample(t, pos)

    def command(self, t: float, u: np.ndarray) -> None:
        """The commanded acceleration ``u`` (m, 2) [units/s^2] acts from ``t`` on (the filter's input)."""
        if t <= self.t + _EPS_T and not self._commands:
            self.u = np.array(u, float)
        else:
            self._commands.append((float(t), np.array(u, float)))

    def _predict(self, t: float) -> None:
        cmds = self._commands
        while cmds and cmds[0][0] <= t + _EPS_T:
            t_due, u = cmds.popleft()
            self._step(t_due)
            self.u = u
        self._step(t)

    def _step(self, t: float) -> None:
        d = t - self.t
        if d <= 0:
            return
        x, u, q = self.x, self.u, self.q
        x[:, :2] += x[:, 2:] * d + 0.5 * d * d * u
        x[:, 2:] += u * d
        self.pp += 2.0 * d * self.pv + d * d * self.vv + q * d ** 3 / 3.0
        self.pv += d * self.vv + q * d * d / 2.0
        self.vv += q * d
        self.t = t

    def _correct(self, taken: float, z: np.ndarray, mask: np.ndarray) -> None:
        mask = mask & (taken > self.last_taken)  # out of sequence: discarded
        if not mask.any():
            return
        self.last_taken[mask] = taken
        d = max(self.t - taken, 0.0)
        i = slice(None) if mask.all() else np.flatnonzero(mask)
        x = self.x[i]
        pred = x[:, :2] - x[:, 2:] * d + 0.5 * d * d * self.u[i]
        innov = z[i] - pred
        pp, pv, vv = self.pp[i], self.pv[i], self.vv[i]
        s = pp - 2.0 * d * pv + d * d * vv + self.r + self.q * d ** 3 / 3.0
        if self.gains is None:
            kp, kv = (pp - d * pv) / s, (pv - d * vv) / s
        else:
            kp = np.full(len(x), self.gains[0])
            kv = np.full(len(x), self.gains[1] / self.clock.period)
        self.x[i, :2] = x[:, :2] + kp[:, None] * innov
        self.x[i, 2:] = x[:, 2:] + kv[:, None] * innov
        self.pp[i] = pp - kp * kp * s
        self.pv[i] = pv - kp * kv * s
        self.vv[i] = vv - kv * kv * s

    def update(self, t: float) -> np.ndarray:
        """The estimate at ``t`` after every measurement that has arrived by then."""
        self._predict(t)
        for taken, z, mask in self.sensor.arrived(t):
            self._correct(taken, z, mask)
        return self.x.copy()

    def position_at(self, t: float) -> np.ndarray:
        """The estimated ``(m, 2)`` positions at ``t`` (predicted from the last update)."""
        d = max(t - self.t, 0.0)
        return self.x[:, :2] + self.x[:, 2:] * d + 0.5 * d * d * self.u


    def growing_error(self, t: float, ref_pos: np.ndarray, ref_vel: np.ndarray) -> np.ndarray:
        """``(m,)`` estimated distances from the reference at ``t``, 0 where the estimate is closing in.

        Recovery's trigger: an error the controller is already correcting
        (the estimated velocity relative to the reference points back at it)
        does not start a replan, whatever its size; one that grows does.
        """
        d = t - self.t
        x = self.x
        e = x[:, :2] + x[:, 2:] * max(d, 0.0) + 0.5 * max(d, 0.0) ** 2 * self.u - ref_pos
        closing = np.einsum("ik,ik->i", e, x[:, 2:] + self.u * max(d, 0.0) - ref_vel) < 0.0
        return np.where(closing, 0.0, np.sqrt(np.einsum("ik,ik->i", e, e)))


def make_estimator(params, start: np.ndarray, gens: dict, dt: float) -> Estimator | None:
    """The run's filter, or ``None`` when the controller measures the true state (``params.estimating``)."""
    if not params.estimating:
        return None
    from ..scenario.params import Sensing

    s = params.sensing if params.sensing is not None else Sensing()
    sensor = PositionSensor(len(start), float(params.noise.position), s.dropout, s.latency_jitter, s.bias_drift,
                            gens.get("noise"), gens.get("sensing"))
    clock = ControlClock(s.rate if s.rate else params.control_rate, dt)
    return Estimator(sensor, clock, np.asarray(start, float), s.process_noise, s.estimator)


def failure_delay(params) -> float:
    """Seconds from a failure until recovery is told (:class:`sim.scenario.params.Sensing`)."""
    s = params.sensing
    if s is not None and s.failure_delay is not None:
        return float(s.failure_delay)
    return DEFAULT_FAILURE_DELAY if params.estimating else 0.0
