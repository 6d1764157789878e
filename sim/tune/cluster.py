"""The same runs on an existing Dask distributed cluster, with a watchdog per run.

Runs are submitted a window at a time (the thread count of the cluster's
workers, or ``--workers`` if lower), so a run starts about when it is
submitted; its watchdog counts from then.  When it fires, the run is
recorded as a ``Timeout`` row naming the worker that held it, the future is
cancelled and no further run is sent to that worker (a stopped worker keeps
its slot on the scheduler until the scheduler drops it, 5 minutes by
default); runs that were waiting behind it are sent elsewhere.  When every
worker is banned, the runs left have no row (exit 1; a rerun computes them).  A run whose workers
keep dying is a ``WorkerDied`` row (Dask's ``KilledWorker``).  Each row
records the address of the Dask worker that computed it in ``worker``.

Failures of the cluster itself are one line each: a scheduler that cannot
be reached (nothing accepts a connection at the address) is a
:class:`~sim.tune.spec.TuneError` (exit 2, nothing run); a peer that accepts
the connection but does not complete Dask's handshake and first reply within
the connect deadline (silent, garbage, closed), and a scheduler lost or silent
mid-sweep, are a :class:`ClusterLostError` (exit 4; the rows written so far
stay, and the same command finishes the sweep).  Every wait on the network
has a deadline: connecting, the handshake and the first reply
(``_CONNECT_TIMEOUT_S`` plus ``_GRACE_S``), the cluster's workers
(``_WORKERS_TIMEOUT_S``), each request of the sweep (``_REPLY_TIMEOUT_S``) and
each run (its watchdog).  A Dask call that overruns its deadline is abandoned
in a daemon thread, so it cannot keep the process from exiting.  Dask's own
log records are silenced meanwhile, so they add no lines.
"""

from __future__ import annotations

import logging
import queue
import socket
import threading
import time
import uuid
from collections import deque
from collections.abc import Callable

from .limits import TIMEOUT, WORKER_DIED
from .spec import RunSpec, TuneError, failure_row, one_line, run_one

__all__ = ["ClusterLostError", "close", "connect", "run_cluster"]

_CONNECT_TIMEOUT_S = 10.0
_WORKERS_TIMEOUT_S = 10.0  # how long to wait for a cluster without workers to get one
_CLOSE_TIMEOUT_S = 5.0
_GRACE_S = 1.0  # beyond Dask's own connect timeout, before a hung connection attempt is abandoned
_REPLY_TIMEOUT_S = 10.0  # each request to the scheduler during the sweep
_PROBE_TIMEOUT_S = 2.0  # does anything accept a TCP connection at the address?
_LOGGERS = ("distributed", "tornado")


class ClusterLostError(RuntimeError):
    """The Dask scheduler went away mid-sweep (one line; the finished rows are in the file)."""


def connect(address: str):
    """A Dask distributed client of the scheduler at ``address``, with at least one worker.

    Raises :class:`TuneError` when nothing accepts a connection at ``address``
    or the cluster has no workers, :class:`ClusterLostError` when a peer
    accepts the connection but does not answer as a Dask scheduler in time.
    """
    try:
        from dask.distributed import Client
    except ImportError:
        raise TuneError("--scheduler: needs dask.distributed; install it with "
                        "pip install 'swarmform[cluster]'") from None
    with _quiet():
        deadline = _CONNECT_TIMEOUT_S + _GRACE_S
        try:
            client = _within(deadline, Client, address, timeout=_CONNECT_TIMEOUT_S)
        except Exception as exc:  # noqa: BLE001 - a timeout, or any failure of Dask's connection
            if not _accepts(address):
                raise TuneError(f"--scheduler: cannot connect to {address}: "
                                f"{type(exc).__name__}: {one_line(exc)}") from None
            if isinstance(exc, (_Overdue, TimeoutError)):  # ours, or Dask's own for the first reply
                why = f"no Dask handshake and reply within {_CONNECT_TIMEOUT_S:g} s"
            else:
                why = f"{type(exc).__name__}: {one_line(exc)}"[:90]
            raise ClusterLostError(f"--scheduler: {address} accepted the connection but did not answer "
                                   f"as a Dask scheduler ({why})") from None
        try:
            _within(_WORKERS_TIMEOUT_S + _GRACE_S, client.wait_for_workers, 1, timeout=_WORKERS_TIMEOUT_S)
        except _Overdue:
            _abandon(client)
            raise ClusterLostError(f"--scheduler: the Dask scheduler at {address} stopped answering "
                                   f"(no reply within {_WORKERS_TIMEOUT_S + _GRACE_S:g} s)") from None
        except Exception:  # noqa: BLE001 - a timeout, or the scheduler went away meanwhile
            close(client)
            raise TuneError(f"--scheduler: the cluster at {address} has no workers "
                            f"(waited {_WORKERS_TIMEOUT_S:g} s)") from None
    return client


