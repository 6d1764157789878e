"""Tuning sweeps over the planner's g and q: parallel, resumable, summarised.

A sweep is the grid of runs (scenario, g, q, seed), plus auto mode (g = q =
auto) when asked for.  Each run is one call of :func:`run_one` on a
:class:`RunSpec`: one generator, seeded with the run's seed, builds the
problem and plans, exactly as ``swarmform run`` does, so a row depends only
on its spec, wherever it is computed (a worker process, a Dask worker, the
sweep's own process), apart from the fields in :data:`VOLATILE_FIELDS`.

The results file is JSON Lines, one row per finished run.  Only the process
that drives the sweep writes it, each row as one ``write`` followed by an
``fsync``, so an interrupted sweep keeps every finished row and leaves at
most a torn last line, which the next start cuts off.  Rerunning the same
command skips the runs already in the file (see :attr:`RunSpec.key`).  A run
that raises is a row too, a failure with its error; a worker process that
dies takes no finished row with it, and its runs are computed again.

Beside ``NAME.jsonl`` the summary writes ``NAME.md`` (per scenario and
setting: success rate, median and 90th percentile planning time of the
successful runs; whether auto beats the best fixed setting; the comparison
with the paper's Tables II and III when the rows allow it) and
``NAME-SCENARIO.png`` (heatmaps of success rate and median time over g and q,
for scenarios with at least two fixed settings).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import signal
import socket
import sys
import threading
import time
from collections import Counter, defaultdict
from collections.abc import Callable, Iterable, Sequence
from concurrent.futures import FIRST_COMPLETED, Executor, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from planner import NoPlanFound, plan

from .argtypes import int_at_least, seconds
from .media import atomic_path
from .progress import ProgressBar
from .runner import InputError
from .scenario import Scenario, build_problem, read_scenario

__all__ = [
    "KEY_FIELDS",
    "PAPER_DIR",
    "VOLATILE_FIELDS",
    "RunSpec",
    "SweepResult",
    "TuneError",
    "add_tune_parser",
    "grid",
    "paper_grid",
    "paper_table",
    "read_results",
    "run_one",
    "summarize",
    "sweep",
    "write_summary",
]

VOLATILE_FIELDS = ("planning_time_s", "wall_time_s", "host")
"""Row fields that depend on the machine and the moment, not on the run's spec."""

KEY_FIELDS = ("scenario", "mode", "g", "q", "seed", "time_limit", "simulate")
"""The row fields that identify a run: a rerun skips a spec whose key is in the file."""

PAPER_DIR = Path(__file__).resolve().parents[1] / "scenarios" / "paper"
"""Where ``--paper`` finds the scenarios of the paper's Tables II and III (``table*.yaml``)."""

_MAX_POOL_RESTARTS = 3  # a worker that dies breaks the pool; start a new one at most this often
_DASK_CONNECT_TIMEOUT_S = 10.0
_ORPHAN_POLL_S = 0.25  # how often a worker checks that the sweep's process still lives


class TuneError(InputError):
    """Wrong input to a sweep (one line naming the file or option, and the reason)."""


# ----------------------------------------------------------------------------
# one run


@dataclass(frozen=True)
class RunSpec:
    """One run of a sweep.

    mode: ``"fixed"`` (g and q given) or ``"auto"`` (g and q ``None``).
    seed: seeds the run's one generator (problem and planner).
    time_limit: planning time limit [s].
    simulate: also execute the plan in the physics world.
    The scenario travels with the spec, so workers need no scenario files.
    """

    scenario: Scenario
    mode: str
    g: int | None
    q: int | None
    seed: int
    time_limit: float
    simulate: bool = False

    @property
    def key(self) -> tuple:
        """``(scenario name, mode, g, q, seed, time_limit, simulate)``; names are unique in a sweep."""
        return (self.scenario.name, self.mode, self.g, self.q, self.seed, float(self.time_limit),
                self.simulate)

    def __post_init__(self):
        fixed = all(isinstance(v, int) and not isinstance(v, bool) and v >= 1 for v in (self.g, self.q))
        if not ((self.mode == "fixed" and fixed) or (self.mode == "auto" and self.g is None and self.q is None)):
            raise ValueError(f"mode {self.mode!r} with g={self.g!r}, q={self.q!r}: 'fixed' needs integers "
                             ">= 1, 'auto' needs None for both")


def run_one(spec: RunSpec) -> dict:
    """Build the problem, plan (and with ``spec.simulate`` execute); return the result row.

    Never raises for a failing run (an ``Exception``): the row then has
    ``found`` false (unless planning succeeded before the error) and the
    error's type and text in ``error_type`` and ``error``.  Times in seconds,
    lengths in workspace units; ``None`` where a value does not exist.
    """
    t0 = time.perf_counter()
    sc = spec.scenario
    row = {
        "scenario": sc.name,
        "scenario_file": sc.path,
        "mode": spec.mode,
        "g": spec.g,
        "q": spec.q,
        "seed": spec.seed,
        "time_limit": float(spec.time_limit),
        "simulate": spec.simulate,
        "robots": sc.count,
        "start": sc.start.describe(),
        "target": sc.target.describe(),
        "paper_table": sc.paper.table if sc.paper else None,
        "paper_row": sc.paper.row if sc.paper else None,
        "paper_time_s": sc.paper.time_s if sc.paper else None,
        "paper_g": sc.planner.g if sc.paper else None,
        "paper_q": sc.planner.q if sc.paper else None,
        "found": False,
        "planning_time_s": None,
        "g_used": None,
        "q_used": None,
        "graphs": None,
        "connections": None,
        "steps": None,
        "makespan_s": None,
        "path_length": None,
        "min_clearance": None,
        "makespan_lower_bound_s": None,
        "sim_ok": None,
        "sim_contacts": None,
        "sim_reached": None,
        "sim_min_clearance": None,
        "sim_max_tracking_error": None,
        "error_type": None,
        "error": None,
        "wall_time_s": None,
        "host": socket.gethostname(),
    }
    try:
        rng = np.random.default_rng(spec.seed)
        problem = build_problem(sc, rng)
        row["robots"] = problem.m
        params = replace(sc.planner, g=spec.g, q=spec.q, time_limit=float(spec.time_limit))
        try:
            result, stats = plan(problem, params, rng)
        except NoPlanFound as exc:
            row.update(_stats_fields(exc.stats))
            row["found"] = False
            row["error_type"], row["error"] = "NoPlanFound", _one_line(exc)
        else:
            row.update(_stats_fields(stats))
            if spec.simulate:
                from .execute import execute

                sim = execute(problem, result, sc.sim)
                row["sim_ok"] = bool(sim.ok)
                row["sim_contacts"] = len(sim.contacts)
                row["sim_reached"] = bool(sim.reached)
                row["sim_min_clearance"] = _num(sim.min_clearance)
                row["sim_max_tracking_error"] = _num(sim.max_tracking_error)
    except Exception as exc:  # noqa: BLE001 - a failing run is a row, not the end of the sweep
        row["error_type"], row["error"] = type(exc).__name__, _one_line(exc)
    row["wall_time_s"] = time.perf_counter() - t0
    return row


