"""Local worker processes, one run at a time each, with a watchdog per run.

The sweep's process hands each worker one run through a pipe and waits for
its row.  When a run's watchdog fires, its worker is killed (``SIGKILL``,
which also ends a stopped process) and replaced, and the run is recorded as
a ``Timeout`` row; when a worker dies mid-run (killed, out of memory, a
crash in native code), the run is recorded as a ``WorkerDied`` row and the
worker replaced.  Workers ignore Ctrl-C (the sweep stops them) and end by
themselves when the sweep's process is gone, so a killed sweep leaves no
worker waiting forever.
"""

from __future__ import annotations

import multiprocessing
import os
import signal
import threading
import time
from collections import deque
from collections.abc import Callable
from multiprocessing.connection import wait

from . import spec as _spec
from .limits import TIMEOUT, WORKER_DIED
from .spec import RunSpec, failure_row

__all__ = ["run_pool"]

_ORPHAN_POLL_S = 0.25  # how often a worker checks that the sweep's process still lives
_STOP_WAIT_S = 2.0  # how long a worker told to stop may take before it is killed


class _Worker:
    """One worker process and the run it is computing (``spec`` is ``None`` when idle)."""

    def __init__(self, ctx):
        parent, child = ctx.Pipe(duplex=True)
        self.process = ctx.Process(target=_worker_main, args=(child, os.getpid()), daemon=True,
                                   name="swarmform-tune-worker")
        self.process.start()
        child.close()
        self.conn = parent
        self.spec: RunSpec | None = None
        self.started = 0.0
        self.deadline = 0.0

    @property
    def name(self) -> str:
        return f"local:{self.process.pid}"

    def give(self, spec: RunSpec, limit_s: float) -> bool:
        """Send ``spec``; False when the worker is gone (it takes no run then)."""
        try:
            self.conn.send(spec)
        except OSError:
            return False
        self.spec, self.started = spec, time.monotonic()
        self.deadline = self.started + limit_s
        return True

    def kill(self) -> None:
        if self.process.is_alive():
            self.process.kill()
        self.process.join(_STOP_WAIT_S)
        self.conn.close()

    def stop(self) -> None:
        """End an idle worker politely, a busy one at once."""
        if self.spec is None and self.process.is_alive():
            try:
                self.conn.send(None)
            except OSError:
                pass
            self.process.join(_STOP_WAIT_S)
        self.kill()


def run_pool(todo: list[RunSpec], workers: int, state, limit: Callable[[RunSpec], float]) -> None:
    """Compute ``todo`` on ``workers`` processes; every run ends as a row in ``state``."""
    ctx = multiprocessing.get_context("fork" if "fork" in multiprocessing.get_all_start_methods() else "spawn")
    pending = deque(todo)
    pool = [_Worker(ctx) for _ in range(min(workers, len(todo)))]
    try:
        while pending or any(w.spec is not None for w in pool):
            for w in pool:
                if w.spec is None and pending:
                    spec = pending.popleft()
                    if not w.give(spec, limit(spec)):
                        pending.appendleft(spec)  # it died idle; _check replaces it
            busy = [w for w in pool if w.spec is not None]
            timeout = max(0.0, min(w.deadline for w in busy) - time.monotonic()) if busy else None
            ready = set(wait([w.conn for w in busy] + [w.process.sentinel for w in pool], timeout))
            pool = [_check(w, ready, state, limit, ctx, bool(pending)) for w in pool]
            pool = [w for w in pool if w is not None]
    finally:
        for w in pool:
            w.stop()


def _check(w: _Worker, ready: set, state, limit, ctx, needed: bool) -> _Worker | None:
    """Take ``w``'s row if it has one; replace it when it died or its run's watchdog fired.

    A worker that is gone is replaced only when runs are still waiting (``needed``).
    """
    now = time.monotonic()
    if w.spec is not None and (w.conn in ready or w.conn.poll()):
        try:
            row = w.conn.recv()
        except (EOFError, OSError):
            row = None
        if row is not None:
            row["worker"] = w.name
            w.spec = None
            state.record(row)
            return w
    dead = w.process.sentinel in ready or not w.process.is_alive()
    if w.spec is not None and not dead and now < w.deadline:
        return w
    if w.spec is None and not dead:
        return w
    spec, elapsed = w.spec, now - w.started
    w.kill()
    if spec is not None:
        if dead:
            code = w.process.exitcode
            how = (f"killed by {signal.Signals(-code).name}" if code is not None and code < 0
                   and -code in signal.valid_signals() else f"exit status {code}")
            state.record(failure_row(spec, WORKER_DIED, f"the worker process died while running it ({how})",
                                     wall_time_s=elapsed, worker=w.name))
        else:
            state.record(failure_row(
                spec, TIMEOUT, f"no result within its watchdog of {limit(spec):.1f} s (1.1 x the "
                f"{spec.time_limit:g} s time limit plus the allowance); the worker process was killed",
                wall_time_s=elapsed, worker=w.name))
    if not needed:
        return None
    state.replaced += 1
    return _Worker(ctx)


def _worker_main(conn, sweep_pid: int) -> None:
    """Compute the runs the sweep sends, one at a time, until it sends ``None`` or goes away."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    threading.Thread(target=_exit_with, args=(sweep_pid,), daemon=True, name="exit-with-sweep").start()
    while True:
        try:
            spec = conn.recv()
        except (EOFError, OSError):
            return
        if spec is None:
            return
        conn.send(_spec.run_one(spec))


def _exit_with(sweep_pid: int) -> None:
    while os.getppid() == sweep_pid:
        time.sleep(_ORPHAN_POLL_S)
    os._exit(1)
