"""The planner end to end: every scenario, determinism, failure within the limits."""

import json
import os
import subprocess
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from planner import NoPlanFound, Plan, PlanFileError, PlannerParams, check_plan, plan
from planner.problem import Polygon, Problem
from sim.scenario import build_problem, read_scenario

ROOT = Path(__file__).resolve().parents[2]
SCENARIOS = sorted((ROOT / "scenarios").rglob("*.yaml"))
PYTHON = sys.executable


def _plan_scenario(path, seed=None, **overrides):
    sc = read_scenario(path)
    seed = sc.seed if seed is None else seed
    rng = np.random.default_rng(seed)
    problem = build_problem(sc, rng)
    params = replace(PlannerParams(), time_limit=30, **overrides)
    return problem, *plan(problem, params, rng)


@pytest.mark.parametrize("path", SCENARIOS, ids=lambda p: p.stem)
def test_every_scenario_plans_in_auto_mode(path):
    problem, result, stats = _plan_scenario(path)
    clearance = check_plan(problem, result)  # independent re-check
    assert clearance.value >= problem.margin
    assert stats.found and stats.min_clearance == pytest.approx(clearance.value)
    assert stats.steps == result.steps and stats.makespan_s == pytest.approx(result.makespan)


@pytest.mark.parametrize("name", ["fig1-line-to-phi", "fig5-N-to-A"])
def test_paper_parameters(name):
    path = ROOT / "scenarios" / "paper" / f"{name}.yaml"
    sc = read_scenario(path)
    rng = np.random.default_rng(sc.seed)
    problem = build_problem(sc, rng)
    result, stats = plan(problem, sc.planner, rng)
    check_plan(problem, result)
    assert (stats.g, stats.q) == (sc.planner.g, sc.planner.q)


_DETERMINISM = """
import sys, numpy as np
from planner import plan
from sim.scenario import read_scenario, build_problem
sc = read_scenario(sys.argv[1])
rng = np.random.default_rng(int(sys.argv[2]))
problem = build_problem(sc, rng)
result, stats = plan(problem, sc.planner, rng)
result.stats.planning_time_s = 0.0  # wall-clock time is the one thing that may differ
sys.stdout.write(result.to_json())
"""


@pytest.mark.parametrize("name", ["paper/fig1-line-to-phi", "paper/tableII-row12-random-to-N-m10"])
def test_same_seed_same_bytes(name):
    """Byte-identical plan JSON across processes and hash seeds."""
    path = str(ROOT / "scenarios" / f"{name}.yaml")
    outs = []
    for hashseed in ("0", "1", "0"):
        env = dict(os.environ, PYTHONHASHSEED=hashseed)
        r = subprocess.run([PYTHON, "-c", _DETERMINISM, path, "7"], capture_output=True, env=env, cwd=ROOT)
        assert r.returncode == 0, r.stderr.decode()
        outs.append(r.stdout)
    assert outs[0] == outs[1] == outs[2]
    other = subprocess.run([PYTHON, "-c", _DETERMINISM, path, "8"], capture_output=True, cwd=ROOT)
    assert other.stdout != outs[0]  # the seed matters


def _walled_in() -> Problem:
    """Robot 0 sits in a closed box of four obstacles; its target is outside."""
    box = (
        Polygon(np.array([[5, 5], [15, 5], [15, 6], [5, 6]])),
        Polygon(np.array([[5, 14], [15, 14], [15, 15], [5, 15]])),
        Polygon(np.array([[5, 6], [6, 6], [6, 14], [5, 14]])),
        Polygon(np.array([[14, 6], [15, 6], [15, 14], [14, 14]])),
    )
    start = np.array([[10.0, 10.0], [30.0, 30.0]])
    target = np.array([[30.0, 10.0], [25.0, 30.0]])
    return Problem(40, 40, box, 1.0, 0.1, start, target)


def test_impossible_problem_is_proven_at_once():
    problem = _walled_in()
    t0 = time.perf_counter()
    with pytest.raises(NoPlanFound) as info:
        plan(problem, PlannerParams(time_limit=30), np.random.default_rng(0))
    assert time.perf_counter() - t0 < 1.0
    assert str(info.value).startswith("no plan exists: the component around (10, 10) holds 1 start and 0 targets")
    assert info.value.stats.extra["feasible"] is False and info.value.stats.graphs == 0


