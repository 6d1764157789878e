"""Signals that stop a run: each one ends it the way Ctrl-C does.

``timeout``, CI runners and service managers stop a process with SIGTERM,
a closed terminal sends SIGHUP and Ctrl-\\ sends SIGQUIT.  While
:func:`stop_handlers` is active each of them raises :class:`Stopped`, a
:class:`KeyboardInterrupt`, in the main thread, so every ``with`` block
unwinds as for SIGINT: the staging folder of a run's outputs is removed,
the previous outputs stay as they were, a results file keeps whole rows.
The command then says one line and exits ``128 + signal number`` (SIGHUP
129, SIGQUIT 131, SIGTERM 143; SIGINT stays 130), the codes a shell
reports for a process killed by that signal.  A Python-level handler also
keeps pygame's fatal-signal "parachute" from printing a dump for SIGQUIT.
"""

from __future__ import annotations

import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager

__all__ = ["STOP_SIGNALS", "Stopped", "stop_handlers"]

#: The signals, besides SIGINT, that stop a command cleanly.
STOP_SIGNALS: tuple[signal.Signals, ...] = tuple(
    getattr(signal, name) for name in ("SIGTERM", "SIGHUP", "SIGQUIT") if hasattr(signal, name)
)


class Stopped(KeyboardInterrupt):
    """The command was stopped by ``signum`` (SIGTERM, SIGHUP or SIGQUIT)."""

    def __init__(self, signum: int):
        self.signum = int(signum)
        super().__init__(signal.Signals(signum).name)

    @property
    def exit_code(self) -> int:
        return 128 + self.signum


def _raise(signum, _frame) -> None:
    raise Stopped(signum)


@contextmanager
def stop_handlers() -> Iterator[None]:
    """Make :data:`STOP_SIGNALS` raise :class:`Stopped` in the block (main thread only)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    old = {}
    for sig in STOP_SIGNALS:
        old[sig] = signal.signal(sig, _raise)
    try:
        yield
    finally:
        for sig, handler in old.items():
            signal.signal(sig, handler if handler is not None else signal.SIG_DFL)
