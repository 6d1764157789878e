"""Tuning sweeps: the grid, resuming, interruptions, failures, determinism, summaries, bad input.

The sweeps use two fast scenarios (a paper figure and a Table II row, about
0.1 s a run at q = 20 or 40).  One module fixture runs the reference sweep,
2 scenarios x g {1, 2} x q {20, 40} x seeds {0, 1, 2} on 2 worker processes
through the command line; other tests compare against its rows.  The tests of
files refused by -o, watchdogs, robustness sweeps and Dask clusters are in
the test_tune_*.py files beside this one.
"""

from __future__ import annotations

import json
import multiprocessing
import os
import shutil
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

import sim.tune as tune
import sim.tune.spec as tune_spec
from planner import NoPlanFound, PlanStats
from sim.cli import main
from sim.scenario import read_scenario
from sim.tune import VOLATILE_FIELDS, grid, paper_table, read_results, summarize, sweep
from sim.tune.results import row_key

ROOT = Path(__file__).resolve().parents[2]
FIG2 = ROOT / "scenarios" / "paper" / "fig2-random-to-C.yaml"
ROW06 = ROOT / "scenarios" / "paper" / "tableII-row06-lambda-to-C-m7.yaml"
GRID = ["--g", "1", "2", "--q", "20", "40", "--seeds", "3"]

_SCRIPT = Path(sys.executable).with_name("swarmform")
SWARMFORM = [str(_SCRIPT)] if _SCRIPT.exists() else [sys.executable, "-m", "sim.cli"]


def _cli(argv, capsys) -> tuple[int, str, str]:
    """Run ``swarmform ARGV`` in this process: exit code, stdout, stderr."""
    try:
        code = main([str(a) for a in argv])
    except SystemExit as exc:  # argparse
        code = exc.code
    out, err = capsys.readouterr()
    return code, out, err


def _specs(seeds=range(3)):
    return grid([read_scenario(FIG2), read_scenario(ROW06)], g=[1, 2], q=[20, 40], seeds=seeds)


def _lines(path: Path) -> list[bytes]:
    return path.read_bytes().splitlines(keepends=True)


def _stable(rows) -> list[tuple]:
    """Rows without the wall-clock fields, in a fixed order."""
    return sorted(tuple(sorted((k, v) for k, v in r.items() if k not in VOLATILE_FIELDS)) for r in rows)


def _keys(rows) -> list[tuple]:
    return [row_key(r) for r in rows]


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """The sweep of the issue through the command line: 2 x 2 x 2 x 3 runs on 2 workers."""
    out = tmp_path_factory.mktemp("reference") / "results.jsonl"
    t0 = time.perf_counter()
    code = main(["tune", str(FIG2), str(ROW06), *GRID, "--workers", "2", "-o", str(out)])
    wall = time.perf_counter() - t0
    assert code == 0
    return {"path": out, "wall_s": wall, "bytes": out.read_bytes(), "md": out.with_suffix(".md").read_text()}


# ----------------------------------------------------------------------------
# the grid and resuming


def test_sweep_writes_one_row_per_run(reference):
    rows = read_results(reference["path"])
    assert len(rows) == 24
    assert len(set(_keys(rows))) == 24
    assert {(r["scenario"], r["g"], r["q"], r["seed"]) for r in rows} == {
        (s, g, q, seed) for s in ("fig2-random-to-C", "tableII-row06-lambda-to-C-m7")
        for g in (1, 2) for q in (20, 40) for seed in range(3)
    }
    for r in rows:
        assert r["mode"] == "fixed" and r["time_limit"] == 60.0 and r["simulate"] is False
        assert r["found"] is True and r["error"] is None
        assert (r["g_used"], r["q_used"]) == (r["g"], r["q"])
        assert r["planning_time_s"] > 0 and r["steps"] >= 1 and r["min_clearance"] >= 0.1 - 1e-9
    assert all(line.endswith(b"\n") for line in _lines(reference["path"]))
    folder = reference["path"].parent
    assert (folder / "results-fig2-random-to-C.png").stat().st_size > 1000
    assert (folder / "results-tableII-row06-lambda-to-C-m7.png").stat().st_size > 1000


