"""A small text progress bar for long work, drawn only on a terminal."""

from __future__ import annotations

import sys
import time

__all__ = ["ProgressBar"]


class ProgressBar:
    """``bar(fraction, note)`` redraws one line on ``stream`` when it is a terminal.

    Redraws at most ten times a second; :meth:`close` ends the line.  On a
    pipe or file it draws nothing, so logs stay clean.
    """

    def __init__(self, label: str, stream=None, width: int = 30, enabled: bool | None = None):
        self.stream = stream if stream is not None else sys.stderr
        self.enabled = self.stream.isatty() if enabled is None else enabled
        self.label = label
        self.width = width
        self._last = 0.0
        self._drawn = False

    def __call__(self, fraction: float, note: str = "") -> None:
        if not self.enabled:
            return
        now = time.monotonic()
        if fraction < 1.0 and now - self._last < 0.1:
            return
        self._last = now
        f = min(max(fraction, 0.0), 1.0)
        full = int(round(f * self.width))
        bar = "#" * full + "-" * (self.width - full)
        self.stream.write(f"\r{self.label} [{bar}] {100 * f:5.1f}% {note}\x1b[K")
        self.stream.flush()
        self._drawn = True

    def close(self) -> None:
        if self.enabled and self._drawn:
            self.stream.write("\n")
            self.stream.flush()
            self._drawn = False
