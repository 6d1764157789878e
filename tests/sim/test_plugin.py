"""The pytest plugin: the ``swarmform`` fixture, ``assert_run_ok``, and the README's example file."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from sim.pytest_plugin import assert_run_ok

ROOT = Path(__file__).resolve().parents[2]
EXAMPLE = ROOT / "docs" / "regression_example" / "test_my_scenarios.py"
FIG5 = ROOT / "scenarios" / "paper" / "fig5-N-to-A.yaml"


def _pytest(path: Path, cwd: Path):
    return subprocess.run([sys.executable, "-m", "pytest", str(path), "-q", "-p", "no:cacheprovider",
                           "-p", "no:randomly"], cwd=cwd, check=False, capture_output=True, text=True, timeout=600)


def test_the_example_file_passes_as_written():
    r = _pytest(EXAMPLE, ROOT)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "3 passed" in r.stdout


def test_the_negative_control_fails_when_inverted(tmp_path):
    """Without pytest.raises the colliding plan's test fails, with the verdict and the first contact."""
    text = EXAMPLE.read_text()
    guarded = '    with pytest.raises(AssertionError, match="contact"):\n        swarmform.assert_ok(report)\n'
    anchor = 'SCENARIOS = Path(__file__).resolve().parents[2] / "scenarios" / "paper"\n'
    assert guarded in text and anchor in text
    text = text.replace(guarded, "    swarmform.assert_ok(report)\n")
    text = text.replace(anchor, f"SCENARIOS = Path({str(ROOT / 'scenarios' / 'paper')!r})\n")
    inverted = tmp_path / "test_inverted.py"
    inverted.write_text(text)
    r = _pytest(inverted, tmp_path)
    assert r.returncode == 1, r.stdout + r.stderr
    assert "1 failed, 2 passed" in r.stdout
    assert "FAILED test_inverted.py::test_negative_control_a_colliding_plan_fails" in r.stdout
    assert "fig5-N-to-A: FAILED:" in r.stdout and "first contact: kind robot-" in r.stdout


def test_the_fixture_runs_in_tmp_path_without_video(swarmform, tmp_path):
    report = swarmform(str(FIG5))
    assert_run_ok(report)
    assert report["scenario"] == "fig5-N-to-A" and report["media"] == []
    assert (tmp_path / "swarmform" / "run1" / "fig5-N-to-A.json").is_file()
    assert not list(tmp_path.rglob("*.gif")) and not list(tmp_path.rglob("*.mp4"))
    assert swarmform.last.exit_code == 0


def _failed_report():
    return {"scenario": "x", "ok": False, "robots": 2, "margin": 0.1,
            "plan": {"found": True, "valid": True, "min_clearance": 0.3},
            "sim": {"contacts": 2, "reached": True, "first_contact":
                    {"time": 1.5, "kind": "robot-robot", "a": 0, "b": 1, "depth": 0.01, "witness": "pymunk"}}}


def test_assert_run_ok_says_the_verdict_and_the_first_contact():
    with pytest.raises(AssertionError) as info:
        assert_run_ok(_failed_report())
    msg = str(info.value)
    assert msg.startswith("x: FAILED: 2 contacts in the physics run, the first robots 0 and 1 at t = 1.5 s")
    assert "first contact: kind robot-robot, a 0, b 1, time 1.5, depth 0.01, witness pymunk" in msg


def test_assert_run_ok_fails_a_run_without_a_plan():
    with pytest.raises(AssertionError, match="no plan"):
        assert_run_ok({"scenario": "x", "ok": False, "plan": {"found": False, "error": "time limit"}, "sim": None})


def test_bad_input_raises_the_runs_own_error(swarmform, tmp_path):
    from sim.scenario import ScenarioError

    bad = tmp_path / "bad.yaml"
    bad.write_text("name: bad\nworkspace: [0, 10]\n")
    with pytest.raises(ScenarioError, match="bad.yaml: start: is required"):
        swarmform(bad)
