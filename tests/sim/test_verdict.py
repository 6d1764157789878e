"""Tests that pin the verdict: each fails if one link of "green means safe" is weakened.

* The run's validity verdict uses the margin: a plan whose exact clearance
  lies between 0 and the margin executes without contact, yet the run must
  fail (exit 1) because the plan is below the margin.
* Both contact witnesses see every wall: a robot driven into each of the
  four walls is reported as a robot-wall contact by pymunk and, separately,
  by the geometric monitor, when its disc reaches the wall line (a wall
  shifted outwards, in the world or in the monitor, is missed or late).
* Infinite numbers are refused where they would make a run unbounded or
  meaningless (``robots.max_speed``, ``workspace``), however they are spelt.
* Placements keep the margin: start and target robots closer than
  ``2 radius + margin`` to each other, or than ``radius + margin`` to a
  wall or an obstacle, are refused even when the discs do not touch.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from planner.plan import Plan, min_jerk
from planner.problem import Problem
from sim.execute.physics import execute
from sim.runner import run_scenario
from sim.scenario import ScenarioError, build_problem, read_scenario
from sim.scenario.params import SimParams

ROOT = Path(__file__).resolve().parents[2]
_SCRIPT = Path(sys.executable).with_name("swarmform")
SWARMFORM = [str(_SCRIPT)] if _SCRIPT.exists() else [sys.executable, "-m", "sim.cli"]


def _write(tmp_path: Path, text: str, name: str = "case.yaml") -> Path:
    path = tmp_path / name
    path.write_text(textwrap.dedent(text))
    return path


def _read_and_build(path: Path):
    scenario = read_scenario(path)
    return build_problem(scenario, np.random.default_rng(scenario.seed))


# ----------------------------------------------------------------------------
# the run's verdict needs the margin


def _passing_plan(tmp_path: Path, offset: float) -> tuple[Path, Path]:
    """Two robots swap ends on parallel lanes ``offset`` apart: they pass at the middle.

    Radius 1 and margin 0.1: the exact clearance is ``offset - 2`` at the
    moment they pass, and nowhere smaller.
    """
    scen = _write(tmp_path, f"""\
        name: passing
        workspace: [40, 40]
        robots: {{radius: 1.0, margin: 0.1}}
        start: {{points: [[5, 20], [35, {20 + offset}]]}}
        target: {{points: [[35, 20], [5, {20 + offset}]]}}
        sim: {{settle_time: 1}}
        """)
    w = np.array([[[5, 20], [35, 20 + offset]], [[35, 20], [5, 20 + offset]]], float)
    plan = Plan.from_waypoints(w, 1.0, 0.1, 2.0, 2.0)
    path = tmp_path / "passing-plan.json"
    path.write_text(plan.to_json({"seed": 0}))
    return scen, path


def test_a_plan_below_the_margin_fails_the_run_though_nothing_touches(tmp_path):
    scen, plan_path = _passing_plan(tmp_path, 2.05)  # gap 0.05: above 0, below the margin 0.1
    result = run_scenario(scen, plan_path=plan_path, out_dir=tmp_path / "out", render=False, out=None,
                          progress=False)
    report = result.report
    assert report["plan"]["min_clearance"] == pytest.approx(0.05, abs=1e-9)
    assert report["sim"]["contacts"] == 0 and report["sim"]["reached"]  # physics alone says fine
    assert report["plan"]["valid"] is False
    assert report["ok"] is False and result.exit_code == 1
    saved = json.loads((tmp_path / "out" / "passing.json").read_text())
    assert saved["ok"] is False and saved["plan"]["valid"] is False

    r = subprocess.run(SWARMFORM + ["run", str(scen), "--plan", str(plan_path), "--out", str(tmp_path / "cli"),
                                    "--no-render"], capture_output=True, text=True, cwd=ROOT)
    assert r.returncode == 1, r.stdout + r.stderr
    assert "closer than the margin" in r.stdout


def test_a_plan_at_the_margin_passes(tmp_path):
    """The positive control: the same swap with a gap of 0.2 is a green run."""
    scen, plan_path = _passing_plan(tmp_path, 2.2)
    result = run_scenario(scen, plan_path=plan_path, out_dir=tmp_path / "out", render=False, out=None,
                          progress=False)
    assert result.report["plan"]["min_clearance"] == pytest.approx(0.2, abs=1e-9)
    assert result.report["plan"]["valid"] is True
    assert result.exit_code == 0 and result.report["ok"] is True


# ----------------------------------------------------------------------------
# every wall, each witness


R = 0.5
WALLS = {
    # wall: (start, end on the wall line, the coordinate that reaches it)
    "left": ((5.0, 5.0), (0.0, 5.0)),
    "right": ((5.0, 5.0), (10.0, 5.0)),
    "bottom": ((5.0, 5.0), (5.0, 0.0)),
    "top": ((5.0, 5.0), (5.0, 10.0)),
}


def _time_at(plan: Plan, s: float) -> float:
    """Plan time at which the single step has covered the fraction ``s`` of its path."""
    lo, hi = 0.0, 1.0
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if min_jerk(mid)[0] < s else (lo, mid)
    return float(0.5 * (lo + hi) * plan.durations[0])


@pytest.mark.parametrize("wall", list(WALLS))
def test_each_witness_sees_each_wall(wall):
    """A robot driven onto a wall line: both witnesses report robot-wall when its disc reaches it."""
    a, b = WALLS[wall]
    w = np.array([[a], [b]], float)
    problem = Problem(10.0, 10.0, (), R, 0.1, w[0], w[0])
    plan = Plan.from_waypoints(w, R, 0.1, 2.0, 2.0)
    report = execute(problem, plan, SimParams(settle_time=0.5))
    touch = _time_at(plan, (5.0 - R) / 5.0)  # the disc reaches the wall line
    for witness in ("pymunk", "monitor"):
        hits = [c for c in report.contacts if c.witness == witness and c.kind == "robot-wall"]
        assert hits, f"{witness} missed the {wall} wall: {report.contacts}"
        assert (hits[0].a, hits[0].b) == (0, -1)
        assert hits[0].time == pytest.approx(touch, abs=0.05), (witness, hits[0].time, touch)
        assert hits[0].depth > 0.0
    assert not report.ok
    assert report.min_clearance < 0 and report.min_clearance_kind == "robot-wall"


def test_a_robot_near_each_wall_is_not_a_contact():
    """The negative control of the walls: 0.1 from every wall line, nothing is reported."""
    w = np.array([[[5.0, 5.0]], [[0.6, 0.6]], [[9.4, 0.6]], [[9.4, 9.4]], [[0.6, 9.4]]], float)
    problem = Problem(10.0, 10.0, (), R, 0.1, w[0], w[-1])
    plan = Plan.from_waypoints(w, R, 0.1, 2.0, 2.0)
    report = execute(problem, plan, SimParams(settle_time=0.5))
    assert report.contacts == ()
    assert report.min_clearance == pytest.approx(0.1, abs=report.max_tracking_error + 1e-6)


# ----------------------------------------------------------------------------
# infinite numbers


BASE = "start: {points: [[5, 5], [5, 15]]}\ntarget: {points: [[15, 5], [15, 15]]}\n"


@pytest.mark.parametrize("line, field", [
    ("robots: {max_speed: .inf}", "robots.max_speed"),
    ("robots: {max_speed: .Inf}", "robots.max_speed"),
    ("robots: {max_speed: 1.0e+400}", "robots.max_speed"),
    ("robots: {max_speed: -.inf}", "robots.max_speed"),
    ("robots: {max_accel: .inf}", "robots.max_accel"),
    ("robots: {max_speed: .nan}", "robots.max_speed"),
    ("workspace: [.inf, 40]", "workspace[0]"),
    ("workspace: [40, .inf]", "workspace[1]"),
    ("workspace: [40, 1.0e+400]", "workspace[1]"),
    ("workspace: [.nan, 40]", "workspace[0]"),
])
def test_infinite_limits_and_workspaces_are_refused(tmp_path, line, field):
    path = _write(tmp_path, line + "\n" + BASE)
    with pytest.raises(ScenarioError) as info:
        read_scenario(path)
    assert info.value.field == field
    assert "finite" in info.value.reason or "got inf" in info.value.reason or "got 1e" in info.value.reason


def test_the_largest_allowed_limits_and_workspace_are_accepted(tmp_path):
    path = _write(tmp_path, "workspace: [1000, 1000]\nrobots: {max_speed: 10, max_accel: 10000}\n" + BASE)
    s = read_scenario(path)
    assert (s.width, s.height, s.max_speed, s.max_accel) == (1000, 1000, 10, 10000)


# ----------------------------------------------------------------------------
# placements keep the margin, not just the discs apart


@pytest.mark.parametrize("key", ["start", "target"])
def test_robots_closer_than_the_separation_are_refused(tmp_path, key):
    """Centres 2.05 apart: the discs (radius 1) do not touch, but the margin 0.1 is not kept."""
    other = "target" if key == "start" else "start"
    path = _write(tmp_path, f"""\
        robots: {{radius: 1.0, margin: 0.1}}
        {key}: {{points: [[10, 10], [12.05, 10]]}}
        {other}: {{points: [[10, 20], [20, 20]]}}
        """)
    with pytest.raises(ScenarioError) as info:
        _read_and_build(path)
    assert info.value.field == f"{key}.points[0]"
    assert "2 * radius + margin = 2.1" in info.value.reason


def test_robots_at_the_separation_are_accepted(tmp_path):
    path = _write(tmp_path, """\
        robots: {radius: 1.0, margin: 0.1}
        start: {points: [[10, 10], [12.1, 10]]}
        target: {points: [[10, 20], [20, 20]]}
        """)
    problem = _read_and_build(path)
    assert np.linalg.norm(problem.start[0] - problem.start[1]) == pytest.approx(2.1)


@pytest.mark.parametrize("point, hits", [
    ([1.05, 20], "the wall"),  # 1.05 from the wall: the disc does not touch it
    ([20, 38.95], "the wall"),
    ([14.05, 20], "obstacle 0"),  # 1.05 from the square's side
])
def test_robots_closer_than_the_clearance_are_refused(tmp_path, point, hits):
    path = _write(tmp_path, f"""\
        robots: {{radius: 1.0, margin: 0.1}}
        obstacles:
          - polygon: [[15, 15], [25, 15], [25, 25], [15, 25]]
        start: {{points: [{point}, [30, 30]]}}
        target: {{points: [[5, 5], [30, 35]]}}
        """)
    with pytest.raises(ScenarioError) as info:
        _read_and_build(path)
    assert info.value.field == "start.points[0]"
    assert hits in info.value.reason and "radius + margin = 1.1" in info.value.reason


def test_robots_at_the_clearance_are_accepted(tmp_path):
    path = _write(tmp_path, """\
        robots: {radius: 1.0, margin: 0.1}
        obstacles:
          - polygon: [[15, 15], [25, 15], [25, 25], [15, 25]]
        start: {points: [[1.1, 20], [13.9, 20]]}
        target: {points: [[5, 5], [30, 35]]}
        """)
    problem = _read_and_build(path)
    assert problem.env.point_clearance(problem.start).min() == pytest.approx(1.1)
    assert math.isclose(problem.clearance, 1.1)
