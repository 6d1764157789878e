"""Progress bars for long work (physics, video, sweeps): tqdm, drawn only on a terminal."""

from __future__ import annotations

import sys

__all__ = ["ProgressBar"]


class ProgressBar:
    """``bar(fraction, note)`` shows a tqdm bar on ``stream`` when it is a terminal.

    fraction: the share of the work done, in [0, 1]; note: a short text
    after the bar.  :meth:`close` ends the line.  On a pipe or a file it
    draws nothing (``enabled`` overrides the terminal test), so logs stay
    clean.  The bar is created at the first call.
    """

    def __init__(self, label: str, stream=None, width: int | None = None, enabled: bool | None = None):
        self.stream = stream if stream is not None else sys.stderr
        self.enabled = _is_terminal(self.stream) if enabled is None else bool(enabled)
        self.label = label
        self.width = width
        self._bar = None

    def __call__(self, fraction: float, note: str = "") -> None:
        if not self.enabled:
            return
        if self._bar is None:
            from tqdm import tqdm

            self._bar = tqdm(
                total=1.0,
                desc=self.label,
                file=self.stream,
                ncols=None if self.width is None else self.width + len(self.label) + 40,
                bar_format="{desc} |{bar}| {percentage:5.1f}% {elapsed}<{remaining} {postfix}",
                mininterval=0.1,
                leave=True,
            )
        f = min(max(float(fraction), 0.0), 1.0)
        if note:
            self._bar.set_postfix_str(note, refresh=False)
        self._bar.update(f - self._bar.n)

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()
            self._bar = None


def _is_terminal(stream) -> bool:
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError):
        return False