def test_rerun_computes_nothing(reference, tmp_path, capsys):
    path = tmp_path / "results.jsonl"
    shutil.copy(reference["path"], path)
    result = sweep(_specs(), path, workers=2)
    assert (result.total, result.skipped, result.computed) == (24, 24, 0)
    assert path.read_bytes() == reference["bytes"]
    code, out, _ = _cli(["tune", FIG2, ROW06, *GRID, "--workers", "2", "-o", path], capsys)
    assert code == 0 and "0 runs computed" in out
    assert path.read_bytes() == reference["bytes"]


def test_more_seeds_computes_only_the_new_ones(reference, tmp_path):
    path = tmp_path / "results.jsonl"
    shutil.copy(reference["path"], path)
    result = sweep(_specs(range(4)), path, workers=1)
    assert (result.skipped, result.computed) == (24, 8)
    assert len(read_results(path)) == 32


def test_time_limit_and_physics_are_part_of_the_key(tmp_path):
    path = tmp_path / "results.jsonl"
    fig2 = [read_scenario(FIG2)]
    assert sweep(grid(fig2, g=[1], q=[20], seeds=[0]), path, workers=1).computed == 1
    assert sweep(grid(fig2, g=[1], q=[20], seeds=[0], time_limit=5), path, workers=1).computed == 1
    assert sweep(grid(fig2, g=[1], q=[20], seeds=[0], time_limit=5), path, workers=1).computed == 0
    result = sweep(grid(fig2, g=[1], q=[20], seeds=[0], simulate=True), path, workers=1)
    assert result.computed == 1
    row = read_results(path)[-1]
    assert row["simulate"] is True and row["sim_ok"] is True and row["sim_contacts"] == 0
    assert row["sim_reached"] is True and row["sim_min_clearance"] > 0


def test_default_settings_come_from_the_scenario_file(tmp_path):
    auto_file = tmp_path / "auto.yaml"
    auto_file.write_text(FIG2.read_text().replace("planner: {g: 3, q: 150}", "planner: {time_limit: 7}")
                         .replace("name: fig2-random-to-C", "name: fig2-auto"))
    specs = grid([read_scenario(FIG2), read_scenario(auto_file)], seeds=[0, 1])
    assert {(s.scenario.name, s.mode, s.g, s.q, s.time_limit) for s in specs} == {
        ("fig2-random-to-C", "fixed", 3, 150, 60.0), ("fig2-auto", "auto", None, None, 7.0)}
    specs = grid([read_scenario(FIG2)], g=[1, 2], auto=True, seeds=[0])
    assert [(s.mode, s.g, s.q) for s in specs] == [("fixed", 1, 150), ("fixed", 2, 150), ("auto", None, None)]
    with pytest.raises(tune.TuneError, match="planner.q: is auto"):
        grid([read_scenario(auto_file)], g=[1], seeds=[0])


def test_default_output_is_named_after_the_scenario(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    code, _, _ = _cli(["tune", FIG2, "--g", "1", "--q", "20", "--seeds", "1", "--workers", "1"], capsys)
    assert code == 0
    assert len(read_results(tmp_path / "media" / "fig2-random-to-C-tune.jsonl")) == 1
    assert (tmp_path / "media" / "fig2-random-to-C-tune.md").exists()


# ----------------------------------------------------------------------------
# interruptions and failures


def _alive_in_group(pgid: int) -> list[int]:
    """Processes of a process group that are still running (not zombies)."""
    alive = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[2]) == pgid and fields[0] != "Z":
            alive.append(int(stat.parent.name))
    return alive


