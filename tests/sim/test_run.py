"""End to end: plan, validate, execute in pymunk, render; and plans built to collide."""

import json
import subprocess
import sys
from pathlib import Path

import imageio.v3 as iio
import numpy as np
import pytest

from planner import Plan
from sim.runner import run_scenario
from sim.scenario import build_problem, read_scenario

ROOT = Path(__file__).resolve().parents[2]
ALL = sorted((ROOT / "scenarios").rglob("*.yaml"))
FAST = [ROOT / "scenarios" / p for p in (
    "paper/fig2-random-to-C.yaml",
    "paper/fig5-N-to-A.yaml",
    "letters/line-to-lambda.yaml",
    "harder/narrow-gap-2.3.yaml",
)]
EXE = str(Path(sys.executable).parent / "swarmform")


def _check_ok(result):
    sim = result.report["sim"]
    assert result.exit_code == 0, result.report
    assert sim["contacts"] == 0
    assert sim["reached"] is True
    assert result.report["plan"]["valid"] is True
    assert result.report["plan"]["min_clearance"] >= 0.1 - 1e-9
    # the physics keeps (nearly) the planned clearance: tracking error is tiny
    assert sim["min_clearance"] >= result.report["plan"]["min_clearance"] - 2 * sim["max_tracking_error"] - 1e-6


@pytest.mark.parametrize("path", FAST, ids=lambda p: p.stem)
def test_fast_scenarios_run_clean(path, tmp_path):
    _check_ok(run_scenario(path, out_dir=tmp_path, render=False, out=None))


@pytest.mark.slow
@pytest.mark.parametrize("path", ALL, ids=lambda p: p.stem)
def test_every_scenario_runs_clean(path, tmp_path):
    _check_ok(run_scenario(path, out_dir=tmp_path, render=False, out=None))


def test_main_job_writes_report_and_gif(tmp_path):
    """What the README's main command does, for the Fig. 1 scenario."""
    r = subprocess.run([EXE, "run", "scenarios/paper/fig1-line-to-phi.yaml", "--out", str(tmp_path)],
                       capture_output=True, text=True, cwd=ROOT)
    assert r.returncode == 0, r.stdout + r.stderr
    report = json.loads((tmp_path / "fig1-line-to-phi.json").read_text())
    assert report["sim"]["contacts"] == 0 and report["sim"]["reached"]
    for key in ("found", "planning_time_s", "g", "q", "makespan_s", "path_length", "min_clearance"):
        assert key in report["plan"]
    for key in ("contacts", "min_clearance", "max_tracking_error", "reached", "sim_time_s", "wall_time_s"):
        assert key in report["sim"]
    gif = tmp_path / "fig1-line-to-phi.gif"
    assert str(gif) in report["media"]
    frames = iio.imread(gif, index=None)
    assert frames.shape[0] > 50 and frames.shape[1] % 2 == 0 and frames.shape[2] % 2 == 0
    assert not np.array_equal(frames[0], frames[-1])  # the robots moved


def _bad_plan(tmp_path, kind: str) -> tuple[Path, Path]:
    """A plan for fig2 that collides: two robots swap places, or one crosses an obstacle."""
    scen = ROOT / "scenarios" / "paper" / "fig2-random-to-C.yaml"
    sc = read_scenario(scen)
    problem = build_problem(sc, np.random.default_rng(sc.seed))
    start = problem.start
    if kind == "swap":
        mid = start.copy()
        mid[[0, 1]] = start[[1, 0]]  # straight swap: they meet halfway
        w = [start, mid]
    else:
        ob = problem.obstacles[0].vertices  # a robot driven through obstacle 0 and back
        c = ob.mean(axis=0)
        mid = start.copy()
        mid[0] = c
        w = [start, mid, start]
    plan = Plan.from_waypoints(np.array(w), problem.radius, problem.margin, 2.0, 2.0)
    path = tmp_path / f"{kind}.json"
    plan.save(path, extra={"seed": sc.seed})
    return scen, path


@pytest.mark.parametrize("kind", ["swap", "obstacle"])
def test_plan_built_to_collide_is_caught(kind, tmp_path):
    """Negative control: the contact witnesses see the collision and the run fails."""
    scen, plan_path = _bad_plan(tmp_path, kind)
    r = subprocess.run([EXE, "run", str(scen), "--plan", str(plan_path), "--no-render", "--out", str(tmp_path)],
                       capture_output=True, text=True, cwd=ROOT)
    assert r.returncode == 1, r.stdout + r.stderr
    report = json.loads((tmp_path / "fig2-random-to-C.json").read_text())
    assert report["sim"]["contacts"] > 0
    assert report["plan"]["valid"] is False
    kinds = {c["kind"] for c in report["sim"]["contact_list"]}
    assert ("robot-robot" if kind == "swap" else "robot-obstacle") in kinds


def test_plan_for_another_problem_is_bad_input(tmp_path):
    scen, plan_path = _bad_plan(tmp_path, "swap")
    r = subprocess.run([EXE, "run", str(scen), "--plan", str(plan_path), "--seed", "7", "--no-render",
                        "--out", str(tmp_path)], capture_output=True, text=True, cwd=ROOT)
    assert r.returncode == 2
    assert len(r.stderr.strip().splitlines()) == 1 and "waypoints[0]" in r.stderr
    assert not (tmp_path / "fig2-random-to-C.json").exists()  # nothing half-done written
