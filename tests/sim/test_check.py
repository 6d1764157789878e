"""``swarmform check``: PASS/FAIL lines, exit codes, JUnit XML, baselines, wrong input."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

from planner import Plan
from sim.check import TOLERANCES, compare_reports, run_check
from sim.scenario import build_problem, read_scenario

ROOT = Path(__file__).resolve().parents[2]
PAPER = ROOT / "scenarios" / "paper"
GOOD = PAPER / "fig5-N-to-A.yaml"
BAD = PAPER / "fig2-random-to-C.yaml"  # run with the swap plan below: it collides
EXE = str(Path(sys.executable).parent / "swarmform")


def _swarmform(*args, cwd=ROOT):
    return subprocess.run([EXE, *map(str, args)], check=False, capture_output=True, text=True, cwd=cwd, timeout=300)


def _swap_plan(tmp_path: Path, scenario: bool = True) -> Path:
    """A plan for fig2 in which robots 0 and 1 swap places on straight lines: they meet halfway."""
    sc = read_scenario(BAD)
    problem = build_problem(sc, np.random.default_rng(sc.seed))
    mid = problem.start.copy()
    mid[[0, 1]] = problem.start[[1, 0]]
    plan = Plan.from_waypoints(np.array([problem.start, mid]), problem.radius, problem.margin, 2.0, 2.0)
    extra = {"seed": sc.seed, **({"scenario": sc.name} if scenario else {})}
    return plan.save(tmp_path / "swap.json", extra=extra)


@pytest.fixture
def folder(tmp_path):
    """A scenario folder: one good scenario, one that fails when given the swap plan."""
    d = tmp_path / "scen"
    d.mkdir()
    for f in (GOOD, BAD):
        shutil.copy(f, d / f.name)
    return d


def test_a_colliding_plan_is_one_junit_failure(folder, tmp_path):
    junit = tmp_path / "out" / "check.xml"
    r = _swarmform("check", folder, "--plan", _swap_plan(tmp_path), "--junit", junit)
    assert r.returncode == 1, r.stdout + r.stderr
    lines = r.stdout.splitlines()
    assert lines[0].startswith("fig2-random-to-C") and " FAIL " in lines[0] and "contact" in lines[0]
    assert lines[1].startswith("fig5-N-to-A") and " PASS " in lines[1]
    suite = ET.parse(junit).getroot().find("testsuite")
    assert suite.get("tests") == "2" and suite.get("failures") == "1"
    cases = {c.get("name"): c for c in suite.findall("testcase")}
    assert set(cases) == {"fig2-random-to-C", "fig5-N-to-A"}
    failures = suite.findall("testcase/failure")
    assert len(failures) == 1
    assert cases["fig2-random-to-C"].find("failure") is failures[0]
    assert cases["fig5-N-to-A"].find("failure") is None
    message = failures[0].get("message")
    assert message.startswith("FAILED:") and "contacts in the physics run" in message
    assert message in lines[0]  # the message is the verdict line printed


def test_all_pass_exit_0_and_junit_has_no_failure(tmp_path):
    junit = tmp_path / "check.xml"
    r = _swarmform("check", GOOD, "--junit", junit)
    assert r.returncode == 0, r.stdout + r.stderr
    assert " PASS " in r.stdout and "1 scenario: 1 passed, 0 failed" in r.stdout
    root = ET.parse(junit).getroot()
    assert root.findall(".//failure") == [] and len(root.findall(".//testcase")) == 1


def test_plan_without_scenario_key_needs_one_scenario(folder, tmp_path):
    plan = _swap_plan(tmp_path, scenario=False)
    r = _swarmform("check", folder, "--plan", plan)
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1
    assert "swap.json: scenario:" in r.stderr
    r = _swarmform("check", BAD, "--plan", plan)  # one scenario: the plan is its
    assert r.returncode == 1 and " FAIL " in r.stdout


def test_baseline_round_trip_and_a_change_named(tmp_path):
    base = tmp_path / "base"
    cases = run_check([GOOD], baseline=base, update=True, out=None)
    assert cases[0].ok and (base / "fig5-N-to-A.json").is_file()
    stored = json.loads((base / "fig5-N-to-A.json").read_text())
    assert "page" not in stored and stored["plan"]["makespan_s"] > 0
    assert [c.ok for c in run_check([GOOD], baseline=base, out=None)] == [True]
    # negative control: a makespan 10 % off in the baseline is a failure that names it
    old = stored["plan"]["makespan_s"]
    stored["plan"]["makespan_s"] = old * 1.10
    (base / "fig5-N-to-A.json").write_text(json.dumps(stored))
    r = _swarmform("check", GOOD, "--baseline", base)
    assert r.returncode == 1 and " FAIL " in r.stdout
    assert f"plan.makespan_s was {old * 1.10:.6g}, now {old:.6g}" in r.stdout


def test_missing_baseline_file_fails_the_case(tmp_path):
    (tmp_path / "base").mkdir()
    case, = run_check([GOOD], baseline=tmp_path / "base", out=None)
    assert not case.ok and "no baseline" in case.message and "--update-baseline" in case.message


def _report(**plan):
    p = {"makespan_s": 10.0, "path_length": 50.0, "min_clearance": 0.5}
    p.update(plan)
    return {"ok": True, "sim": {"contacts": 0}, "plan": p}


@pytest.mark.parametrize("change, field", [
    ({"makespan_s": 10.6}, "plan.makespan_s"),
    ({"makespan_s": 9.4}, "plan.makespan_s"),
    ({"path_length": 52.6}, "plan.path_length"),
    ({"min_clearance": 0.5012}, "plan.min_clearance"),
    ({"min_clearance": None}, "plan.min_clearance"),
])
def test_over_the_tolerance_is_a_difference(change, field):
    diff = compare_reports(_report(), _report(**change))
    assert len(diff) == 1 and diff[0].startswith(field + " was ")


def test_within_the_tolerances_is_no_difference():
    assert compare_reports(_report(), _report(makespan_s=10.49, path_length=47.6, min_clearance=0.5009)) == []
    assert TOLERANCES["plan.makespan_s"] == ("relative", 0.05)
    assert TOLERANCES["plan.min_clearance"] == ("absolute", 1e-3)


def test_verdict_and_contacts_must_be_equal():
    new = _report()
    new["ok"], new["sim"]["contacts"] = False, 3
    diff = compare_reports(_report(), new)
    assert diff == ["ok was true, now false", "sim.contacts was 0, now 3"]


@pytest.mark.parametrize("args, says", [
    (["check", "no-such.yaml"], "no-such.yaml: file: no such file"),
    (["check", "EMPTY"], "folder: holds no *.yaml"),
    (["check", GOOD, "--update-baseline"], "--update-baseline: needs --baseline"),
    (["check", GOOD, "--set", "robots.margin"], "must be KEY=VALUE"),
    (["check", GOOD, "--set", "robots.margin=-1"], "robots.margin"),
    (["check", GOOD, "--baseline", "BASE"], "fig5-N-to-A.json: line 1: is not JSON"),
    (["check", GOOD, GOOD], "is also the name of"),
    (["check", GOOD, "--seed", "-1"], "--seed"),
])
def test_wrong_input_is_one_line_exit_2(args, says, tmp_path):
    (tmp_path / "EMPTY").mkdir()
    (tmp_path / "BASE").mkdir()
    (tmp_path / "BASE" / "fig5-N-to-A.json").write_text("{not json")
    args = [str(tmp_path / a) if a in ("EMPTY", "BASE") else a for a in args]
    r = _swarmform(*args)
    assert r.returncode == 2, r.stdout + r.stderr
    assert len(r.stderr.strip().splitlines()) == 1 and says in r.stderr
    assert "PASS" not in r.stdout and "FAIL" not in r.stdout  # nothing ran


PROBE = """
import contextlib, io, json, sys
from sim.cli import main
with contextlib.redirect_stdout(io.StringIO()):
    try:
        main([{cmd!r}, "--help"])
    except SystemExit:
        pass
print(json.dumps(sorted(m for m in ("planner", "numpy", "pymunk", "pygame", "scipy") if m in sys.modules)))
"""


@pytest.mark.parametrize("cmd", ["check", "export"])
def test_help_of_the_new_commands_imports_nothing_heavy(cmd):
    r = subprocess.run([sys.executable, "-c", PROBE.format(cmd=cmd)], cwd=ROOT, check=False, capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout.strip().splitlines()[-1]) == []


def test_out_keeps_the_reports(tmp_path):
    case, = run_check([GOOD], out_dir=tmp_path / "reports", out=None)
    kept = json.loads((tmp_path / "reports" / "fig5-N-to-A.json").read_text())
    assert case.ok and kept["ok"] is True and kept["media"] == []