def test_kill_midway_then_rerun_finishes(tmp_path, capsys):
    """kill -9 the sweep after a few rows; the rerun adds the rest: no duplicate, no broken line.

    Only the sweep's own process is killed: its workers must not keep the
    results file from the rerun, and must end by themselves.
    """
    path = tmp_path / "results.jsonl"
    argv = [*SWARMFORM, "tune", str(FIG2), str(ROW06), "--g", "1", "2", "--q", "20", "40",
            "--seeds", "4", "--workers", "2", "--no-progress", "-o", str(path)]
    proc = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    try:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline and proc.poll() is None:
            if path.exists() and path.read_bytes().count(b"\n") >= 3:
                break
            time.sleep(0.005)
        proc.kill()
        proc.wait()
        assert proc.returncode == -signal.SIGKILL, "the sweep ended before it could be killed"
        before = read_results(path)
        assert 3 <= len(before) < 32
        code, out, _ = _cli(argv[len(SWARMFORM):], capsys)  # the same command, at once, in this process
        assert code == 0 and f"{32 - len(before)} runs computed" in out
        rows = read_results(path)
        assert len(rows) == 32 and len(set(_keys(rows))) == 32
        lines = _lines(path)
        assert len(lines) == 32 and all(line.endswith(b"\n") and json.loads(line) for line in lines)
        assert rows[: len(before)] == before
        if Path("/proc/self/stat").exists():
            deadline = time.monotonic() + 10
            while _alive_in_group(proc.pid) and time.monotonic() < deadline:
                time.sleep(0.05)
            assert not _alive_in_group(proc.pid), "workers of the killed sweep are still running"
    finally:
        try:
            os.killpg(proc.pid, signal.SIGKILL)
        except (ProcessLookupError, PermissionError):
            pass


def test_ctrl_c_stops_at_once_and_keeps_every_row(tmp_path):
    path = tmp_path / "results.jsonl"
    # q large enough that the 32 runs take seconds: Ctrl-C must land mid-sweep
    # even on a loaded machine, where the poll below may see the rows late.
    argv = [*SWARMFORM, "tune", str(FIG2), str(ROW06), "--g", "1", "2", "--q", "200", "400",
            "--seeds", "4", "--workers", "2", "--no-progress", "-o", str(path)]
    proc = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline and proc.poll() is None:
            if path.exists() and path.read_bytes().count(b"\n") >= 3:
                break
            time.sleep(0.005)
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=20)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 130, err
    assert "interrupted" in err and "Traceback" not in err
    rows = read_results(path)
    assert 3 <= len(rows) < 32
    assert all(line.endswith(b"\n") and json.loads(line) for line in _lines(path))
    result = sweep(grid([read_scenario(FIG2), read_scenario(ROW06)], g=[1, 2], q=[200, 400], seeds=range(4)),
                   path, workers=2)
    assert result.computed == 32 - len(rows)
    assert len(set(_keys(read_results(path)))) == 32


def test_torn_last_line_is_cut_on_start(reference, tmp_path):
    path = tmp_path / "results.jsonl"
    good = _lines(reference["path"])[:5]
    path.write_bytes(b"".join(good) + good[5 - 1][:40])  # a row cut short by a hard kill
    assert len(read_results(path)) == 5
    log = tmp_path / "log.txt"
    with log.open("w") as stream:
        result = sweep(_specs(), path, workers=2, log=stream)
    assert "torn last line" in log.read_text()
    assert (result.skipped, result.computed) == (5, 19)
    lines = _lines(path)
    assert lines[:5] == good and len(lines) == 24
    assert all(line.endswith(b"\n") and json.loads(line) for line in lines)
    assert _stable(read_results(path)) == _stable(read_results(reference["path"]))


def test_a_results_file_with_lines_that_are_not_rows_is_refused(reference, tmp_path, capsys):
    """read_results skips lines that are not rows; a sweep refuses to append to such a file."""
    path = tmp_path / "results.jsonl"
    good = _lines(reference["path"])
    path.write_bytes(good[0] + b"not json\n" + b'{"scenario": 1}\n' + b"".join(good[1:]))
    before = path.read_bytes()
    assert len(read_results(path)) == 24
    with pytest.raises(tune.TuneError, match="line 2 is not a result row"):
        sweep(_specs(), path, workers=1)
    code, _, err = _cli(["tune", FIG2, ROW06, *GRID, "-o", path], capsys)
    assert code == 2 and len(err.splitlines()) == 1 and "not a results file" in err
    assert path.read_bytes() == before


