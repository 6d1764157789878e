"""PD control with feed-forward, for all robots at once.

The commanded acceleration of robot ``i`` over one control step is::

    a = kp * (x_ref - x) + kd * (v_ref - v) + a_ff

limited in magnitude to ``force_limit``; the force is ``mass * a``.  It is
computed once per control step ``dt`` and held for ``substeps`` physics
steps of ``dt / substeps``.

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

import numpy as np

__all__ = ["ReferenceChunk", "pd_acceleration", "reference_chunk"]


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
