"""How long a sweep's run may take beyond its planning deadline (the watchdog's allowances),
and the error types of a run the watchdog or a dead worker ended.

Kept apart from the driver so that the command line's help text can name
them without importing the sweep's machinery.
"""

from __future__ import annotations

__all__ = ["BUILD_ALLOWANCE_S", "PHYSICS_ALLOWANCE_S", "TIMEOUT", "WORKER_DIED"]

BUILD_ALLOWANCE_S = 30.0
"""Seconds a run may take beyond its planning deadline to build the problem and write its row."""

PHYSICS_ALLOWANCE_S = 270.0
"""Further seconds a run with ``--simulate`` may take for its physics run."""

TIMEOUT = "Timeout"
"""A results row's error type when the watchdog ended the run."""

WORKER_DIED = "WorkerDied"
"""A results row's error type when the run's worker process or Dask worker died."""