class _Overdue(Exception):
    """A Dask call ran past its deadline; it goes on, abandoned, in a daemon thread."""


def _within(seconds: float, fn, *args, **kwargs):
    """``fn(*args, **kwargs)``, or :class:`_Overdue` after ``seconds``.

    The call runs in a daemon thread: one that hangs on a silent peer is
    abandoned there and does not keep the process from exiting.  Dask's
    loggers stay silenced for good then, so its death adds no lines.
    """
    box: dict = {}

    def call() -> None:
        try:
            box["value"] = fn(*args, **kwargs)
        except BaseException as exc:  # noqa: BLE001 - handed to the caller
            box["error"] = exc

    thread = threading.Thread(target=call, name="swarmform-dask-call", daemon=True)
    thread.start()
    thread.join(seconds)
    if thread.is_alive():
        _quiet().__enter__()  # never exited: the abandoned call may log as it dies
        raise _Overdue(f"no answer within {seconds:g} s")
    if "error" in box:
        raise box["error"]
    return box["value"]


def _accepts(address: str) -> bool:
    """Whether something accepts a TCP connection at ``address`` (true for addresses not over TCP)."""
    try:
        from distributed.comm.addressing import parse_address, parse_host_port

        scheme, location = parse_address(address)
        if scheme not in ("tcp", "tls"):
            return True
        host, port = parse_host_port(location)
    except Exception:  # noqa: BLE001 - not an address Dask can use: it cannot be reached
        return False
    try:
        with socket.create_connection((host, port), timeout=_PROBE_TIMEOUT_S):
            return True
    except OSError:
        return False


def _abandon(client) -> None:
    """Close ``client`` without waiting on a scheduler that stopped answering."""
    try:
        _within(_CLOSE_TIMEOUT_S, close, client)
    except _Overdue:
        pass


def _ask(client, method: str, *args):
    """``client.method(*args)``: a request to the scheduler, with a deadline (else the cluster is lost)."""
    try:
        return _within(_REPLY_TIMEOUT_S, getattr(client, method), *args)
    except _Overdue:
        raise ClusterLostError(f"the scheduler did not answer within {_REPLY_TIMEOUT_S:g} s") from None


def close(client) -> None:
    """Close the client without waiting long or logging, whatever state the cluster is in."""
    with _quiet():
        try:
            client.close(timeout=_CLOSE_TIMEOUT_S)
        except Exception:  # noqa: BLE001 - a lost scheduler: nothing left to close
            pass


def run_cluster(todo: list[RunSpec], client, window: int | None, state, limit: Callable[[RunSpec], float]) -> None:
    """Compute ``todo`` on the cluster; every run ends as a row in ``state`` (or in ``state.not_done``)."""
    from distributed import KilledWorker

    with _quiet():
        try:
            threads = dict(_ask(client, "nthreads"))
        except ClusterLostError:
            raise
        except Exception as exc:  # noqa: BLE001
            raise ClusterLostError(one_line(exc)) from None
        arrived: queue.Queue = queue.Queue()
        pending = deque(todo)
        running: dict = {}  # future -> (spec, submitted, deadline)
        banned: set[str] = set()
        while pending or running:
            room = sum(n for w, n in threads.items() if w not in banned)
            if not room and not running:
                reason = "every worker of the cluster stopped answering"
                state.not_done.extend((s, reason) for s in pending)
                break
            while pending and len(running) < min(window or room, room):
                spec = pending.popleft()
                fut = _submit(client, spec, banned)
                now = time.monotonic()
                running[fut] = (spec, now, now + limit(spec))
                fut.add_done_callback(arrived.put)
            wait_s = max(0.0, min(d for _, _, d in running.values()) - time.monotonic())
            try:
                fut = arrived.get(timeout=wait_s)
            except queue.Empty:
                _expire(client, running, pending, banned, state, limit)
                continue
            if fut not in running:
                continue  # cancelled by a watchdog
            spec, submitted, _ = running.pop(fut)
            try:
                row = fut.result()
            except KilledWorker as exc:
                state.record(failure_row(spec, WORKER_DIED, f"Dask workers died running it: {one_line(exc)}",
                                         wall_time_s=time.monotonic() - submitted))
                continue
            except Exception as exc:  # noqa: BLE001 - the cluster, not the run (run_one never raises)
                if _lost(client, exc):
                    for f in running:
                        f.cancel()
                    raise ClusterLostError(_lost_reason(exc)) from None
                state.not_done.append((spec, f"{type(exc).__name__}: {one_line(exc)}"))
                continue
            state.record(row)


