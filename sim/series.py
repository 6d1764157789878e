"""The time series of a physics run, beside its report: ``DIR/NAME-series.npz``.

A NumPy ``.npz`` archive (read it with :func:`numpy.load`) of three
``float32`` arrays, compressed:

* ``times`` ``(T,)``: the sample times [s], one per control step;
* ``min_gap`` ``(T,)``: the smallest gap of each sample over all robot
  pairs, obstacles and walls [units], exact up to one robot diameter
  (larger gaps are stored as ``2 * radius``);
* ``tracking_error`` ``(T, m)``: each robot's distance from its reference
  [units], NaN for a failed robot.

The archive is written byte for byte the same for the same run: its entries
carry a fixed date instead of the time of writing.
"""

from __future__ import annotations

import io
import zipfile
from pathlib import Path

import numpy as np

__all__ = ["SERIES_KEYS", "series_arrays", "write_series"]

SERIES_KEYS = ("times", "min_gap", "tracking_error")
_DATE = (1980, 1, 1, 0, 0, 0)  # the earliest date a zip entry can hold


def series_arrays(report) -> dict[str, np.ndarray]:
    """The ``float32`` arrays of a :class:`sim.execute.SimReport` under :data:`SERIES_KEYS`."""
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