def _stats_fields(stats) -> dict:
    return {
        "found": bool(stats.found),
        "planning_time_s": _num(stats.planning_time_s),
        "g_used": int(stats.g),
        "q_used": int(stats.q),
        "graphs": int(stats.graphs),
        "connections": int(stats.connections),
        "steps": int(stats.steps) if stats.found else None,
        "makespan_s": _num(stats.makespan_s) if stats.found else None,
        "path_length": _num(stats.path_length) if stats.found else None,
        "min_clearance": _num(stats.min_clearance) if stats.found else None,
        "makespan_lower_bound_s": _num(stats.makespan_lower_bound_s) if stats.found else None,
    }


def _num(v) -> float | None:
    v = float(v)
    return v if math.isfinite(v) else None


def _one_line(exc: BaseException) -> str:
    return " ".join(str(exc).split()) or type(exc).__name__


# ----------------------------------------------------------------------------
# the grid


def grid(
    scenarios: Sequence[Scenario],
    *,
    g: Sequence[int] | None = None,
    q: Sequence[int] | None = None,
    auto: bool = False,
    seeds: Iterable[int] = range(20),
    time_limit: float | None = None,
    simulate: bool = False,
) -> list[RunSpec]:
    """The runs of a sweep over ``g`` x ``q`` (plus auto) x ``seeds``, per scenario.

    Without ``g`` and ``q`` each scenario runs its own planner g and q (only
    auto when its file says auto); with one of them, the other comes from the
    file.  ``time_limit`` [s] overrides each scenario's ``planner.time_limit``.
    The runs are ordered seed by seed, so a sweep stopped early has covered
    every setting about equally.
    """
    scenarios = _unique(scenarios)
    seeds = _check_seeds(seeds)
    g = _check_counts(g, "--g")
    q = _check_counts(q, "--q")
    time_limit = _check_time_limit(time_limit)
    settings = {}
    for sc in scenarios:
        own = sc.planner
        if g is None and q is None:
            fixed = [] if own.auto else [(own.g, own.q)]
            settings[sc.name] = (fixed, auto or own.auto)
            continue
        for values, name in ((g, "g"), (q, "q")):
            if values is None and getattr(own, name) is None:
                raise TuneError(f"{sc.path}: planner.{name}: is auto, so the sweep needs --{name} values")
        fixed = [(gi, qi) for gi in (g or [own.g]) for qi in (q or [own.q])]
        settings[sc.name] = (fixed, auto)
    return _specs(scenarios, settings, seeds, time_limit, simulate)


def paper_grid(
    scenarios: Sequence[Scenario],
    *,
    seeds: Iterable[int] = range(20),
    time_limit: float | None = None,
    simulate: bool = False,
) -> list[RunSpec]:
    """The runs that reproduce the paper's tables: each scenario at its own g and q, and auto.

    Every scenario must carry a ``paper`` block (its table, row and time).
    """
    scenarios = _unique(scenarios)
    for sc in scenarios:
        if sc.paper is None:
            raise TuneError(f"{sc.path}: paper: missing; --paper needs scenarios from the paper's "
                            "tables (with paper: {table, row, time_s})")
    settings = {sc.name: ([] if sc.planner.auto else [(sc.planner.g, sc.planner.q)], True)
                for sc in scenarios}
    return _specs(scenarios, settings, _check_seeds(seeds), _check_time_limit(time_limit), simulate)


def _specs(scenarios, settings, seeds, time_limit, simulate) -> list[RunSpec]:
    out = []
    for seed in seeds:
        for sc in scenarios:
            fixed, auto = settings[sc.name]
            limit = sc.planner.time_limit if time_limit is None else time_limit
            out += [RunSpec(sc, "fixed", gi, qi, seed, float(limit), simulate) for gi, qi in fixed]
            if auto:
                out.append(RunSpec(sc, "auto", None, None, seed, float(limit), simulate))
    return out


def _unique(scenarios: Sequence[Scenario]) -> list[Scenario]:
    """The scenarios without repeats; two different files may not share a name."""
    out: dict[str, Scenario] = {}
    for sc in scenarios:
        seen = out.get(sc.name)
        if seen is None:
            out[sc.name] = sc
        elif os.path.realpath(seen.path) != os.path.realpath(sc.path):
            raise TuneError(f"{sc.path}: name: {sc.name!r} is also the name of {seen.path}; "
                            "scenario names must be unique in a sweep")
    if not out:
        raise TuneError("SCENARIO: give at least one scenario file")
    return list(out.values())