def test_impossible_problem_ends_within_the_time_limit(monkeypatch):
    import planner.planning as planning

    monkeypatch.setattr(planning, "feasibility", lambda problem: None)  # the search alone
    problem = _walled_in()
    t0 = time.perf_counter()
    with pytest.raises(NoPlanFound) as info:
        plan(problem, PlannerParams(time_limit=1.5), np.random.default_rng(0))
    elapsed = time.perf_counter() - t0
    assert elapsed < 1.5 + 1.0
    assert info.value.stats.found is False
    assert info.value.stats.graphs > 0


def test_fixed_parameters_fail_fast_when_too_small(monkeypatch):
    import planner.planning as planning

    monkeypatch.setattr(planning, "feasibility", lambda problem: None)  # the search alone
    problem = _walled_in()
    with pytest.raises(NoPlanFound) as info:
        plan(problem, PlannerParams(g=1, q=5, time_limit=30), np.random.default_rng(0))
    assert (info.value.stats.g, info.value.stats.q) == (1, 5)


def test_plan_file_round_trip(tmp_path):
    problem, result, stats = _plan_scenario(ROOT / "scenarios" / "paper" / "fig2-random-to-C.yaml")
    path = result.save(tmp_path / "p.json", extra={"scenario": "x", "seed": 2})
    loaded = Plan.load(path)
    assert np.array_equal(loaded.waypoints, result.waypoints)
    assert np.array_equal(loaded.durations, result.durations)
    d = json.loads(path.read_text())
    for key in ("found", "planning_time_s", "g", "q", "graphs", "connections", "steps",
                "makespan_s", "path_length", "min_clearance"):
        assert key in d["stats"], key
    assert d["profile"] == "minimum_jerk" and d["scenario"] == "x"


@pytest.mark.parametrize(
    "content, field",
    [
        ("{", "line 1"),
        ('{"radius": 1, "margin": 0.1, "durations": [1], "waypoints": [[[0, 0]]]}', "durations"),
        ('{"radius": 1, "margin": 0.1, "durations": [], "waypoints": [[0, 0]]}', "waypoints"),
        ('{"radius": 1, "margin": 0.1, "durations": [-1], "waypoints": [[[0, 0]], [[1, 1]]]}', "durations[0]"),
        ('{"margin": 0.1, "durations": [], "waypoints": [[[0, 0]]]}', "radius"),
        ('{"radius": 1, "margin": 0.1, "profile": "cubic", "durations": [], "waypoints": [[[0, 0]]]}', "profile"),
    ],
)
def test_bad_plan_files(tmp_path, content, field):
    path = tmp_path / "bad.json"
    path.write_text(content)
    with pytest.raises(PlanFileError) as info:
        Plan.load(path)
    assert info.value.field == field


def test_cli_plan_exit_codes(tmp_path):
    exe = str(Path(PYTHON).parent / "swarmform")
    out = tmp_path / "plan.json"
    r = subprocess.run([exe, "plan", "scenarios/paper/fig5-N-to-A.yaml", "-o", str(out)],
                       capture_output=True, text=True, cwd=ROOT)
    assert r.returncode == 0, r.stderr
    assert "min clearance" in r.stdout and out.exists()
    assert Plan.load(out).stats.found

    scen = tmp_path / "walled.yaml"
    scen.write_text(
        "robots: {count: 2}\n"
        "obstacles:\n"
        "  - polygon: [[5, 5], [15, 5], [15, 6], [5, 6]]\n"
        "  - polygon: [[5, 14], [15, 14], [15, 15], [5, 15]]\n"
        "  - polygon: [[5, 6], [6, 6], [6, 14], [5, 14]]\n"
        "  - polygon: [[14, 6], [15, 6], [15, 14], [14, 14]]\n"
        "start: {points: [[10, 10], [30, 30]]}\n"
        "target: {points: [[30, 10], [25, 30]]}\n"
        "planner: {time_limit: 1}\n"
    )
    out2 = tmp_path / "none.json"
    r = subprocess.run([exe, "plan", str(scen), "-o", str(out2)], capture_output=True, text=True, cwd=ROOT)
    assert r.returncode == 1
    assert "found           no" in r.stdout and not out2.exists()

    r = subprocess.run([exe, "plan", str(tmp_path / "missing.yaml")], capture_output=True, text=True, cwd=ROOT)
    assert r.returncode == 2 and "missing.yaml" in r.stderr and "Traceback" not in r.stderr