def _submit(client, spec: RunSpec, banned: set[str]):
    """Submit one run, to the workers not banned (the caller makes sure some are left)."""
    if client.status != "running":
        raise ClusterLostError(f"the client is {client.status}")
    allowed = None
    if banned:
        try:
            allowed = [w for w in _ask(client, "nthreads") if w not in banned]
        except ClusterLostError:
            raise
        except Exception as exc:  # noqa: BLE001
            raise ClusterLostError(one_line(exc)) from None
    # pure=False and a fresh key: every run is computed, never taken from the cluster's cache
    return client.submit(_run_on_worker, spec, pure=False, key=f"swarmform-tune-{uuid.uuid4().hex}",
                         workers=allowed)


def _expire(client, running: dict, pending: deque, banned: set[str], state, limit) -> None:
    """Record the runs whose watchdog fired as ``Timeout`` rows and ban their workers.

    Other runs waiting on a banned worker have not started: they go back to
    ``pending`` (no row) and are submitted again to the other workers.
    """
    now = time.monotonic()
    late = [f for f, (_, _, deadline) in running.items() if deadline <= now]
    if not late:
        return
    try:
        where = {key: w for w, keys in _ask(client, "processing").items() for key in keys}
    except ClusterLostError:
        raise
    except Exception as exc:  # noqa: BLE001
        raise ClusterLostError(one_line(exc)) from None
    for fut in late:
        spec, submitted, _ = running.pop(fut)
        worker = where.get(fut.key)
        fut.cancel()
        if worker is not None:
            banned.add(worker)
        held = f" on Dask worker {worker}" if worker else ""
        state.record(failure_row(
            spec, TIMEOUT, f"no result within its watchdog of {limit(spec):.1f} s (1.1 x the {spec.time_limit:g} s "
            f"time limit plus the allowance){held}; the run hung or its worker stopped answering",
            wall_time_s=now - submitted, worker=worker))
    for fut in [f for f in running if where.get(f.key) in banned]:
        spec, _, _ = running.pop(fut)
        fut.cancel()
        pending.appendleft(spec)


def _lost(client, exc: BaseException) -> bool:
    return client.status != "running" or "scheduler-connection-lost" in str(exc)


def _lost_reason(exc: BaseException) -> str:
    if "scheduler-connection-lost" in str(exc):
        return "the connection to it was lost"
    return f"{type(exc).__name__}: {one_line(exc)}"[:100]


def _run_on_worker(spec: RunSpec) -> dict:
    """``run_one`` on a Dask worker; the row names the worker's address."""
    from distributed import get_worker

    row = run_one(spec)
    row["worker"] = get_worker().address
    return row


class _quiet:
    """Silence Dask's log records (they would add lines to the sweep's one-line errors)."""

    def __enter__(self):
        names = [n for n in logging.root.manager.loggerDict if n.split(".")[0] in _LOGGERS]
        self._loggers = [(logger, logger.disabled) for logger in map(logging.getLogger, {*names, *_LOGGERS})]
        for logger, _ in self._loggers:
            logger.disabled = True
        return self

    def __exit__(self, *exc):
        for logger, disabled in self._loggers:
            logger.disabled = disabled
        return False
