"""The time limit covers the whole run: what reading the scenario, its map and its
formations took is taken off the planner's limit (``Scenario.planner_params``)."""

import json
import time
from pathlib import Path

import pytest

import sim.execute.legs as legs
import sim.scenario.maps as maps
from sim.cli import main

ROS = Path(__file__).resolve().parents[2] / "scenarios" / "maps" / "two-rooms-ros.yaml"
SCEN = Path(__file__).resolve().parents[2] / "scenarios" / "maps" / "warehouse-10-20-10-2-1-20.yaml"  # no scatter


@pytest.fixture
def limits(monkeypatch):
    """The time limits the planner was called with."""
    seen = []
    real = legs.plan

    def spy(problem, params, rng):
        seen.append(params.time_limit)
        return real(problem, params, rng)

    monkeypatch.setattr(legs, "plan", spy)
    return seen


def _slow_map(monkeypatch, delay):
    real = maps.read_grid

    def slow(path, threshold=None):
        time.sleep(delay)
        return real(path, threshold)

    monkeypatch.setattr(maps, "read_grid", slow)


@pytest.mark.parametrize("command", ["plan", "run"])
def test_map_reading_is_taken_off_the_planners_limit(command, limits, monkeypatch, tmp_path, capsys):
    _slow_map(monkeypatch, 0.5)
    out = ["-o", str(tmp_path / "p.json")] if command == "plan" else ["--out", str(tmp_path), "--no-render"]
    assert main([command, str(ROS), "--time-limit", "2", *out]) == 0
    assert len(limits) == 1 and 1.0 < limits[0] <= 1.5


def test_fast_reading_leaves_the_limit_and_a_slow_one_a_twentieth(limits, monkeypatch, tmp_path, capsys):
    """The control: a quick read leaves nearly all of the limit; a read longer than the
    limit leaves the planner a twentieth of it."""
    assert main(["plan", str(ROS), "--time-limit", "2", "-o", str(tmp_path / "a.json")]) == 0
    assert limits[-1] > 1.8
    _slow_map(monkeypatch, 1.0)
    main(["plan", str(SCEN), "--time-limit", "0.5", "-o", str(tmp_path / "b.json")])
    assert limits[-1] == pytest.approx(0.025)


@pytest.mark.parametrize("command", ["plan", "run"])
def test_a_scatter_past_the_limit_ends_the_run_with_no_plan(command, limits, monkeypatch, tmp_path, capsys):
    """Placing the robots counts too: a scatter still drawing when the limit has run out
    stops; exit 1, no plan file, and ``run`` writes a report that says why (the control
    above: with the limit left, the same scenario plans)."""
    _slow_map(monkeypatch, 1.0)
    out = ["-o", str(tmp_path / "p.json")] if command == "plan" else ["--out", str(tmp_path), "--no-render"]
    assert main([command, str(ROS), "--time-limit", "0.5", *out]) == 1
    said = capsys.readouterr()
    assert "ran out while the robots were being placed" in said.out + said.err
    assert limits == [] and not (tmp_path / "p.json").exists()
    if command == "run":
        report = json.loads((tmp_path / "two-rooms-ros.json").read_text())
        assert report["ok"] is False and "being placed" in report["plan"]["error"]
