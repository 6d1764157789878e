"""Time series of a physics run: the smallest gap and each robot's tracking error.

Two sources, one format: a plain dict of arrays::

    {"times": (S,) [s], "min_gap": (S,) [units], "tracking_error": (S, m) [units]}

* The physics run records them at every control step
  (:attr:`sim.SimReport.min_gap`, ``tracking_error``);
  :func:`series_arrays` takes them as ``float32`` and :func:`write_series`
  writes them beside the report as ``DIR/NAME-series.npz``, a compressed
  NumPy archive (read it with :func:`numpy.load`).  ``min_gap`` there is
  exact up to one robot diameter (larger gaps are stored as ``2 * radius``);
  ``tracking_error`` is NaN for a failed robot.  The archive is byte for
  byte the same for the same run: its entries carry a fixed date instead of
  the time of writing.
* :func:`run_series` computes them from any recording (sample times and
  positions) and the plan, on at most ``max_samples`` evenly spaced samples
  (the first and last always among them): ``min_gap[s]`` is the smallest gap
  at sample ``s`` between two disc boundaries or between a disc and an
  obstacle or a wall (negative: overlap; a centre inside a polygon counts as
  a gap of ``-radius``); ``tracking_error[s, i]`` the distance from robot
  ``i`` to where the plan puts it (its final waypoint after the plan's end,
  so settling is included).

:func:`thin` keeps at most ``max_samples`` evenly spaced samples of a series
for plotting.
"""

from __future__ import annotations

import io
import math
import zipfile
from pathlib import Path

import numpy as np

__all__ = ["SERIES_KEYS", "run_series", "series_arrays", "thin", "write_series"]

SERIES_KEYS = ("times", "min_gap", "tracking_error")
_DATE = (1980, 1, 1, 0, 0, 0)  # the earliest date a zip entry can hold


def series_arrays(report) -> dict[str, np.ndarray]:
    """The ``float32`` arrays of a :class:`sim.SimReport` under :data:`SERIES_KEYS`."""
    return {key: np.ascontiguousarray(getattr(report, key), dtype=np.float32) for key in SERIES_KEYS}


def write_series(path: str | Path, report) -> Path:
    """Write the run's series to ``path`` (an ``.npz`` archive; the caller makes it atomic)."""
    path = Path(path)
    with zipfile.ZipFile(path, "w", compression=zipfile.ZIP_DEFLATED, compresslevel=6) as zf:
        for key, arr in series_arrays(report).items():
            buf = io.BytesIO()
            np.lib.format.write_array(buf, arr, allow_pickle=False)
            info = zipfile.ZipInfo(f"{key}.npy", date_time=_DATE)
            info.compress_type = zipfile.ZIP_DEFLATED
            info.external_attr = 0o644 << 16
            zf.writestr(info, buf.getvalue(), compress_type=zipfile.ZIP_DEFLATED, compresslevel=6)
    return path


def _indices(n: int, max_samples: int) -> np.ndarray:
    if max_samples < 2:
        raise ValueError(f"max_samples must be >= 2, got {max_samples!r}")
    stride = max(1, math.ceil(n / max_samples))
    idx = np.arange(0, n, stride)
    if idx[-1] != n - 1:
        idx = np.append(idx, n - 1)
    return idx


def thin(series: dict, max_samples: int = 2000) -> dict:
    """``series`` with at most ``max_samples`` evenly spaced samples (first and last kept)."""
    idx = _indices(len(series["times"]), max_samples)
    return {key: np.asarray(series[key])[idx] for key in SERIES_KEYS}

_POINT_EDGE_BLOCK = 2_000_000  # point-edge distances computed at once (memory bound)


def run_series(problem, plan, times, positions, *, max_samples: int = 2000) -> dict:
    """The ``times``, ``min_gap`` and ``tracking_error`` series of a run (see the module docstring)."""
    t = np.asarray(times, float).reshape(-1)
    pos = np.asarray(positions, float)
    if pos.shape != (len(t), problem.m, 2) or len(t) == 0:
        raise ValueError(f"positions must be (T, m, 2) = ({len(t)}, {problem.m}, 2) with T >= 1, got {pos.shape}")
    idx = _indices(len(t), max_samples)
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