def _check_counts(values, option: str) -> list[int] | None:
    if values is None:
        return None
    values = list(dict.fromkeys(values))
    for v in values:
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 1:
            raise TuneError(f"{option}: must be integers >= 1, got {v!r}")
    if not values:
        raise TuneError(f"{option}: give at least one value")
    return [int(v) for v in values]


def _check_seeds(seeds) -> list[int]:
    seeds = list(dict.fromkeys(seeds))
    if not seeds:
        raise TuneError("--seeds: must be at least 1")
    for s in seeds:
        if isinstance(s, bool) or not isinstance(s, (int, np.integer)) or s < 0:
            raise TuneError(f"--seed-start: seeds must be integers >= 0, got {s!r}")
    return [int(s) for s in seeds]


def _check_time_limit(time_limit) -> float | None:
    if time_limit is None:
        return None
    if isinstance(time_limit, bool) or not isinstance(time_limit, (int, float)) \
            or not math.isfinite(time_limit) or time_limit <= 0:
        raise TuneError(f"--time-limit: must be a finite number of seconds > 0, got {time_limit!r}")
    return float(time_limit)


# ----------------------------------------------------------------------------
# the results file


def read_results(path: str | Path) -> list[dict]:
    """The rows of a results file, in file order.

    A torn last line (a sweep killed while writing) and lines that are not
    result rows are left out.  Raises :class:`TuneError` when the file
    cannot be read.
    """
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise TuneError(f"{path}: cannot read the results file: {exc.strerror or exc}") from None
    rows, _bad = _parse_rows(data)
    return rows


def _parse_rows(data: bytes) -> tuple[list[dict], list[int]]:
    """Rows of the complete lines of ``data``, and the numbers of the lines that are not rows."""
    end = data.rfind(b"\n") + 1
    rows, bad = [], []
    for n, line in enumerate(data[:end].splitlines(), 1):
        if not line.strip():
            continue
        try:
            row = json.loads(line)
        except (ValueError, UnicodeDecodeError):
            bad.append(n)
            continue
        if _is_row(row):
            rows.append(row)
        else:
            bad.append(n)
    return rows, bad


def _is_row(row) -> bool:
    if not isinstance(row, dict) or not all(k in row for k in (*KEY_FIELDS, "found")):
        return False
    ints = all(row[k] is None or (isinstance(row[k], int) and not isinstance(row[k], bool))
               for k in ("g", "q"))
    return (isinstance(row["scenario"], str) and row["mode"] in ("fixed", "auto") and ints
            and isinstance(row["seed"], int) and isinstance(row["time_limit"], (int, float))
            and isinstance(row["simulate"], bool) and isinstance(row["found"], bool))


def _row_key(row: dict) -> tuple:
    return (row["scenario"], row["mode"], row["g"], row["q"], row["seed"], float(row["time_limit"]),
            row["simulate"])


class _ResultsFile:
    """The results file, open for appending by this process alone.

    Opening takes an exclusive lock (where the platform has ``fcntl``), so
    two sweeps never write one file, and cuts off a torn last line.
    """

    def __init__(self, path: Path, log):
        self.path = path
        path.parent.mkdir(parents=True, exist_ok=True)
        try:
            self._fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_APPEND, 0o666)
        except OSError as exc:
            raise TuneError(f"{path}: cannot open the results file: {exc.strerror or exc}") from None
        try:
            self._lock()
            data = self._read_all()
            end = data.rfind(b"\n") + 1
            if end < len(data):
                os.ftruncate(self._fd, end)
                os.fsync(self._fd)
                print(f"swarmform tune: {path}: cut off a torn last line ({len(data) - end} bytes)",
                      file=log)
            self.rows, bad = _parse_rows(data[:end])
            if bad:
                lines = ", ".join(map(str, bad[:5])) + (" ..." if len(bad) > 5 else "")
                print(f"swarmform tune: {path}: ignored {len(bad)} line(s) that are not result rows "
                      f"(line {lines})", file=log)
        except BaseException:
            os.close(self._fd)
            raise
        self.keys = {_row_key(r) for r in self.rows}

    def _lock(self) -> None:
        # A POSIX record lock belongs to this process alone: forked workers do
        # not inherit it, so a worker outliving a killed sweep never blocks
        # the rerun; the system drops it when the process ends, however.
        try:
            import fcntl
        except ImportError:  # no advisory locks on this platform
            return
        try:
            fcntl.lockf(self._fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            raise TuneError(f"{self.path}: is being written by another sweep") from None

    def _read_all(self) -> bytes:
        os.lseek(self._fd, 0, os.SEEK_SET)
        chunks = []
        while chunk := os.read(self._fd, 1 << 20):
            chunks.append(chunk)
        return b"".join(chunks)

    def append(self, row: dict) -> None:
        """Add one row as one line: a single write (completed if short), then fsync."""
        data = (json.dumps(row, allow_nan=False, ensure_ascii=False) + "\n").encode("utf-8")
        done = os.write(self._fd, data)
        while done < len(data):
            done += os.write(self._fd, data[done:])
        os.fsync(self._fd)
        self.rows.append(row)
        self.keys.add(_row_key(row))

    def close(self) -> None:
        os.close(self._fd)


# ----------------------------------------------------------------------------
# running a sweep


@dataclass(frozen=True)
class SweepResult:
    """What a sweep did.

    total: runs in the grid; skipped: already in the file; computed: rows
    written now; no_plan: of those, runs without a plan; raised: runs that
    raised; not_done: runs with no row because their worker was lost (a
    rerun computes them), with the reason.
    """

    path: Path
    total: int
    skipped: int
    computed: int
    no_plan: int
    raised: int
    not_done: tuple[tuple[RunSpec, str], ...] = ()
    pool_restarts: int = 0

    @property
    def complete(self) -> bool:
        return not self.not_done


def sweep(
    specs: Sequence[RunSpec],
    path: str | Path,
    *,
    workers: int | None = None,
    scheduler: str | None = None,
    progress: bool | None = None,
    log=None,
) -> SweepResult:
    """Compute the runs not yet in ``path`` and append their rows.

    workers: local worker processes (default ``os.cpu_count()``); ``1``
        runs in this process, without a pool.  With ``scheduler``, the
        number of runs in flight on the cluster at a time (default all).
    scheduler: address of a Dask distributed scheduler
        (``tcp://HOST:PORT``); its workers need swarmform installed.
    progress: draw a progress bar (default: when ``log`` is a terminal).
    log: stream for status lines and the progress bar (default ``sys.stderr``).
    """
    log = sys.stderr if log is None else log
    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int) or workers < 1):
        raise TuneError(f"--workers: must be an integer >= 1, got {workers!r}")
    path = Path(path)
    client = _connect(scheduler) if scheduler is not None else None
    try:
        results = _ResultsFile(path, log)
    except BaseException:
        if client is not None:
            client.close()
        raise
    try:
        todo, seen = [], set()
        for s in specs:
            if s.key not in results.keys and s.key not in seen:
                seen.add(s.key)
                todo.append(s)
        skipped = len({s.key for s in specs}) - len(todo)
        local = min(workers or os.cpu_count() or 1, max(len(todo), 1))
        where = (f"on {scheduler}" if scheduler else
                 "in this process" if local == 1 else f"on {local} worker processes")
        print(f"swarmform tune: {len(todo)} runs to compute {where}, "
              f"{skipped} already in {path}", file=log)
        state = _State(results, ProgressBar("  tune", stream=log, enabled=progress), len(todo))
        try:
            if not todo:
                pass
            elif client is not None:
                _run_dask(todo, client, workers, state)
            elif local == 1:
                for s in todo:
                    state.record(run_one(s))
            else:
                _run_pool(todo, local, state)
        finally:
            state.bar.close()
        return SweepResult(path, len({s.key for s in specs}), skipped, state.done, state.no_plan,
                           state.raised, tuple(state.not_done), state.restarts)
    finally:
        results.close()
        if client is not None:
            client.close()


