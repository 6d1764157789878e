"""Straightened detours: one robot's moves over a window of steps replaced by
one straight line travelled across those steps, when that is clear and faster.
"""

from __future__ import annotations

import numpy as np

from .geometry import closest_approach
from .problem import Problem
from .steps import _late

__all__ = ["shortcut"]


def _durations(problem: Problem, lengths: np.ndarray) -> np.ndarray:
    from .plan import step_duration

    return np.where(lengths > 0, step_duration(lengths, problem.max_speed, problem.max_accel), 0.0)


def _shortcut_tables(problem: Problem, w: np.ndarray, r: int):
    """Per step of ``w``: robot ``r``'s move length, the longest move of the others,
    and the step's duration (what :func:`_try_shortcut` reads for every window)."""
    length = np.linalg.norm(w[1:] - w[:-1], axis=2)  # (L, m)
    own = length[:, r].copy()
    others = np.delete(length, r, axis=1).max(axis=1, initial=0.0)  # (L,)
    return own, others, _durations(problem, np.maximum(others, own))


def _try_shortcut(problem: Problem, w: np.ndarray, r: int, j1: int, j2: int, tables=None) -> bool:
    """Straighten robot ``r`` between waypoints ``j1`` and ``j2`` if clear and faster.

    The straight displacement is shared among the steps in proportion to
    the longest move of the *other* robots in each, so no step gets longer
    when it fits; steps where only ``r`` moved lose that move.  Checked
    exactly: obstacles, and the closest approach to every other robot in
    every step of the window.  Edits ``w`` in place when accepted.
    ``tables`` are :func:`_shortcut_tables` of ``w`` and ``r`` (computed
    when not given).
    """
    if j2 - j1 < 1:
        return False
    own_all, others_all, dur_all = tables if tables is not None else _shortcut_tables(problem, w, r)
    own = own_all[j1:j2]
    own_sum = own.sum()
    if own_sum <= 1e-12:
        return False
    d = w[j2, r] - w[j1, r]
    dist = float(np.linalg.norm(d))
    if dist >= own_sum - 1e-9:
        return False  # already straight
    others = others_all[j1:j2]
    old_cost = dur_all[j1:j2].sum()
    cap = others.sum()
    if cap > 1e-12:
        frac = others / cap
    else:
        frac = np.zeros(len(others))
        frac[0] = 1.0
    new_own = dist * frac
    new_cost = _durations(problem, np.maximum(others, new_own)).sum()
    if new_cost > old_cost - 1e-9:
        return False
    cum = np.concatenate([[0.0], np.cumsum(frac)])
    ys = w[j1, r] + cum[:, None] * d  # (L + 1, 2)
    ys[-1] = w[j2, r]  # exactly where the window ends
    a, b = ys[:-1], ys[1:]
    if not problem.env.segments_clear(a, b, problem.clearance).all():
        return False
    oa = np.delete(w[j1:j2], r, axis=1)  # (L, m - 1, 2)
    ob = np.delete(w[j1 + 1 : j2 + 1], r, axis=1)
    if oa.shape[1]:
        dmin = closest_approach(a[:, None], b[:, None], oa, ob)
        if dmin.min() < problem.separation:
            return False
    w[j1 : j2 + 1, r] = ys
    return True


def shortcut(problem: Problem, waypoints: np.ndarray, passes: int = 3, deadline: float | None = None) -> np.ndarray:
    """Straighten detours robot by robot (see :func:`_try_shortcut`).

    For each robot the whole plan is tried first, then its halves, quarters
    and so on down to windows of two steps; a few passes run until nothing
    improves or ``deadline`` passes (every accepted change is checked, so
    the plan is valid whenever it stops).  Steps in which nobody moves any
    more are dropped.
    """
    w = np.array(waypoints, float)
    if len(w) <= 2:
        return w
    for _ in range(passes):
        improved = False
        for r in range(w.shape[1]):
            if _late(deadline):
                break
            tables = None  # of the current w, for robot r
            stack = [(0, len(w) - 1)]
            while stack:
                j1, j2 = stack.pop()
                if j2 - j1 < 2:
                    continue
                if tables is None:
                    tables = _shortcut_tables(problem, w, r)
                if _try_shortcut(problem, w, r, j1, j2, tables):
                    improved = True
                    tables = None
                    continue
                mid = (j1 + j2) // 2
                stack.append((mid, j2))
                stack.append((j1, mid))
        if not improved or _late(deadline):
            break
    keep = [0] + [k + 1 for k in range(len(w) - 1) if np.any(w[k + 1] != w[k])]
    return w[keep]
