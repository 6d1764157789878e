"""The minimum-jerk time scaling of a plan's steps and the shortest step
duration under speed and acceleration limits (see :mod:`planner.plan`)."""

from __future__ import annotations

import math

import numpy as np

__all__ = ["PROFILE", "min_jerk", "min_jerk_s", "step_duration"]


PROFILE = "minimum_jerk"
_S1_MAX = 15.0 / 8.0  # max of s'(u), at u = 1/2
_S2_MAX = 10.0 / math.sqrt(3.0)  # max of |s''(u)|, at u = (3 -+ sqrt 3) / 6


def min_jerk_s(u):
    """``s(u) = 10 u^3 - 15 u^4 + 6 u^5`` for ``u`` in [0, 1], on floats or arrays alike."""
    u2 = u * u
    return u2 * u * (10.0 - 15.0 * u + 6.0 * u2)


def min_jerk(u):
    """``(s, s', s'')`` of the minimum-jerk scaling at ``u`` in [0, 1]."""
    u = np.clip(np.asarray(u, float), 0.0, 1.0)
    s = min_jerk_s(u)
    ds = 30.0 * (u * u) * (1.0 - u) ** 2
    dds = 60.0 * u * (1.0 - u) * (1.0 - 2.0 * u)
    return s, ds, dds


def step_duration(distance, max_speed: float, max_accel: float):
    """Shortest duration of a straight move of ``distance`` from rest to rest."""
    d = np.asarray(distance, float)
    t = np.maximum(_S1_MAX * d / max_speed, np.sqrt(_S2_MAX * d / max_accel))
    return t if t.ndim else float(t)
