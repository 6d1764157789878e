"""Snapping a crowd onto a fine occupancy grid's uneven lines: settled robots make room
for the ones they fence in (planner.snappush), and a robot in a pocket between desks
reaches a line in two axis-aligned legs."""

from pathlib import Path

import numpy as np
import pytest

import planner.lattice as lattice
from planner import gridstage
from planner.steps import steps_clear
from sim.scenario import build_legs, read_scenario

OFFICE = Path(__file__).resolve().parents[2] / "scenarios" / "maps" / "office-map.yml"


def _office(tmp_path, seed: int):
    path = tmp_path / "office-200.yaml"
    path.write_text(f"seed: {seed}\nmap: {{file: {OFFICE}}}\n"
                    "robots: {count: 200, radius: 0.2, margin: 0.05}\n"
                    "start: {formation: scatter, region: [0.3, 0.3, 19.7, 6.0]}\n"
                    "target: {formation: scatter, region: [0.3, 9.0, 19.7, 14.7]}\n")
    scenario = read_scenario(path)
    problem, _ = build_legs(scenario, scenario.generator(scenario.seed))
    grid, snapped = gridstage.find_grid(problem)
    assert snapped
    lat, _, _ = gridstage.build_grid(problem, grid)
    return problem, lat


# seeds 0 to 2: the last robots are fenced in by settled ones (seed 1: one in a pocket between desks)
@pytest.mark.parametrize("seed, side", [(0, "start"), (1, "start"), (2, "start")])
def test_crowded_snapping_succeeds_and_every_round_is_exact(tmp_path, seed, side, monkeypatch):
    import time

    problem, lat = _office(tmp_path, seed)
    placement = problem.target if side == "target" else problem.start
    got = lattice.snap(problem, lat, placement, time.perf_counter() + 30)
    assert got is not None
    steps, vert = got
    assert len(np.unique(vert)) == problem.m
    w = np.asarray([placement, *steps])
    assert np.array_equal(w[-1], lat.points[vert])
    assert steps_clear(problem, w[:-1], w[1:]).all()
    # the negative control: without the push, the same snapping gets stuck
    monkeypatch.setattr(lattice, "push", lambda *args: None)
    assert lattice.snap(problem, lat, placement, time.perf_counter() + 30) is None


def test_office_with_200_robots_plans(tmp_path):
    from planner import PlannerParams, plan

    problem, _ = _office(tmp_path, 1)
    result = plan(problem, PlannerParams(time_limit=30), np.random.default_rng(0))
    found = result[0] if isinstance(result, tuple) else result
    assert found.stats.extra.get("direct") == "grid"
