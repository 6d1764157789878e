"""Watchdogs on the local pool: a hung, stopped or dead worker's run is a failed row; the rest complete.

The misbehaving runs are injected by replacing the planner in
``sim.tune.spec`` (the forked workers inherit the replacement): runs with
q = 40 hang or kill their own process, runs with q = 60 stop it (SIGSTOP).  Each sweep runs in a thread
with a deadline, so a missing watchdog fails the test instead of hanging it.
"""

from __future__ import annotations

import multiprocessing
import os
import signal
import threading
import time
from pathlib import Path

import pytest

import sim.tune.spec as tune_spec
from sim.cli import main
from sim.scenario import read_scenario
from sim.tune import (
    BUILD_ALLOWANCE_S,
    PHYSICS_ALLOWANCE_S,
    TIMEOUT,
    WORKER_DIED,
    grid,
    read_results,
    summarize,
    sweep,
    watchdog_s,
)

ROOT = Path(__file__).resolve().parents[2]
FIG2 = ROOT / "scenarios" / "paper" / "fig2-random-to-C.yaml"
LIMIT_S, ALLOWANCE_S = 1.0, 0.5  # watchdog 1.1 * 1 + 0.5 = 1.6 s


def _misbehave(monkeypatch, how: str) -> None:
    real = tune_spec.plan

    def plan(problem, params, rng):
        if params.q == 40 and how == "hang":
            time.sleep(3600)
        if params.q == 60 and how == "hang":
            os.kill(os.getpid(), signal.SIGSTOP)
        if params.q == 40 and how == "die":
            os.kill(os.getpid(), signal.SIGKILL)
        return real(problem, params, rng)

    monkeypatch.setattr(tune_spec, "plan", plan)


def _sweep_within(deadline_s: float, *args, **kwargs):
    out = {}

    def target():
        try:
            out["result"] = sweep(*args, **kwargs)
        except BaseException as exc:  # noqa: BLE001 - reported below
            out["error"] = exc

    thread = threading.Thread(target=target, daemon=True)
    thread.start()
    thread.join(deadline_s)
    assert not thread.is_alive(), f"the sweep did not finish within {deadline_s} s"
    if "error" in out:
        raise out["error"]
    return out["result"]


def _gone(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return True
    return Path(f"/proc/{pid}/stat").exists() and Path(f"/proc/{pid}/stat").read_text().split()[2] == "Z"


def test_watchdog_length():
    sc = read_scenario(FIG2)
    plain, physics = grid([sc], g=[1], q=[20], seeds=[0], time_limit=10) + \
        grid([sc], g=[1], q=[20], seeds=[0], time_limit=10, simulate=True)
    assert watchdog_s(plain) == pytest.approx(11 + BUILD_ALLOWANCE_S)
    assert watchdog_s(physics) == pytest.approx(11 + BUILD_ALLOWANCE_S + PHYSICS_ALLOWANCE_S)
    assert watchdog_s(physics, allowance=2) == pytest.approx(13)


def test_a_hung_or_stopped_run_is_a_timeout_row_and_the_rest_complete(tmp_path, monkeypatch):
    _misbehave(monkeypatch, "hang")
    path = tmp_path / "results.jsonl"
    specs = grid([read_scenario(FIG2)], g=[1], q=[20, 40, 60], seeds=[0, 1], time_limit=LIMIT_S)
    t0 = time.monotonic()
    result = _sweep_within(60, specs, path, workers=2, allowance=ALLOWANCE_S)
    wall = time.monotonic() - t0
    rows = read_results(path)
    assert len(rows) == 6 and result.complete and result.computed == 6
    late = [r for r in rows if r["q"] in (40, 60)]
    assert all(r["error_type"] == TIMEOUT and "1.6 s" in r["error"] and "killed" in r["error"] for r in late)
    assert all(r["found"] is False and r["wall_time_s"] >= 1.6 for r in late)
    assert all(r["found"] is True and r["error"] is None for r in rows if r["q"] == 20)
    assert result.timed_out == 4 and result.raised == 0 and result.workers_replaced >= 2
    # two workers, four stuck runs of 1.6 s each: at least two rounds, far less than a hang
    assert 3.2 <= wall < 45
    pids = {int(r["worker"].split(":")[1]) for r in late}
    assert os.getpid() not in pids and all(_gone(pid) for pid in pids)
    assert not multiprocessing.active_children()
    assert "error in 4 run(s): Timeout: no result within its watchdog of 1.6 s" in summarize(rows)


def test_a_run_that_kills_its_worker_is_a_worker_died_row(tmp_path, monkeypatch):
    _misbehave(monkeypatch, "die")
    path = tmp_path / "results.jsonl"
    specs = grid([read_scenario(FIG2)], g=[1], q=[20, 40], seeds=[0, 1], time_limit=LIMIT_S)
    result = _sweep_within(60, specs, path, workers=2, allowance=ALLOWANCE_S)
    rows = {(r["q"], r["seed"]): r for r in read_results(path)}
    assert len(rows) == 4 and result.worker_died == 2 and result.timed_out == 0
    for seed in (0, 1):
        dead = rows[(40, seed)]
        assert dead["error_type"] == WORKER_DIED and "SIGKILL" in dead["error"]
        assert rows[(20, seed)]["found"] is True
    assert not multiprocessing.active_children()


def test_the_command_line_reports_timeouts(tmp_path, monkeypatch, capsys):
    _misbehave(monkeypatch, "hang")
    path = tmp_path / "results.jsonl"
    code = main(["tune", str(FIG2), "--g", "1", "--q", "20", "40", "--seeds", "1", "--workers", "2",
                 "--time-limit", str(LIMIT_S), "--allowance", str(ALLOWANCE_S), "-o", str(path)])
    out, _ = capsys.readouterr()
    assert code == 0
    assert "2 runs computed (0 without a plan, 0 raised, 1 timed out, 0 lost with their worker)" in out
    assert "Timeout: no result within its watchdog" in path.with_suffix(".md").read_text()
    assert "Timeout" in path.with_suffix(".html").read_text()