def test_a_run_that_raises_is_a_failure_row(tmp_path, monkeypatch):
    real_plan = tune_spec.plan

    def flaky_plan(problem, params, rng):
        if params.q == 40:
            raise RuntimeError("boom\nsecond line")
        return real_plan(problem, params, rng)

    monkeypatch.setattr(tune_spec, "plan", flaky_plan)
    path = tmp_path / "results.jsonl"
    specs = grid([read_scenario(FIG2)], g=[1], q=[20, 40], seeds=[0, 1])
    result = sweep(specs, path, workers=1)
    assert (result.computed, result.raised, result.no_plan, result.complete) == (4, 2, 0, True)
    rows = {(r["q"], r["seed"]): r for r in read_results(path)}
    for seed in (0, 1):
        assert rows[(20, seed)]["found"] is True and rows[(20, seed)]["error"] is None
        bad = rows[(40, seed)]
        assert bad["found"] is False and bad["error_type"] == "RuntimeError" and bad["error"] == "boom second line"
    assert "error in 2 run(s): RuntimeError: boom second line" in summarize(read_results(path))


def test_a_scenario_that_fails_to_build_does_not_stop_the_sweep(tmp_path, capsys):
    broken = tmp_path / "too-big.yaml"
    broken.write_text("name: too-big\nworkspace: [20, 20]\nrobots: {count: 40}\n"
                      "start: {formation: line}\ntarget: {formation: random}\nplanner: {g: 1, q: 20}\n")
    path = tmp_path / "results.jsonl"
    code, out, _ = _cli(["tune", broken, FIG2, "--g", "1", "--q", "20", "--seeds", "2", "--workers", "2",
                         "-o", path], capsys)
    assert code == 0
    rows = read_results(path)
    assert len(rows) == 4
    failed = [r for r in rows if r["scenario"] == "too-big"]
    assert len(failed) == 2
    assert all(r["error_type"] == "ScenarioError" and "does not fit" in r["error"] for r in failed)
    assert all(r["found"] for r in rows if r["scenario"] == "fig2-random-to-C")
    assert "2 raised" in out


def test_no_plan_within_the_limits_is_recorded(tmp_path, monkeypatch):
    def no_plan(problem, params, rng):
        stats = PlanStats(planning_time_s=0.25, g=params.g, q=params.q, graphs=1, connections=0)
        raise NoPlanFound("start and target did not connect within 1 graphs", stats)

    monkeypatch.setattr(tune_spec, "plan", no_plan)
    path = tmp_path / "results.jsonl"
    result = sweep(grid([read_scenario(FIG2)], g=[1], q=[1], seeds=[1]), path, workers=1)
    row = read_results(path)[0]
    assert result.no_plan == 1 and result.raised == 0
    assert row["found"] is False and row["error_type"] == "NoPlanFound"
    assert row["error"] == "start and target did not connect within 1 graphs"
    assert (row["graphs"], row["connections"], row["planning_time_s"], row["steps"]) == (1, 0, 0.25, None)
    assert "| 1 | 1 | 1 | 0% (0/1) | - | - | 0 |" in summarize([row])


def test_a_killed_worker_is_replaced_and_the_rest_complete(tmp_path):
    """SIGKILL one pool worker mid-sweep: it is replaced, and every run gets one row.

    The run it held (if it held one) is a WorkerDied row naming the signal.
    """
    path = tmp_path / "results.jsonl"
    specs = grid([read_scenario(FIG2)], g=[1, 2], q=[20, 40], seeds=range(6))
    killed = []

    def kill_a_worker():
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:
            if path.exists() and path.read_bytes().count(b"\n") >= 2:
                workers = multiprocessing.active_children()
                if workers:
                    os.kill(workers[0].pid, signal.SIGKILL)
                    killed.append(workers[0].pid)
                    return
            time.sleep(0.002)

    killer = threading.Thread(target=kill_a_worker)
    killer.start()
    result = sweep(specs, path, workers=2)
    killer.join()
    assert killed and result.workers_replaced >= 1
    assert result.complete and result.computed == 24
    rows = read_results(path)
    assert len(rows) == 24 and len(set(_keys(rows))) == 24
    died = [r for r in rows if r["error_type"] == tune.WORKER_DIED]
    assert len(died) <= 1 and all("SIGKILL" in r["error"] for r in died)
    assert result.worker_died == len(died)
    assert sum(r["found"] for r in rows) == 24 - len(died)
    assert not multiprocessing.active_children()