@dataclass
class _State:
    results: _ResultsFile
    bar: ProgressBar
    total: int
    done: int = 0
    no_plan: int = 0
    raised: int = 0
    restarts: int = 0
    not_done: list = field(default_factory=list)

    def record(self, row: dict) -> None:
        self.results.append(row)
        self.done += 1
        if row["error_type"] == "NoPlanFound":
            self.no_plan += 1
        elif row["error_type"] is not None:
            self.raised += 1
        failed = self.no_plan + self.raised
        self.bar(self.done / max(self.total, 1), f"{self.done}/{self.total} runs, {failed} failed")


def _drive(executor: Executor, specs: Sequence[RunSpec], window: int | None, state: _State) -> bool:
    """Submit ``specs`` (at most ``window`` in flight) and record each row as it arrives.

    Returns True when the process pool broke (a worker died); the runs
    without a row are then for the caller to submit again.  Runs whose
    future fails otherwise (a lost cluster worker) go to ``state.not_done``.
    """
    pending = iter(specs)
    running: dict[Future, RunSpec] = {}
    broken = False

    def fill() -> None:
        nonlocal broken
        while not broken and (window is None or len(running) < window):
            spec = next(pending, None)
            if spec is None:
                return
            try:
                running[executor.submit(run_one, spec)] = spec
            except BrokenProcessPool:
                broken = True

    fill()
    while running:
        finished, _ = wait(running, return_when=FIRST_COMPLETED)
        for fut in finished:
            spec = running.pop(fut)
            try:
                row = fut.result()
            except BrokenProcessPool:
                broken = True
                continue
            except Exception as exc:  # noqa: BLE001 - infrastructure, not the run: no row
                state.not_done.append((spec, f"{type(exc).__name__}: {_one_line(exc)}"))
                continue
            state.record(row)
        fill()
    return broken


def _run_pool(todo: list[RunSpec], workers: int, state: _State) -> None:
    """Local worker processes; a pool broken by a dying worker is replaced a few times."""
    remaining = todo
    while remaining:
        executor = ProcessPoolExecutor(max_workers=min(workers, len(remaining)), initializer=_worker_init,
                                       initargs=(os.getpid(),))
        try:
            broken = _drive(executor, remaining, 2 * workers, state)
        except BaseException:
            _abandon(executor)
            raise
        executor.shutdown(wait=True)
        lost = {s.key for s, _ in state.not_done}
        remaining = [s for s in remaining if s.key not in state.results.keys and s.key not in lost]
        if not broken or not remaining:
            return
        if state.restarts >= _MAX_POOL_RESTARTS:
            reason = f"a worker process died {state.restarts + 1} times (BrokenProcessPool); stopped"
            state.not_done.extend((s, reason) for s in remaining)
            return
        state.restarts += 1


def _worker_init(sweep_pid: int) -> None:
    """Workers leave Ctrl-C to the sweep, which stops them, and end when the sweep's process does.

    A worker of a pool whose process was killed would otherwise wait for
    work forever.
    """
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    threading.Thread(target=_exit_with, args=(sweep_pid,), daemon=True, name="exit-with-sweep").start()


def _exit_with(sweep_pid: int) -> None:
    while os.getppid() == sweep_pid:
        time.sleep(_ORPHAN_POLL_S)
    os._exit(1)


