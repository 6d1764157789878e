"""Robots that are not ideal: what the executor adds between the controller and the bodies.

Everything here is a plain function or a small record over arrays of all
robots at once; :func:`sim.execute` calls it at every physics step.

Units.  A workspace unit counts as one metre and a mass unit as one
kilogram wherever a force is named in newtons (N) or an impulse in newton
seconds (N s): 1 N accelerates a mass of 1 by 1 unit/s^2, and an impulse
``J`` changes a body's velocity by ``J / m``.  Friction uses ``g = 9.81``
units/s^2 (:data:`G`).

* **Real masses** (:func:`real_masses`): body ``i`` weighs
  ``(1 + u_i) * mass`` with ``u_i ~ U(-mass_error, mass_error)``; the
  controller keeps computing with ``mass``.
* **Measurement** (:class:`Sensor`): at each controller update the state is
  measured with Gaussian noise of the given standard deviation on every
  coordinate; the bodies are never moved by it.
* **Timing** (:class:`ControlClock`, :class:`DelayLine`): controller
  updates at ``control_rate`` with a zero-order hold between them, and a
  force computed from a measurement taken at ``t`` is applied from
  ``t + latency`` on.  Both happen at physics-step boundaries: an update
  or a force is due at the first physics step that starts at or after its
  time, so holds and delays are whole physics steps ``h = dt / substeps``
  (an update rate of 50 Hz with ``h = 1/240`` s holds for 4 or 5 steps,
  50 updates per second on average).
* **Resistance** (:func:`resistive_forces`): Coulomb friction against the
  floor and the brake of a failed robot, as a force that opposes the
  motion and never reverses it within a step.  Over one physics step the
  velocity a body would reach without resistance, ``v + F h / m``, is
  brought towards zero by at most ``R h / m`` (``R`` the largest resisting
  force): a sliding body decelerates at exactly ``R / m`` and a body that
  can stop within the step stops, with no chatter at rest.  A body at rest
  stays at rest while the other forces are smaller than ``R`` (static
  friction).
* **Impulses** (:class:`Events`): scheduled impulses, random pushes (a
  Poisson process per robot, drawn lazily one second of simulated time at a
  time so that a run's pushes do not depend on how long it lasts), and
  failures, each applied at the first physics step at or after its time.

Every random draw comes from the run's generator, split into one stream per
purpose by :func:`streams` (``Generator.spawn``): turning noise on does not
change the pushes, and the same seed gives the same run.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

import numpy as np

__all__ = [
    "G",
    "ControlClock",
    "DelayLine",
    "Disturbance",
    "Events",
    "Resistance",
    "Sensor",
    "phase_margin",
    "real_masses",
    "resistive_forces",
    "streams",
]

G = 9.81
"""Gravity for floor friction [units/s^2] (a workspace unit counts as a metre)."""

_EPS_T = 1e-9  # times closer than this [s] count as equal
_STREAMS = ("masses", "noise", "pushes", "replan", "sensing")  # new names go last: spawn keeps the others
_PUSH_WINDOW = 1.0  # seconds of pushes drawn at a time


def streams(rng: np.random.Generator) -> dict[str, np.random.Generator]:
    """Independent generators for the run's random purposes, derived from ``rng``.

    ``rng.spawn`` derives children from the generator's seed sequence, not
    from draws, so the streams are the same however much ``rng`` has been
    used (by the planner, say) and adding a purpose does not change others.
    """
    children = rng.spawn(len(_STREAMS))
    return dict(zip(_STREAMS, children))


def phase_margin(kp: float, kd: float, delay: float) -> float:
    """Phase margin [degrees] of the PD loop around a unit mass with a pure delay.

    The open loop is ``(kd s + kp) e^(-s delay) / s^2``; it crosses unity
    gain at ``w^2 = (kd^2 + sqrt(kd^4 + 4 kp^2)) / 2``, where its phase is
    ``-180 deg + atan(kd w / kp) - w delay``.  The closed loop is stable
    (without saturation) when the margin is positive; below about 30
    degrees it rings.  A zero-order hold of period ``T`` acts like a delay
    of ``T / 2``.  ``inf`` without feedback.
    """
    if kp <= 0 and kd <= 0:
        return math.inf
    w = math.sqrt((kd * kd + math.sqrt(kd**4 + 4.0 * kp * kp)) / 2.0)
    return math.degrees(math.atan2(kd * w, kp) - w * delay)


def real_masses(mass: float, mass_error: float, m: int, rng: np.random.Generator | None) -> np.ndarray:
    """``(m,)`` real body masses ``(1 + u) * mass``, ``u ~ U(-mass_error, mass_error)``."""
    if mass_error <= 0 or rng is None:
        return np.full(m, float(mass))
    return float(mass) * (1.0 + rng.uniform(-mass_error, mass_error, size=m))


class Sensor:
    """Measured states: ``[x, y, vx, vy]`` plus Gaussian noise per coordinate.

    position, velocity: standard deviations [units], [units/s].
    """

    def __init__(self, position: float, velocity: float, rng: np.random.Generator | None):
        self.scale = np.array([position, position, velocity, velocity], float)
        self.noisy = bool(self.scale.any())
        self.rng = rng

    def measure(self, state: np.ndarray) -> np.ndarray:
        """A new ``(m, 4)`` measured state; ``state`` is left as it is."""
        if not self.noisy:
            return state.copy()
        return state + self.rng.standard_normal(state.shape) * self.scale


class ControlClock:
    """When the controller updates.

    ``rate`` [Hz] or ``None`` (once per control step ``dt``).  Update ``j``
    is due at ``j / rate``; :meth:`due` says whether one falls due at a
    physics step starting at ``t`` and moves on past ``t``.
    """

    def __init__(self, rate: float | None, dt: float):
        self.period = 1.0 / rate if rate else float(dt)
        self._j = 0

    def due(self, t: float) -> bool:
        if self._j * self.period > t + _EPS_T:
            return False
        self._j = math.floor((t + _EPS_T) / self.period) + 1
        return True


class DelayLine:
    """Forces on their way from the controller to the actuators.

    :meth:`put` stores a force computed from a measurement at ``t``, due at
    ``t + latency``; :meth:`take` returns the newest force due by ``t`` (or
    ``None`` while none is due), dropping older ones.
    """

    def __init__(self, latency: float):
        self.latency = float(latency)
        self._line: deque = deque()

    def put(self, t: float, force: np.ndarray) -> None:
        self._line.append((t + self.latency, force))

    def take(self, t: float) -> np.ndarray | None:
        out = None
        line = self._line
        while line and line[0][0] <= t + _EPS_T:
            out = line.popleft()[1]
        return out


def resistive_forces(vel: np.ndarray, force: np.ndarray, masses: np.ndarray,
                     limit: np.ndarray, h: float) -> np.ndarray:
    """``(m, 2)`` forces of friction and brakes for one physics step of length ``h``.

    ``vel`` are the velocities at the start of the step, ``force`` the other
    forces held over it, ``limit`` ``(m,)`` the largest resisting force of
    each body [N].  The resisting impulse brings the velocity the body
    would reach without it, ``v + force h / m``, towards zero by at most
    ``limit * h`` (see the module docstring).
    """
    return Resistance(masses, h, limit)(vel, force)


class Resistance:
    """:func:`resistive_forces` with the per-body constants computed once.

    ``limit`` may be changed with :meth:`set_limit` (a robot fails).
    """

    def __init__(self, masses: np.ndarray, h: float, limit: np.ndarray):
        self.h = float(h)
        self._h_over_m = (self.h / np.asarray(masses, float))[:, None]
        self._minus_m_over_h = (-np.asarray(masses, float) / self.h)[:, None]
        self.set_limit(limit)

    def set_limit(self, limit: np.ndarray) -> None:
        self._cap = np.asarray(limit, float)  # the largest force, so the largest impulse over h

    def __call__(self, vel: np.ndarray, force: np.ndarray) -> np.ndarray:
        out = force * self._h_over_m
        out += vel  # the velocity without resistance
        out *= self._minus_m_over_h  # the force that stops the body within the step
        norm = np.sqrt(np.einsum("ij,ij->i", out, out))
        scale = np.minimum(self._cap / np.maximum(norm, 1e-300), 1.0)
        out *= scale[:, None]
        return out


@dataclass(frozen=True)
class Disturbance:
    """One disturbance as applied.

    kind: ``impulse`` (scheduled), ``push`` (random) or ``failure``.
    robot: robot index; time: when it was applied [s] (the first physics
    step at or after the scheduled time); impulse: ``(x, y)`` [N s], or
    ``None`` for a failure.
    """

    kind: str
    robot: int
    time: float
    impulse: tuple[float, float] | None = None

    def to_dict(self) -> dict:
        d = {"kind": self.kind, "robot": self.robot, "time": self.time}
        if self.impulse is not None:
            d["impulse"] = [self.impulse[0], self.impulse[1]]
        return d


class Events:
    """Scheduled impulses, random pushes and failures, in time order.

    :meth:`due` returns the events due at a physics step starting at ``t``
    (each as a :class:`Disturbance` stamped with ``t``).
    """

    def __init__(self, params, m: int, rng: np.random.Generator | None):
        items = [(float(d.time), 0, "impulse", int(d.robot), (float(d.impulse[0]), float(d.impulse[1])))
                 for d in params.disturbances]
        items += [(float(f.time), 1, "failure", int(f.robot), None) for f in params.failures]
        items.sort(key=lambda e: (e[0], e[1], e[3]))
        self._fixed = deque(items)
        self._m = m
        p = params.pushes
        self._rate = float(p.rate) * m if (p.rate > 0 and p.impulse > 0 and rng is not None) else 0.0
        self._push_size = float(p.impulse)
        self._rng = rng
        self._pushes: deque = deque()
        self._window = 0  # pushes are drawn up to _window * _PUSH_WINDOW
        self._next = self._fixed[0][0] if self._fixed else math.inf
        self._refill(0.0)

    def _refill(self, t: float) -> None:
        """Draw pushes for every whole window up to the one holding ``t``."""
        while self._rate and self._window * _PUSH_WINDOW <= t + _EPS_T:
            w0 = self._window * _PUSH_WINDOW
            rng = self._rng
            n = int(rng.poisson(self._rate * _PUSH_WINDOW))
            times = w0 + rng.random(n) * _PUSH_WINDOW
            robots = rng.integers(0, self._m, size=n)
            angles = rng.random(n) * (2.0 * math.pi)
            order = np.argsort(times, kind="stable")
            for k in order:
                j = self._push_size
                self._pushes.append((float(times[k]), int(robots[k]),
                                     (j * math.cos(angles[k]), j * math.sin(angles[k]))))
            self._window += 1

    def next_time(self) -> float:
        """The earliest time an event may fall due (a lower bound while pushes are on)."""
        nxt = self._fixed[0][0] if self._fixed else math.inf
        if self._rate:
            nxt = min(nxt, self._pushes[0][0] if self._pushes else self._window * _PUSH_WINDOW)
        return nxt

    def due(self, t: float) -> list[Disturbance]:
        out: list[Disturbance] = []
        if self.next_time() > t + _EPS_T:
            return out
        self._refill(t)
        fixed, pushes = self._fixed, self._pushes
        while fixed and fixed[0][0] <= t + _EPS_T:
            _, _, kind, robot, imp = fixed.popleft()
            out.append(Disturbance(kind, robot, t, imp))
        while pushes and pushes[0][0] <= t + _EPS_T:
            _, robot, imp = pushes.popleft()
            out.append(Disturbance("push", robot, t, imp))
        return out