# ----------------------------------------------------------------------------
# determinism


def test_one_worker_gives_the_rows_of_two(reference, tmp_path):
    path = tmp_path / "results.jsonl"
    assert sweep(_specs(), path, workers=1).computed == 24
    assert _stable(read_results(path)) == _stable(read_results(reference["path"]))


# ----------------------------------------------------------------------------
# summaries


def _row(scenario, mode, g, q, seed, found, t, **extra):
    return {"scenario": scenario, "scenario_file": f"{scenario}.yaml", "mode": mode, "g": g, "q": q,
            "seed": seed, "time_limit": 60.0, "simulate": False, "robots": 7, "start": "line", "target": "C",
            "paper_table": None, "paper_row": None, "paper_time_s": None, "paper_g": None, "paper_q": None,
            "found": found, "planning_time_s": t, "error_type": None if found else "NoPlanFound",
            "error": None if found else "no plan", **extra}


def test_summary_rates_percentiles_and_verdict():
    rows = [_row("s", "fixed", 1, 10, k, True, t) for k, t in enumerate([1.0, 2.0, 3.0, 4.0])]
    rows += [_row("s", "fixed", 2, 10, k, k < 2, 0.5) for k in range(4)]
    rows += [_row("s", "auto", None, None, k, True, 1.5) for k in range(4)]
    text = summarize(rows)
    assert "| 1 | 10 | 4 | 100% (4/4) | 2.500 | 3.700 | 0 |" in text
    assert "| 2 | 10 | 4 | 50% (2/4) | 0.500 | 0.500 | 0 |" in text
    assert "| auto | auto | 4 | 100% (4/4) | 1.500 | 1.500 | 0 |" in text
    assert "auto beats the best fixed setting on median time" in text
    assert "best fixed (g=1, q=10)" in text
    rows += [_row("s", "fixed", 3, 10, k, True, 0.1) for k in range(4)]
    assert "the best fixed setting beats auto on median time" in summarize(rows)
    rows = [r for r in rows if r["mode"] != "auto"] + [_row("s", "auto", None, None, k, k == 0, 0.1)
                                                       for k in range(4)]
    assert "the best fixed setting beats auto on success rate" in summarize(rows)


def test_paper_table_columns_and_ratio():
    paper = {"paper_table": "III", "paper_row": 2, "paper_time_s": 4.789, "paper_g": 3, "paper_q": 150}
    rows = [_row("t", "fixed", 3, 150, k, True, 0.5, **paper) for k in range(3)]
    rows += [_row("t", "auto", None, None, k, True, 0.25, **paper) for k in range(3)]
    text = paper_table(rows)
    assert "| table | row | m | start -> target | paper (g, q) | paper time [s] | fixed: success |" in text
    assert "| III | 2 | 7 | line -> C | (3, 150) | 4.789 | 100% (3/3) | 0.500 | 9.6 | 100% (3/3) | 0.250 | 19.2 |" \
        in text
    assert "hardware is unknown" in text
    assert paper_table([_row("s", "fixed", 1, 10, 0, True, 1.0)]) is None


def test_summarize_redraws_markdown_and_heatmaps(reference, tmp_path, capsys):
    path = tmp_path / "results.jsonl"
    shutil.copy(reference["path"], path)
    code, out, _ = _cli(["tune", "--summarize", path], capsys)
    assert code == 0
    md = path.with_suffix(".md").read_text()
    assert md == reference["md"].replace("results.jsonl", path.name)
    assert "### fig2-random-to-C" in md and "### tableII-row06-lambda-to-C-m7" in md
    assert "| 2 | 40 | 3 | 100% (3/3) |" in md
    for name in ("fig2-random-to-C", "tableII-row06-lambda-to-C-m7"):
        png = tmp_path / f"results-{name}.png"
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "### fig2-random-to-C" in out and "wrote" in out
    assert path.read_bytes() == reference["bytes"]  # nothing was run