def _abandon(executor: ProcessPoolExecutor) -> None:
    """Stop a pool now: cancel what has not started, end the workers that are running."""
    stop = getattr(executor, "terminate_workers", None)  # Python >= 3.14
    if stop is not None:
        stop()
        return
    processes = list((getattr(executor, "_processes", None) or {}).values())
    executor.shutdown(wait=False, cancel_futures=True)
    for p in processes:
        if p.is_alive():
            p.terminate()


def _connect(address: str):
    """A Dask distributed client of the scheduler at ``address`` (dask is imported only here)."""
    try:
        from dask.distributed import Client
    except ImportError:
        raise TuneError("--scheduler: needs dask.distributed; install it with "
                        "pip install 'swarmform[cluster]'") from None
    try:
        return Client(address, timeout=_DASK_CONNECT_TIMEOUT_S)
    except Exception as exc:  # noqa: BLE001 - any failure to connect is bad input
        raise TuneError(f"--scheduler: cannot connect to {address}: "
                        f"{type(exc).__name__}: {_one_line(exc)}") from None


def _run_dask(todo: list[RunSpec], client, window: int | None, state: _State) -> None:
    """The same runs on an existing Dask distributed cluster, through its concurrent.futures executor."""
    # pure=False: every run is computed, never taken from the cluster's cache
    executor = client.get_executor(pure=False)
    try:
        _drive(executor, todo, window, state)
    except BaseException:
        executor.shutdown(wait=False)
        raise
    executor.shutdown(wait=True)


# ----------------------------------------------------------------------------
# summaries


@dataclass(frozen=True)
class _Cell:
    """The runs of one setting of one scenario (one time limit, with or without physics)."""

    mode: str
    g: int | None
    q: int | None
    runs: int
    found: int
    raised: int
    sim_ok: int | None
    median_s: float | None
    p90_s: float | None
    errors: tuple[tuple[str, int], ...]

    @property
    def rate(self) -> float:
        return self.found / self.runs if self.runs else 0.0

    @property
    def label(self) -> str:
        return "auto" if self.mode == "auto" else f"g={self.g}, q={self.q}"


def _cell(rows: list[dict]) -> _Cell:
    times = [r["planning_time_s"] for r in rows if r["found"] and r.get("planning_time_s") is not None]
    raised = Counter(f"{r['error_type']}: {r.get('error') or ''}" for r in rows
                     if r.get("error_type") not in (None, "NoPlanFound"))
    simulated = [r for r in rows if r["simulate"]]
    first = rows[0]
    return _Cell(
        mode=first["mode"],
        g=first["g"],
        q=first["q"],
        runs=len(rows),
        found=sum(bool(r["found"]) for r in rows),
        raised=sum(raised.values()),
        sim_ok=sum(r.get("sim_ok") is True for r in simulated) if simulated else None,
        median_s=float(np.median(times)) if times else None,
        p90_s=float(np.percentile(times, 90)) if times else None,
        errors=tuple(raised.most_common()),
    )


def _groups(rows: list[dict]) -> dict[tuple[str, float, bool], list[_Cell]]:
    """Per (scenario, time limit, physics): one cell per setting, fixed by (g, q), then auto."""
    by: dict = defaultdict(lambda: defaultdict(dict))
    for r in rows:  # a later row of the same run replaces an earlier one
        by[(r["scenario"], float(r["time_limit"]), r["simulate"])][(r["mode"], r["g"], r["q"])][r["seed"]] = r
    out = {}
    for variant in sorted(by, key=lambda v: (v[0], v[1], v[2])):
        settings = by[variant]
        order = sorted(settings, key=lambda s: (s[0] == "auto", s[1] or 0, s[2] or 0))
        out[variant] = [_cell(list(settings[s].values())) for s in order]
    return out


def _info(rows: list[dict]) -> dict[str, dict]:
    """Per scenario: robots, formations, file, seeds and paper reference (from its last row)."""
    out: dict[str, dict] = {}
    for r in rows:
        d = out.setdefault(r["scenario"], {"seeds": set()})
        d.update({k: r.get(k) for k in ("robots", "start", "target", "scenario_file", "paper_table",
                                        "paper_row", "paper_time_s", "paper_g", "paper_q")})
        d["seeds"].add(r["seed"])
    return out


def _best_fixed(cells: list[_Cell]) -> _Cell | None:
    fixed = [c for c in cells if c.mode == "fixed"]
    if not fixed:
        return None
    return max(fixed, key=lambda c: (c.rate, -(c.median_s if c.median_s is not None else math.inf)))


def _auto_verdict(cells: list[_Cell]) -> str | None:
    """Whether auto beats the best fixed setting: success rate first, then median time."""
    auto = next((c for c in cells if c.mode == "auto"), None)
    best = _best_fixed(cells)
    if auto is None or best is None:
        return None
    a = f"auto {_pct(auto.found, auto.runs)} found, median {_sec(auto.median_s)}"
    b = f"best fixed ({best.label}) {_pct(best.found, best.runs)} found, median {_sec(best.median_s)}"
    if auto.rate != best.rate:
        winner = "auto beats the best fixed setting" if auto.rate > best.rate else \
            "the best fixed setting beats auto"
        return f"{winner} on success rate: {a}; {b}."
    if auto.median_s is None and best.median_s is None:
        return f"neither auto nor any fixed setting found a plan: {a}; {b}."
    if auto.median_s == best.median_s:
        return f"auto ties with the best fixed setting: {a}; {b}."
    winner = "auto beats the best fixed setting" if auto.median_s < best.median_s else \
        "the best fixed setting beats auto"
    return f"{winner} on median time (same success rate): {a}; {b}."


def _pct(k: int, n: int) -> str:
    return f"{100 * k / n:.0f}% ({k}/{n})" if n else "-"


def _sec(v: float | None) -> str:
    if v is None:
        return "-"
    return f"{v:.3f} s" if v < 10 else f"{v:.1f} s"


