"""Sweeps on a Dask cluster: the cluster computes the rows, watchdogs, and one-line failures.

Named to run after the other sweep tests: a Dask cluster leaves threads
behind in this process, and the local pools fork.  Every row names the Dask
worker that computed it, and the tests check those names against the
cluster's workers, so a sweep that quietly ran on the local pool (its rows
say ``local:PID``) fails them.
"""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

import sim.tune.cluster as tune_cluster
import sim.tune.spec as tune_spec
from sim.cli import main
from sim.scenario import read_scenario
from sim.tune import TIMEOUT, VOLATILE_FIELDS, grid, read_results, run_one, sweep

distributed = pytest.importorskip("distributed")

ROOT = Path(__file__).resolve().parents[2]
FIG2 = ROOT / "scenarios" / "paper" / "fig2-random-to-C.yaml"
DASK = Path(sys.executable).with_name("dask")


def _cli(argv, capsys) -> tuple[int, str, str]:
    try:
        code = main([str(a) for a in argv])
    except SystemExit as exc:
        code = exc.code
    out, err = capsys.readouterr()
    return code, out, err


def _stable(rows) -> list[tuple]:
    return sorted(tuple(sorted((k, repr(v)) for k, v in r.items() if k not in VOLATILE_FIELDS)) for r in rows)


def _specs(**kw):
    return grid([read_scenario(FIG2)], g=[1, 2], q=[20], seeds=[0, 1], **kw)


def test_unreachable_scheduler_is_one_line_and_exit_2(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(tune_cluster, "_CONNECT_TIMEOUT_S", 0.5)
    path = tmp_path / "results.jsonl"
    code, _, err = _cli(["tune", FIG2, "--seeds", "1", "--scheduler", "tcp://127.0.0.1:9", "-o", path], capsys)
    assert code == 2 and err.startswith("swarmform: error: --scheduler: cannot connect to tcp://127.0.0.1:9")
    assert len(err.splitlines()) == 1 and "Traceback" not in err
    assert not path.exists()


def test_the_cluster_computes_the_rows_of_the_local_process(tmp_path):
    specs = _specs()
    here = [run_one(s) for s in specs]
    path = tmp_path / "results.jsonl"
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=False,
                                  dashboard_address=None) as cluster:
        workers = set(cluster.scheduler_info["workers"])
        result = sweep(specs, path, scheduler=cluster.scheduler_address)
    rows = read_results(path)
    assert result.computed == 4 and result.complete
    assert _stable(rows) == _stable(here)
    assert {r["worker"] for r in rows} <= workers and all(r["worker"] for r in rows)
    assert not any(r["worker"].startswith("local:") for r in rows)