def test_paper_mode_writes_the_comparison(tmp_path, capsys):
    path = tmp_path / "paper-tables.jsonl"
    code, out, _ = _cli(["tune", "--paper", ROW06, "--seeds", "2", "--workers", "1", "-o", path], capsys)
    assert code == 0
    rows = read_results(path)
    assert sorted((r["mode"], r["g"], r["q"], r["seed"]) for r in rows) == [
        ("auto", None, None, 0), ("auto", None, None, 1), ("fixed", 2, 500, 0), ("fixed", 2, 500, 1)]
    md = path.with_suffix(".md").read_text()
    line = next(x for x in md.splitlines() if x.startswith("| II | 6 |"))
    assert line.startswith("| II | 6 | 7 | lambda -> C | (2, 500) | 7.743 | 100% (2/2) |")
    assert "hardware is unknown" in md and "| II | 6 |" in out
    code, _, err = _cli(["tune", "--paper", FIG2, "--seeds", "1", "-o", tmp_path / "x.jsonl"], capsys)
    assert code == 2 and "paper: missing" in err


# ----------------------------------------------------------------------------
# bad input


@pytest.mark.parametrize(
    ("argv", "names"),
    [
        (["tune", "{d}/no-such.yaml"], "no-such.yaml"),
        (["tune", FIG2, "--g", "0"], "--g"),
        (["tune", FIG2, "--q", "many"], "--q"),
        (["tune", FIG2, "--seeds", "0"], "--seeds"),
        (["tune", FIG2, "--workers", "0"], "--workers"),
        (["tune", FIG2, "--time-limit", "-1"], "--time-limit"),
        (["tune", FIG2, "-o", "{d}/results.md"], "--output"),
        (["tune"], "SCENARIO"),
        (["tune", "--summarize", "{d}/none.jsonl"], "none.jsonl"),
        (["tune", "--summarize", "{d}/empty.jsonl"], "no result rows"),
        (["tune", FIG2, "--summarize", "{d}/empty.jsonl"], "SCENARIO"),
        (["tune", "--paper", "--g", "1"], "--paper"),
        (["tune", FIG2, FIG2.with_name("fig3-random-to-line.yaml"), "{d}/same-name.yaml", "--g", "1", "--q", "5"],
         "unique"),
    ],
)
def test_bad_input_exits_2_with_one_line(argv, names, tmp_path, capsys):
    (tmp_path / "empty.jsonl").write_text("")
    (tmp_path / "same-name.yaml").write_text(FIG2.read_text())
    code, _, err = _cli([str(a).replace("{d}", str(tmp_path)) for a in argv], capsys)
    assert code == 2
    assert len(err.splitlines()) == 1 and "Traceback" not in err
    assert names in err
    assert not list(tmp_path.glob("*.png")) and not (tmp_path / "results.md").exists()


def test_help_lists_the_options(capsys):
    code, out, _ = _cli(["tune", "--help"], capsys)
    assert code == 0
    for option in ("--g", "--q", "--auto", "--seeds", "--seed-start", "--workers", "--scheduler",
                   "--time-limit", "--simulate", "--paper", "--summarize", "--output"):
        assert option in out


def test_progress_bar_on_request_and_none_on_a_pipe(tmp_path):
    """tqdm draws the bar when asked (or on a terminal); a log that is not a terminal gets status lines only."""
    import io

    specs = grid([read_scenario(FIG2)], g=[1], q=[20], seeds=[0, 1])
    shown = io.StringIO()
    sweep(specs, tmp_path / "a.jsonl", workers=1, progress=True, log=shown)
    assert "tune: 100%" in shown.getvalue() and "2/2" in shown.getvalue()
    quiet = io.StringIO()
    sweep(specs, tmp_path / "b.jsonl", workers=1, log=quiet)
    assert quiet.getvalue().splitlines() == [f"swarmform tune: 2 runs to compute on 1 worker process, "
                                             f"0 already in {tmp_path / 'b.jsonl'}"]