def _num_cell(v: float | None) -> str:
    if v is None:
        return "-"
    return f"{v:.3f}" if v < 10 else f"{v:.1f}"


def _seeds_text(seeds: set[int]) -> str:
    s = sorted(seeds)
    if s == list(range(s[0], s[-1] + 1)):
        return f"seeds {s[0]}..{s[-1]} ({len(s)})" if len(s) > 1 else f"seed {s[0]}"
    return f"{len(s)} seeds"


def summarize(rows: list[dict]) -> str:
    """Markdown: per scenario, one table of its settings, and auto against the best fixed setting."""
    info = _info(rows)
    groups = _groups(rows)
    scenarios = list(dict.fromkeys(v[0] for v in groups))
    lines = [
        "Planning times are wall-clock seconds of the successful runs, on the machines that ran them; "
        "each seed draws its own obstacles and placements where the scenario leaves them random.",
        "",
    ]
    for name in scenarios:
        d = info[name]
        lines += [f"### {name}", "",
                  f"{d['robots']} robots, {d['start']} -> {d['target']} ({d['scenario_file']}).", ""]
        for variant, cells in groups.items():
            if variant[0] != name:
                continue
            _, limit, physics = variant
            seeds = {r["seed"] for r in rows if r["scenario"] == name and float(r["time_limit"]) == limit
                     and r["simulate"] == physics}
            lines += [f"{_seeds_text(seeds)}, time limit {limit:g} s"
                      + (", plans executed in the physics world." if physics else "."), ""]
            head = ["g", "q", "runs", "found", "median [s]", "p90 [s]"]
            if physics:
                head.append("physics ok")
            head.append("raised")
            lines += ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
            for c in cells:
                cols = ["auto" if c.mode == "auto" else str(c.g), "auto" if c.mode == "auto" else str(c.q),
                        str(c.runs), _pct(c.found, c.runs), _num_cell(c.median_s), _num_cell(c.p90_s)]
                if physics:
                    cols.append(_pct(c.sim_ok or 0, c.runs))
                cols.append(str(c.raised))
                lines.append("| " + " | ".join(cols) + " |")
            lines.append("")
            verdict = _auto_verdict(cells)
            if verdict:
                lines += [f"Auto vs fixed: {verdict}", ""]
            raised = Counter()
            for c in cells:
                raised.update(dict(c.errors))
            for text, n in raised.most_common(3):
                lines.append(f"- raised in {n} run(s): {text}")
            if raised:
                lines.append("")
    return "\n".join(lines)


