"""Plan files with top-level keys this version does not read: the contract
(DESIGN.md, "other keys may follow; a reader ignores what it does not know")
says they are ignored; every command that reads a plan file says which on stderr."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from planner.plan import IGNORED_SHOWN, PlanFileError, note_ignored, read_plan_file

DATA = Path(__file__).resolve().parents[1] / "data"
ROOT = DATA.parents[1]


def test_extra_keys_are_ignored_and_named():
    base, base_extra = read_plan_file(DATA / "plan-base.json")
    plan, extra = read_plan_file(DATA / "plan-extra-key.json")
    assert "ignored" not in base_extra
    assert extra["ignored"] == ["colour", "producer"]
    assert extra["seed"] == base_extra["seed"] and extra["scenario"] == base_extra["scenario"]
    np.testing.assert_array_equal(plan.waypoints, base.waypoints)
    np.testing.assert_array_equal(plan.durations, base.durations)


def test_many_extra_keys_are_named_in_part(tmp_path, capsys):
    d = json.loads((DATA / "plan-base.json").read_text())
    d.update({f"k{i}": i for i in range(IGNORED_SHOWN + 5)})
    path = tmp_path / "many.json"
    path.write_text(json.dumps(d))
    _, extra = read_plan_file(path)
    assert extra["ignored"] == [f"k{i}" for i in range(IGNORED_SHOWN)] + ["and 5 more"]
    note_ignored(path, extra)
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "k0" in err and "and 5 more" in err


def test_known_keys_are_still_checked(tmp_path):
    """Ignoring unknown keys does not loosen the known ones (negative control)."""
    d = json.loads((DATA / "plan-extra-key.json").read_text())
    d["radius"] = "1"
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(d))
    with pytest.raises(PlanFileError, match="radius"):
        read_plan_file(path)


def test_export_reads_a_plan_with_extra_keys(tmp_path):
    out = tmp_path / "plan.csv"
    p = subprocess.run([sys.executable, "-m", "sim.cli", "export", str(DATA / "plan-extra-key.json"),
                        "--format", "csv", "-o", str(out)], cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert p.returncode == 0, p.stderr
    assert out.stat().st_size > 0
    notes = [line for line in p.stderr.splitlines() if line.startswith("note:")]
    assert len(notes) == 1 and "colour, producer" in notes[0]
