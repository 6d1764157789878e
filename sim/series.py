"""Time series of a physics run, for plots: the smallest gap and each robot's tracking error.

:func:`run_series` computes them from the recording (sample times and
positions) and the plan, on at most ``max_samples`` evenly spaced samples
(the first and last always among them).  It returns the plain dict the run
page plots::

    {"times": (S,) [s], "min_gap": (S,) [units], "tracking_error": (S, m) [units]}

``min_gap[s]`` is the smallest gap at sample ``s`` between two disc
boundaries or between a disc and an obstacle or a wall (negative: overlap;
a centre inside a polygon counts as a gap of ``-radius``).
``tracking_error[s, i]`` is the distance from robot ``i`` to where the plan
puts it at that time (its final waypoint after the plan's end, so settling
is included).
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["run_series"]

_POINT_EDGE_BLOCK = 2_000_000  # point-edge distances computed at once (memory bound)


def run_series(problem, plan, times, positions, *, max_samples: int = 2000) -> dict:
    """The ``times``, ``min_gap`` and ``tracking_error`` series of a run (see the module docstring)."""
    t = np.asarray(times, float).reshape(-1)
    pos = np.asarray(positions, float)
    if pos.shape != (len(t), problem.m, 2) or len(t) == 0:
        raise ValueError(f"positions must be (T, m, 2) = ({len(t)}, {problem.m}, 2) with T >= 1, got {pos.shape}")
    if max_samples < 2:
        raise ValueError(f"max_samples must be >= 2, got {max_samples!r}")
    stride = max(1, math.ceil(len(t) / max_samples))
    idx = np.arange(0, len(t), stride)
    if idx[-1] != len(t) - 1:
        idx = np.append(idx, len(t) - 1)
    ts, ps = t[idx], pos[idx]
    ref = plan.sample(ts)[0]
    err = np.sqrt(np.einsum("smk,smk->sm", ps - ref, ps - ref))
    return {"times": ts, "min_gap": _min_gaps(problem, ps), "tracking_error": err}


def _min_gaps(problem, ps: np.ndarray) -> np.ndarray:
    """The smallest gap of every sample ``ps`` ``(S, m, 2)``."""
    from scipy.spatial import cKDTree

    s_count, m = ps.shape[:2]
    r = float(problem.radius)
    out = np.full(s_count, np.inf)
    if m >= 2:
        for s in range(s_count):
            d, _ = cKDTree(ps[s]).query(ps[s], k=2)
            out[s] = float(d[:, 1].min()) - 2.0 * r
    env = problem.env
    edges = max(1, sum(len(p) for p in env.polygons))
    per = max(1, _POINT_EDGE_BLOCK // (edges * m))
    for s0 in range(0, s_count, per):
        block = ps[s0 : s0 + per]
        clear = env.point_clearance(block.reshape(-1, 2)).reshape(len(block), m)
        out[s0 : s0 + per] = np.minimum(out[s0 : s0 + per], clear.min(axis=1) - r)
    return out