def paper_table(rows: list[dict]) -> str | None:
    """Markdown: the paper's Tables II and III against this implementation (fixed and auto).

    ``None`` when no row is from a paper scenario at the paper's g and q or
    in auto mode.
    """
    info = _info(rows)
    groups = _groups(rows)
    entries = []
    for (name, limit, physics), cells in groups.items():
        d = info[name]
        if d["paper_table"] is None:
            continue
        fixed = next((c for c in cells if c.mode == "fixed" and (c.g, c.q) == (d["paper_g"], d["paper_q"])),
                     None)
        auto = next((c for c in cells if c.mode == "auto"), None)
        if fixed is None and auto is None:
            continue
        entries.append((d, limit, physics, fixed, auto))
    if not entries:
        return None
    entries.sort(key=lambda e: ({"II": 2, "III": 3}.get(e[0]["paper_table"], 9), e[0]["paper_row"], e[1], e[2]))
    limits = sorted({e[1] for e in entries})
    several = len({(e[1], e[2]) for e in entries}) > 1
    seeds = set().union(*(e[0]["seeds"] for e in entries))
    head = ["table", "row", "m", "start -> target", "paper (g, q)", "paper time [s]",
            "fixed: success", "fixed: median [s]", "fixed: paper/ours",
            "auto: success", "auto: median [s]", "auto: paper/ours"]
    if several:
        head[6:6] = ["time limit [s]", "physics"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for d, limit, physics, fixed, auto in entries:
        cols = [str(d["paper_table"]), str(d["paper_row"]), str(d["robots"]), f"{d['start']} -> {d['target']}",
                f"({d['paper_g']}, {d['paper_q']})", f"{d['paper_time_s']:.3f}"]
        if several:
            cols += [f"{limit:g}", "yes" if physics else "no"]
        for c in (fixed, auto):
            if c is None:
                cols += ["not run", "-", "-"]
            else:
                ratio = d["paper_time_s"] / c.median_s if c.median_s else None
                cols += [_pct(c.found, c.runs), _num_cell(c.median_s), f"{ratio:.1f}" if ratio else "-"]
        lines.append("| " + " | ".join(cols) + " |")
    limit_text = ", ".join(f"{v:g}" for v in limits)
    lines += [
        "",
        f"Ours: {_seeds_text(seeds)} per row and mode, planning time limit {limit_text} s; median "
        "planning time of the successful runs.  Fixed runs use the paper's g and q for the row; auto "
        "runs choose g and q themselves.  The paper reports one time per row; each of our seeds draws "
        "its own random obstacles and placements, so each is another instance of the row's scenario.",
        "",
        "The paper's hardware is unknown, so the ratios (paper time / our median; above 1 means ours "
        "is faster) compare implementations on different machines and are rough.",
    ]
    return "\n".join(lines)


def write_summary(results_path: str | Path, rows: list[dict] | None = None) -> tuple[str, list[Path]]:
    """Write ``NAME.md`` and the heatmaps ``NAME-SCENARIO.png`` beside ``NAME.jsonl``, atomically.

    Returns the Markdown and the paths written.  ``rows`` default to the
    file's rows.
    """
    results_path = Path(results_path)
    rows = read_results(results_path) if rows is None else rows
    if not rows:
        raise TuneError(f"{results_path}: holds no result rows")
    parts = [f"# Tuning sweep: {results_path.name}", ""]
    paper = paper_table(rows)
    if paper:
        parts += ["## The paper's Tables II and III, reproduced", "", paper, ""]
    parts += ["## Per scenario", "", summarize(rows)]
    text = "\n".join(parts).rstrip() + "\n"
    md = results_path.with_suffix(".md")
    with atomic_path(md) as tmp:
        tmp.write_text(text, encoding="utf-8")
    written = [md]
    info = _info(rows)
    groups = _groups(rows)
    variants = defaultdict(list)
    for v in groups:
        variants[v[0]].append(v)
    for name, vs in variants.items():
        for v in vs:
            cells = groups[v]
            if sum(c.mode == "fixed" for c in cells) < 2:
                continue  # one setting: the table says it all
            suffix = "" if len(vs) == 1 else f"-t{v[1]:g}" + ("-physics" if v[2] else "")
            png = results_path.with_name(f"{results_path.stem}-{name}{suffix}.png")
            _heatmap(png, name, info[name], v, cells)
            written.append(png)
    return text, written


def _heatmap(path: Path, name: str, d: dict, variant, cells: list[_Cell]) -> None:
    """Two panels over (g, q): success rate and median planning time; auto in the title."""
    from matplotlib import colormaps
    from matplotlib.colors import LogNorm, Normalize
    from matplotlib.figure import Figure

    fixed = [c for c in cells if c.mode == "fixed"]
    gs = sorted({c.g for c in fixed})
    qs = sorted({c.q for c in fixed})
    rate = np.full((len(gs), len(qs)), np.nan)
    median = np.full((len(gs), len(qs)), np.nan)
    for c in fixed:
        i, j = gs.index(c.g), qs.index(c.q)
        rate[i, j] = c.rate
        median[i, j] = np.nan if c.median_s is None else c.median_s
    fig = Figure(figsize=(4.2 + 1.6 * len(qs), 2.6 + 0.45 * len(gs)), layout="constrained")
    axes = fig.subplots(1, 2)
    finite = median[np.isfinite(median)]
    if finite.size and finite.min() > 0 and finite.max() / finite.min() > 10:
        time_norm = LogNorm(finite.min(), finite.max())
    else:
        time_norm = Normalize(*(finite.min(), finite.max()) if finite.size else (0, 1))
    panels = (
        (axes[0], rate, "RdYlGn", Normalize(0, 1), "success rate", lambda v: f"{100 * v:.0f}%"),
        (axes[1], median, "viridis", time_norm, "median planning time [s]", lambda v: _num_cell(v)),
    )
    for ax, values, cmap_name, norm, title, fmt in panels:
        cmap = colormaps[cmap_name].with_extremes(bad="#d0d0d0")
        im = ax.imshow(np.ma.masked_invalid(values), cmap=cmap, norm=norm, origin="lower", aspect="auto")
        for i in range(len(gs)):
            for j in range(len(qs)):
                v = values[i, j]
                ax.text(j, i, fmt(v) if np.isfinite(v) else "no plan", ha="center", va="center", fontsize=9,
                        bbox={"boxstyle": "round,pad=0.15", "fc": "white", "alpha": 0.65, "lw": 0})
        ax.set_xticks(range(len(qs)), [str(q) for q in qs])
        ax.set_yticks(range(len(gs)), [str(g) for g in gs])
        ax.set_xlabel("q (connection attempts per pair of graphs)")
        ax.set_ylabel("g (pebble graphs)")
        ax.set_title(title, fontsize=10)
        fig.colorbar(im, ax=ax, shrink=0.9)
    _, limit, physics = variant
    runs = max(c.runs for c in cells)
    auto = next((c for c in cells if c.mode == "auto"), None)
    auto_text = (f"; auto: {_pct(auto.found, auto.runs)} found, median {_sec(auto.median_s)}"
                 if auto else "")
    fig.suptitle(f"{name}: {d['robots']} robots, {d['start']} -> {d['target']}\n"
                 f"{runs} seeds, time limit {limit:g} s{', physics' if physics else ''}{auto_text}",
                 fontsize=10)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=110)


# ----------------------------------------------------------------------------
# the command line


_TUNE_DESCRIPTION = """\
Run the grid of (scenario, g, q, seed) planning runs, plus auto mode with --auto,
on local worker processes or an existing Dask cluster.  Each finished run is
appended at once to a JSON Lines file; rerunning the same command skips the runs
already there, so an interrupted sweep is finished by running it again.  Then
write a Markdown summary beside the results (success rate, median and 90th
percentile planning time per setting; auto against the best fixed setting) and
heatmaps over (g, q)."""

_TUNE_EPILOG = """\
exit status:
  0  every run of the grid has its row (whatever the planner found)
  1  some runs could not be done (a worker was lost); rerun to finish them
  2  bad input

examples:
  swarmform tune scenarios/paper/fig2-random-to-C.yaml --g 1 2 3 --q 100 250 500 800 --auto
  swarmform tune a.yaml b.yaml --g 2 3 --q 250 500 --scheduler tcp://HOST:8786
  swarmform tune --paper --seeds 20
  swarmform tune --summarize media/fig2-random-to-C-tune.jsonl"""