def test_a_hung_run_on_the_cluster_is_a_timeout_and_the_rest_complete(tmp_path, monkeypatch):
    """The first run with g = 2 hangs (the cluster's workers are threads of this process here,
    so the replaced planner reaches them); its worker gets no further run."""
    release, calls = threading.Event(), []
    real = tune_spec.plan

    def plan(problem, params, rng):
        if params.g == 2:
            calls.append(1)
            if len(calls) == 1:
                release.wait(600)
        return real(problem, params, rng)

    monkeypatch.setattr(tune_spec, "plan", plan)
    specs = grid([read_scenario(FIG2)], g=[1, 2], q=[20], seeds=[0, 1, 2], time_limit=1.0)
    path = tmp_path / "results.jsonl"
    guard = threading.Timer(30, release.set)  # without a watchdog the sweep would wait for this
    guard.start()
    try:
        with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=False,
                                      dashboard_address=None) as cluster:
            workers = set(cluster.scheduler_info["workers"])
            t0 = time.monotonic()
            result = sweep(specs, path, scheduler=cluster.scheduler_address, allowance=0.5)
            wall = time.monotonic() - t0
            release.set()
    finally:
        release.set()
        guard.cancel()
    rows = read_results(path)
    assert len(rows) == 6 and result.complete and wall < 30
    (hung,) = [r for r in rows if r["error_type"] is not None]
    assert hung["error_type"] == TIMEOUT and (hung["g"], hung["seed"]) == (2, 0) and hung["worker"] in workers
    assert "1.6 s" in hung["error"] and hung["worker"] in hung["error"]
    others = [r for r in rows if r is not hung]
    assert all(r["found"] and r["worker"] in workers - {hung["worker"]} for r in others)
    assert (result.timed_out, result.computed) == (1, 6)


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture(scope="module")
def processes():
    """A scheduler and two one-thread workers, each in its own process (the ``dask`` command)."""
    if not DASK.exists():
        pytest.skip("the dask command is not installed beside this Python")
    address = f"tcp://127.0.0.1:{_free_port()}"
    quiet = {"stdout": subprocess.DEVNULL, "stderr": subprocess.DEVNULL}
    scheduler = subprocess.Popen([str(DASK), "scheduler", "--host", "127.0.0.1", "--port",
                                  address.rsplit(":", 1)[1], "--no-dashboard"], **quiet)
    workers = [subprocess.Popen([str(DASK), "worker", address, "--nthreads", "1", "--no-nanny", "--no-dashboard"],
                                **quiet) for _ in range(2)]
    try:
        with distributed.Client(address, timeout=60) as client:
            client.wait_for_workers(2, timeout=60)
            client.run(__import__, "sim.tune")  # imports done before any watchdog starts
            pids = client.run(os.getpid)
        yield {"address": address, "scheduler": scheduler, "pids": pids}
    finally:
        for p in (scheduler, *workers):
            p.kill()
            p.wait()


def test_a_stopped_worker_does_not_hang_the_sweep(processes, tmp_path):
    """SIGSTOP one of two worker processes: its run is a Timeout row; the other worker does the rest."""
    specs = grid([read_scenario(FIG2)], g=[1], q=[20, 40], seeds=[0, 1, 2], time_limit=1.0)
    path = tmp_path / "results.jsonl"
    pids = processes["pids"]
    stopped, running = sorted(pids)
    os.kill(pids[stopped], signal.SIGSTOP)
    try:
        t0 = time.monotonic()
        result = sweep(specs, path, scheduler=processes["address"], allowance=2.0)
        wall = time.monotonic() - t0
    finally:
        os.kill(pids[stopped], signal.SIGCONT)
    rows = read_results(path)
    assert len(rows) == 6 and result.complete and wall < 40
    late = [r for r in rows if r["error_type"] == TIMEOUT]
    assert len(late) == 1 and late[0]["worker"] == stopped and stopped in late[0]["error"]
    assert all(r["found"] and r["worker"] == running for r in rows if r["error_type"] is None)
    assert os.getpid() not in pids.values()


def test_a_scheduler_lost_mid_sweep_is_one_line_and_exit_4(processes, tmp_path, capsys):
    """The scheduler process is killed after the first rows (this test ends the module's cluster)."""
    scheduler, address = processes["scheduler"], processes["address"]
    path = tmp_path / "results.jsonl"

    def kill_when_rows_arrive():
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline:
            if path.exists() and path.read_bytes().count(b"\n") >= 2:
                scheduler.kill()
                return
            time.sleep(0.01)

    killer = threading.Thread(target=kill_when_rows_arrive, daemon=True)
    killer.start()
    code, _, err = _cli(["tune", FIG2, "--g", "1", "--q", "100", "200", "--seeds", "20", "--scheduler", address,
                         "--no-progress", "-o", path], capsys)
    killer.join(5)
    assert scheduler.poll() == -signal.SIGKILL, "the sweep ended before the scheduler was killed"
    lines = [line for line in err.splitlines() if not line.startswith("swarmform tune: 40 runs to compute")]
    assert code == 4, err
    assert len(lines) == 1 and "Traceback" not in err
    assert lines[0].startswith("swarmform tune: error: --scheduler: lost the Dask scheduler at " + address)
    assert "rerun the same command" in lines[0]
    rows = read_results(path)
    assert 2 <= len(rows) < 40 and all(r["worker"] in processes["pids"] for r in rows)
    assert path.read_bytes().endswith(b"\n")
