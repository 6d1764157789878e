"""PD control with feed-forward, for all robots at once.

The commanded acceleration of robot ``i`` over one control step is::

    a = kp * (x_ref - x) + kd * (v_ref - v) + a_ff

limited in magnitude to ``force_limit / mass`` (the force limit is in
newtons, :class:`sim.scenario.params.SimParams`); the force is ``mass * a``, with the
model's mass.  For ideal robots it is computed once per control step ``dt``
and held for ``substeps`` physics steps of ``dt / substeps``; realistic
robots (:mod:`sim.execute.realism`) update at their control rate, from noisy,
delayed measurements.

Timing.  Chipmunk moves a body with the velocity it had at the start of a
step and only then adds ``F / m * h`` to the velocity, so over one control
step of ``n`` substeps ``h`` a held acceleration ``a`` gives::

    v(t + dt) = v + a dt
    x(t + dt) = x + v dt + a dt^2 (n - 1) / (2 n)

The velocity is exact when ``a`` is the mean reference acceleration over
``[t, t + dt]``, which the midpoint value ``a_ref(t + dt / 2)`` matches to
third order; so the feed-forward is taken there and the PD terms compare
the state at ``t`` with the reference at ``t``.  The small position deficit
above (a lag of about ``h / 2`` in time) is what the PD terms correct.
With the default gains this keeps the tracking error near ``4e-4`` units
at 2 units/s and 2 units/s^2 (the reference at ``t`` for both terms gives
about ``5e-4``; shifting the position reference by ``h / 2`` gives ``4e-3``).

After the plan's makespan :meth:`Plan.sample` holds the last waypoint with
zero velocity and acceleration, which is the settling reference.
"""

from __future__ import annotations

from bisect import bisect_right

import numpy as np

__all__ = ["PlanReference", "ReferenceChunk", "pd_acceleration", "reference_chunk"]


class ReferenceChunk:
    """Reference of consecutive control steps ``k0 .. k0 + count``.

    pos, vel: ``(count + 1, m, 2)`` reference at the sample times
        ``(k0 + j) * dt``, ``j = 0 .. count`` (the last one is the end of
        the chunk, where the tracking error of its last step is measured).
    acc_ff: ``(count, m, 2)`` feed-forward acceleration of each step, the
        reference acceleration at the middle of the step.
    """

    __slots__ = ("pos", "vel", "acc_ff")

    def __init__(self, pos: np.ndarray, vel: np.ndarray, acc_ff: np.ndarray):
        self.pos = pos
        self.vel = vel
        self.acc_ff = acc_ff


def reference_chunk(plan, k0: int, count: int, dt: float) -> ReferenceChunk:
    """Sample ``plan`` for the control steps ``k0 .. k0 + count - 1`` (one call, vectorised)."""
    ts = (k0 + np.arange(count + 1)) * dt
    pos, vel, _ = plan.sample(ts)
    _, _, acc = plan.sample(ts[:-1] + 0.5 * dt)
    return ReferenceChunk(pos, vel, acc)


def pd_acceleration(
    pos: np.ndarray,
    vel: np.ndarray,
    ref_pos: np.ndarray,
    ref_vel: np.ndarray,
    acc_ff: np.ndarray,
    kp: float,
    kd: float,
    limit: float,
) -> np.ndarray:
    """Commanded acceleration ``(m, 2)``, each row limited to norm ``limit``."""
    a = kp * (ref_pos - pos)
    a += kd * (ref_vel - vel)
    a += acc_ff
    norm2 = np.einsum("ij,ij->i", a, a)
    over = norm2 > limit * limit
    if over.any():
        a[over] *= (limit / np.sqrt(norm2[over]))[:, None]
    return a


class PlanReference:
    """The reference of all ``m`` robots from a plan that moves some of them.

    ``plan`` moves the robots ``rows`` (its robot ``j`` is robot
    ``rows[j]``) and starts at time ``t0`` [s]; the other robots hold
    ``hold`` (an ``(m, 2)`` array; only its other rows are used) at rest.
    :meth:`sample` takes absolute times and returns ``(T, m, 2)``
    positions, velocities and accelerations, like :meth:`planner.Plan.sample`.
    """

    def __init__(self, plan, t0: float = 0.0, rows: np.ndarray | None = None, hold: np.ndarray | None = None):
        self.plan = plan
        self.t0 = float(t0)
        self.rows = None if rows is None else np.asarray(rows, int)
        self.hold = None if hold is None else np.array(hold, float)
        self.end = self.t0 + plan.makespan
        self._times = plan.times.tolist()
        self._durations = plan.durations.tolist()
        self._delta = np.diff(plan.waypoints, axis=0)

    def at(self, t: float):
        """``(pos, vel, acc)`` ``(m, 2)`` each at the absolute time ``t``.

        The same numbers as :meth:`sample` at one time (the same floating
        point operations, on scalars), several times faster.
        """
        t = float(t)
        plan = self.plan
        if self.t0:
            t = t - self.t0
        steps = len(self._durations)
        if steps == 0:
            pos, vel, acc = plan.waypoints[0].copy(), np.zeros((plan.m, 2)), np.zeros((plan.m, 2))
        else:
            k = min(max(bisect_right(self._times, t) - 1, 0), steps - 1)
            dur = self._durations[k]
            u = (t - self._times[k]) / dur if dur > 0 else 1.0
            u = min(max(u, 0.0), 1.0)
            u2 = u * u
            s = u2 * u * (10.0 - 15.0 * u + 6.0 * u2)
            one = 1.0 - u
            ds = 30.0 * u2 * (one * one)
            dds = 60.0 * u * (1.0 - u) * (1.0 - 2.0 * u)
            inv = 1.0 / dur if dur > 0 else 0.0
            delta = self._delta[k]
            pos = plan.waypoints[k] + s * delta
            vel = (ds * inv) * delta
            acc = (dds * inv * inv) * delta
        if self.rows is None:
            return pos, vel, acc
        full = self.hold.copy()
        full[self.rows] = pos
        fv = np.zeros_like(full)
        fa = np.zeros_like(full)
        fv[self.rows] = vel
        fa[self.rows] = acc
        return full, fv, fa

    def sample(self, ts):
        ts = np.asarray(ts, float).reshape(-1)
        pos, vel, acc = self.plan.sample(ts - self.t0 if self.t0 else ts)
        if self.rows is None:
            return pos, vel, acc
        full = np.broadcast_to(self.hold, (len(ts),) + self.hold.shape).copy()
        full[:, self.rows] = pos
        fv = np.zeros_like(full)
        fa = np.zeros_like(full)
        fv[:, self.rows] = vel
        fa[:, self.rows] = acc
        return full, fv, fa