def add_tune_parser(sub) -> argparse.ArgumentParser:
    """Register ``swarmform tune`` on the CLI's subparsers."""
    t = sub.add_parser(
        "tune",
        help="sweep the planner's g and q over seeds (parallel, resumable) and summarise",
        description=_TUNE_DESCRIPTION,
        epilog=_TUNE_EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    t.add_argument("scenarios", nargs="*", metavar="SCENARIO", help="scenario YAML files")
    t.add_argument("--g", nargs="+", type=int_at_least(1), metavar="G",
                   help="pebble graph counts to try (default: each scenario's planner.g)")
    t.add_argument("--q", nargs="+", type=int_at_least(1), metavar="Q",
                   help="connection attempts per pair of graphs to try (default: each scenario's planner.q)")
    t.add_argument("--auto", action="store_true", help="also run auto mode (g and q chosen by the planner)")
    t.add_argument("--seeds", type=int_at_least(1), default=20, metavar="N",
                   help="seeds per setting (default 20): SEED_START .. SEED_START+N-1")
    t.add_argument("--seed-start", type=int_at_least(0), default=0, metavar="S", help="first seed (default 0)")
    t.add_argument("--time-limit", type=seconds, metavar="S",
                   help="planning time limit per run [s] (default: each scenario's planner.time_limit)")
    t.add_argument("--simulate", action="store_true",
                   help="also execute each plan in the physics world and record its verdict")
    t.add_argument("--workers", type=int_at_least(1), metavar="N",
                   help="local worker processes (default: the CPU count; 1 runs in this process); "
                   "with --scheduler, the most runs in flight on the cluster")
    t.add_argument("--scheduler", metavar="ADDRESS",
                   help="run on an existing Dask cluster, e.g. tcp://HOST:8786 (needs swarmform[cluster])")
    t.add_argument("-o", "--output", metavar="FILE",
                   help="results file (default media/NAME-tune.jsonl, NAME the scenario's name or "
                   "'sweep' for several; media/paper-tables.jsonl with --paper)")
    t.add_argument("--paper", action="store_true",
                   help="reproduce the paper's Tables II and III: every scenarios/paper/table*.yaml "
                   "(or the SCENARIOs given) at its own g and q and in auto mode")
    t.add_argument("--summarize", metavar="RESULTS",
                   help="only write the Markdown and heatmaps of an existing results file; run nothing")
    t.add_argument("--no-progress", action="store_true", help="no progress bar")
    t.set_defaults(func=_cmd_tune)
    t.error = _one_line_error(t)  # bad options: one line, exit 2, like bad files
    return t


def _one_line_error(parser: argparse.ArgumentParser) -> Callable[[str], None]:
    def error(message: str) -> None:
        parser.exit(2, f"{parser.prog}: error: {message} (see {parser.prog} --help)\n")

    return error


def _cmd_tune(args) -> int:
    if args.summarize is not None:
        return _cmd_summarize(args)
    if args.paper:
        if args.g or args.q or args.auto:
            raise TuneError("--paper: runs each scenario at the paper's own g and q and in auto mode; "
                            "drop --g, --q and --auto")
        files = args.scenarios or sorted(str(p) for p in PAPER_DIR.glob("table*.yaml"))
        if not files:
            raise TuneError(f"{PAPER_DIR}: no table*.yaml scenarios; give the SCENARIO files")
    else:
        files = args.scenarios
        if not files:
            raise TuneError("SCENARIO: give at least one scenario file (or --paper, or --summarize FILE)")
    scenarios = [read_scenario(f) for f in files]
    seeds = range(args.seed_start, args.seed_start + args.seeds)
    if args.paper:
        specs = paper_grid(scenarios, seeds=seeds, time_limit=args.time_limit, simulate=args.simulate)
        default = Path("media") / "paper-tables.jsonl"
    else:
        specs = grid(scenarios, g=args.g, q=args.q, auto=args.auto, seeds=seeds,
                     time_limit=args.time_limit, simulate=args.simulate)
        names = list(dict.fromkeys(sc.name for sc in scenarios))
        default = Path("media") / f"{names[0] if len(names) == 1 else 'sweep'}-tune.jsonl"
    out = _results_path(args.output, default)
    result = sweep(specs, out, workers=args.workers, scheduler=args.scheduler,
                   progress=False if args.no_progress else None, log=sys.stderr)
    print(f"swarmform tune: {result.computed} runs computed ({result.no_plan} without a plan, "
          f"{result.raised} raised), {result.skipped} were already in {out}")
    _report(out, paper_only=args.paper)
    if result.not_done:
        reasons = Counter(reason for _, reason in result.not_done)
        for reason, n in reasons.most_common(3):
            print(f"swarmform tune: {n} runs not done: {reason}", file=sys.stderr)
        print(f"swarmform tune: rerun the same command to compute the {len(result.not_done)} missing runs",
              file=sys.stderr)
        return 1
    return 0


def _cmd_summarize(args) -> int:
    extra = [name for name, given in (("SCENARIO", args.scenarios), ("--g", args.g), ("--q", args.q),
                                      ("--auto", args.auto), ("--paper", args.paper),
                                      ("--simulate", args.simulate), ("--scheduler", args.scheduler),
                                      ("--workers", args.workers is not None),
                                      ("--time-limit", args.time_limit is not None),
                                      ("--output", args.output)) if given]
    if extra:
        raise TuneError(f"--summarize: runs nothing, so {extra[0]} does not apply")
    path = Path(args.summarize)
    if not path.is_file():
        raise TuneError(f"{path}: no such results file")
    _report(path, paper_only=False)
    return 0


def _results_path(output: str | None, default: Path) -> Path:
    path = Path(output) if output else default
    if path.suffix in (".md", ".png"):
        raise TuneError(f"--output: {path}: the results file may not end in {path.suffix}; "
                        "the summary is written beside it with that suffix")
    return path


def _report(results_path: Path, *, paper_only: bool) -> None:
    """Write the summary files, print the Markdown (only the paper's tables for --paper)."""
    rows = read_results(results_path)
    if not rows:
        raise TuneError(f"{results_path}: holds no result rows")
    text, written = write_summary(results_path, rows)
    shown = paper_table(rows) if paper_only else None
    print()
    print(shown if shown else text.rstrip())
    print()
    for p in written:
        print(f"wrote {p}")
