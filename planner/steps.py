"""Steps of a waypoint plan and their exact clearance checks.

A step moves every robot straight from one waypoint row to the next under
one shared time parameter; :func:`steps_clear` tests many such steps at once
against the obstacles (exact clearance) and every pair of robots (exact
closest approach).
"""

from __future__ import annotations

import time

import numpy as np

from .geometry import closest_approach
from .problem import Problem

__all__ = ["step_clear", "steps_clear", "steps_of"]


def steps_of(waypoints: np.ndarray) -> list[np.ndarray]:
    """The moving robots of each step (index arrays)."""
    w = np.asarray(waypoints)
    if len(w) < 2:
        return []
    step, robot = np.nonzero(np.any(w[1:] != w[:-1], axis=2))
    return np.split(robot, np.searchsorted(step, np.arange(1, len(w) - 1)))


def _late(deadline: float | None) -> bool:
    """Whether ``deadline`` (a ``time.perf_counter()`` value, or ``None``: never) has passed."""
    return deadline is not None and time.perf_counter() > deadline


_CHUNK = 250_000  # pairwise tests per closest-approach call


def step_clear(problem: Problem, a: np.ndarray, b: np.ndarray) -> bool:
    """Exact check of one step in which every robot goes straight ``a -> b``
    (:func:`steps_clear` of that one step)."""
    return bool(steps_clear(problem, np.asarray(a)[None], np.asarray(b)[None])[0])


def steps_clear(problem: Problem, a: np.ndarray, b: np.ndarray, deadline: float | None = None,
                via: np.ndarray | None = None) -> np.ndarray:
    """:func:`step_clear` of ``K`` steps at once: step ``k`` moves every robot ``a[k] -> b[k]``.

    ``a`` and ``b`` are ``(K, m, 2)``; the same exact tests, in one
    clearance call and chunked closest-approach calls.  Steps not tested
    by ``deadline`` count as not clear.  ``via`` (``(K, m, 2)``, optional):
    points whose moves ``a -> via`` and ``via -> b`` are clear of the
    obstacles (two steps being joined).  Where ``a``, ``via`` and ``b`` lie
    on one axis-parallel line (or ``via`` equals an end), exactly, with no
    rounding, the move ``a -> b`` lies in the union of those two, so its
    obstacle test is left out (the robots are still tested).
    """
    n_steps, m = a.shape[:2]
    kk, rr = np.nonzero(np.any(a != b, axis=2))  # every moving robot of every step
    bad = np.zeros(n_steps, bool)
    if len(kk) == 0:
        return ~bad
    sa, sb = a[kk, rr], b[kk, rr]
    test = np.ones(len(kk), bool)
    if via is not None:
        u, v = via[kk, rr] - sa, sb - via[kk, rr]
        still = (u == 0).all(axis=1) | (v == 0).all(axis=1)
        test = ~(still | ((u[:, 0] == 0) & (v[:, 0] == 0)) | ((u[:, 1] == 0) & (v[:, 1] == 0)))
    if test.any():
        bad[kk[test][~problem.env.segments_clear(sa[test], sb[test], problem.clearance)]] = True
    if m > 1:
        chunk = max(1, _CHUNK // m)
        for c0 in range(0, len(kk), chunk):
            if _late(deadline):
                bad[kk[c0:]] = True
                break
            sl = slice(c0, c0 + chunk)
            d = closest_approach(sa[sl, None], sb[sl, None], a[kk[sl]], b[kk[sl]])  # (rows, m)
            d[np.arange(len(d)), rr[sl]] = np.inf  # a robot and itself
            bad[kk[sl][(d < problem.separation).any(axis=1)]] = True
    return ~bad
