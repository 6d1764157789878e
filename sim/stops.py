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
A signal that lands while a module is being imported is raised as soon as
the import is over (checked every 50 ms by SIGALRM).
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


_RETRY_S = 0.05
_pending: list[int] = []


def _importing(frame) -> bool:
    """Whether ``frame`` runs inside an import (where an exception would break a module's init)."""
    while frame is not None:
        if frame.f_code.co_filename.startswith("<frozen importlib"):
            return True
        frame = frame.f_back
    return False


def _raise(signum, frame) -> None:
    # An exception raised while a C extension initialises becomes "ImportError:
    # initialization failed" and can leave the interpreter unable to finish; so a
    # signal that lands in an import is raised once the import is over (SIGALRM polls).
    if _importing(frame):
        _pending.append(signum)
        signal.setitimer(signal.ITIMER_REAL, _RETRY_S)
        return
    _pending.clear()
    raise Stopped(signum)


def _retry(_signum, frame) -> None:
    if _pending:
        _raise(_pending.pop(), frame)


@contextmanager
def stop_handlers() -> Iterator[None]:
    """Make :data:`STOP_SIGNALS` raise :class:`Stopped` in the block (main thread only)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    old = {}
    for sig in STOP_SIGNALS:
        old[sig] = signal.signal(sig, _raise)
    old[signal.SIGALRM] = signal.signal(signal.SIGALRM, _retry)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        _pending.clear()
        for sig, handler in old.items():
            signal.signal(sig, handler if handler is not None else signal.SIG_DFL)
