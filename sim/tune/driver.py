"""Running a sweep: the runs not yet in the results file, on local worker processes or Dask.

Every run has a wall-clock watchdog of :func:`watchdog_s` seconds:
``1.1 x`` its planning time limit (the planner's own deadline, with slack)
plus an allowance for building the problem, ``BUILD_ALLOWANCE_S``, and for
the physics run when simulating, ``PHYSICS_ALLOWANCE_S`` (``allowance=``
replaces both).  A run whose watchdog fires is recorded as a failed row
(``error_type`` ``"Timeout"``), and so is a run whose worker process dies
(``"WorkerDied"``); the other runs go on.  Such rows are results like any
other: a rerun skips them (a rerun with another ``--time-limit`` is another
run).
"""

from __future__ import annotations

import math
import os
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from .limits import BUILD_ALLOWANCE_S, PHYSICS_ALLOWANCE_S, TIMEOUT, WORKER_DIED
from .results import ResultsFile, check_output
from .spec import RunSpec, TuneError

__all__ = [
    "BUILD_ALLOWANCE_S",
    "PHYSICS_ALLOWANCE_S",
    "TIMEOUT",
    "WORKER_DIED",
    "SweepResult",
    "sweep",
    "watchdog_s",
]


PLANNING_SLACK = 1.1
"""The watchdog allows this multiple of the planning time limit."""



def watchdog_s(spec: RunSpec, allowance: float | None = None) -> float:
    """Wall-clock seconds a run may take: ``1.1 * time_limit + allowance``.

    ``allowance`` defaults to ``BUILD_ALLOWANCE_S`` (30 s), plus
    ``PHYSICS_ALLOWANCE_S`` (270 s) when the run simulates.
    """
    if allowance is None:
        allowance = BUILD_ALLOWANCE_S + (PHYSICS_ALLOWANCE_S if spec.simulate else 0.0)
    return PLANNING_SLACK * float(spec.time_limit) + float(allowance)


@dataclass(frozen=True)
class SweepResult:
    """What a sweep did.

    total: runs in the grid; skipped: already in the file; computed: rows
    written now; of those, no_plan: runs without a plan, raised: runs that
    raised, timed_out: runs stopped by their watchdog, worker_died: runs
    whose worker process died; not_done: runs with no row (a cluster lost
    them; a rerun computes them), with the reason; workers_replaced: local
    worker processes started again after one was stopped or died.
    """

    path: Path
    total: int
    skipped: int
    computed: int
    no_plan: int
    raised: int
    not_done: tuple[tuple[RunSpec, str], ...] = ()
    workers_replaced: int = 0
    timed_out: int = 0
    worker_died: int = 0

    @property
    def complete(self) -> bool:
        return not self.not_done


class _State:
    """The rows as they arrive: written to the file at once, counted, shown on the progress bar."""

    def __init__(self, results: ResultsFile, bar, total: int):
        self.results, self.bar, self.total = results, bar, total
        self.done = self.no_plan = self.raised = self.timed_out = self.worker_died = self.replaced = 0
        self.not_done: list[tuple[RunSpec, str]] = []

    def record(self, row: dict) -> None:
        self.results.append(row)
        self.done += 1
        kind = row.get("error_type")
        if kind == "NoPlanFound":
            self.no_plan += 1
        elif kind == TIMEOUT:
            self.timed_out += 1
        elif kind == WORKER_DIED:
            self.worker_died += 1
        elif kind is not None:
            self.raised += 1
        self.bar.update(1)
        failed = self.no_plan + self.raised + self.timed_out + self.worker_died
        if failed:
            self.bar.set_postfix_str(f"{failed} failed", refresh=False)


def sweep(
    specs: Sequence[RunSpec],
    path: str | Path,
    *,
    workers: int | None = None,
    scheduler: str | None = None,
    progress: bool | None = None,
    log=None,
    allowance: float | None = None,
) -> SweepResult:
    """Compute the runs not yet in ``path`` and append their rows.

    workers: local worker processes (default ``os.cpu_count()``).  With
        ``scheduler``, the most runs in flight on the cluster (default:
        its thread count when the sweep starts).
    scheduler: address of a Dask distributed scheduler
        (``tcp://HOST:PORT``); its workers need swarmform installed.
    progress: show a progress bar (default: when ``log`` is a terminal).
    log: stream for status lines and the progress bar (default ``sys.stderr``).
    allowance: seconds each run may take beyond ``1.1 x`` its time limit
        (default: see :func:`watchdog_s`).

    Raises :class:`TuneError` for bad input (before any run) and
    :class:`~sim.tune.cluster.ClusterLostError` when the Dask scheduler is
    lost mid-sweep (the rows written so far stay).
    """
    log = sys.stderr if log is None else log
    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int) or workers < 1):
        raise TuneError(f"--workers: must be an integer >= 1, got {workers!r}")
    if allowance is not None and (isinstance(allowance, bool) or not isinstance(allowance, (int, float))
                                  or not math.isfinite(allowance) or allowance < 0):
        raise TuneError(f"--allowance: must be a finite number of seconds >= 0, got {allowance!r}")
    path = Path(path)
    check_output(path)  # before connecting: an unreachable scheduler leaves no file behind
    client = None
    if scheduler is not None:
        from .cluster import connect

        client = connect(scheduler)
    try:
        results = ResultsFile(path, log)
    except BaseException:
        if client is not None:
            client.close()
        raise
    try:
        todo, seen = [], set()
        for s in specs:
            if not results.has(s) and s.key not in seen:
                seen.add(s.key)
                todo.append(s)
        total = len({s.key for s in specs})
        skipped = total - len(todo)
        local = min(workers or os.cpu_count() or 1, max(len(todo), 1))
        where = f"on {scheduler}" if scheduler else f"on {local} worker process{'es' if local > 1 else ''}"
        print(f"swarmform tune: {len(todo)} runs to compute {where}, {skipped} already in {path}", file=log)
        state = _State(results, _bar(len(todo), log, progress), len(todo))

        def limit(spec: RunSpec) -> float:
            return watchdog_s(spec, allowance)

        try:
            if todo and client is not None:
                from .cluster import ClusterLostError, run_cluster

                try:
                    run_cluster(todo, client, workers, state, limit)
                except ClusterLostError as exc:
                    raise ClusterLostError(
                        f"--scheduler: lost the Dask scheduler at {scheduler} mid-sweep ({exc}); "
                        f"{state.done} of {len(todo)} runs were written to {path}; rerun the same "
                        "command to finish") from None
            elif todo:
                from .pool import run_pool

                run_pool(todo, local, state, limit)
        finally:
            state.bar.close()
        return SweepResult(path, total, skipped, state.done, state.no_plan, state.raised, tuple(state.not_done),
                           state.replaced, state.timed_out, state.worker_died)
    finally:
        results.close()
        if client is not None:
            from .cluster import close

            close(client)


def _bar(total: int, log, progress: bool | None):
    from tqdm import tqdm

    if progress is None:
        isatty = getattr(log, "isatty", None)
        progress = bool(isatty and isatty())
    return tqdm(total=total, desc="  tune", unit="run", file=log, disable=not progress, mininterval=0.2,
                dynamic_ncols=True, leave=True)

