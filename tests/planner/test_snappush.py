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


# seeds 4 and 15: a robot starts in a pocket between desks whose only way out is a gap
# the robot barely fits, off every grid line (seed 15: a short way up, 0.44 right along a
# band 0.05 wide between two desks, then a vertex)
@pytest.mark.parametrize("seed", [4, 15])
def test_a_robot_in_a_pocket_snaps_through_corners(tmp_path, seed, monkeypatch):
    import time

    problem, lat = _office(tmp_path, seed)
    got = lattice.snap(problem, lat, problem.start, time.perf_counter() + 30)
    assert got is not None
    steps, vert = got
    assert len(np.unique(vert)) == problem.m
    w = np.asarray([problem.start, *steps])
    assert np.array_equal(w[-1], lat.points[vert])
    assert steps_clear(problem, w[:-1], w[1:]).all()
    # the negative control: without the way out of the pocket, the snapping fails
    monkeypatch.setattr(lattice, "pocket_corners", lambda *args: {})
    assert lattice.snap(problem, lat, problem.start, time.perf_counter() + 30) is None


def test_pocket_path_legs_are_clear_and_end_in_sight_of_a_vertex(tmp_path):
    from scipy.spatial import cKDTree

    from planner.snappush import pocket_path

    problem, lat = _office(tmp_path, 15)
    tree = cKDTree(lat.points)
    env, cl = problem.env, problem.clearance
    pocket = [r for r in range(problem.m)
              if not env.segments_clear(np.repeat(problem.start[[r]], 144, axis=0),
                                        lat.points[tree.query(problem.start[r], k=144)[1]], cl).any()]
    assert pocket
    for r in pocket:
        way = pocket_path(problem, lat, tree, problem.start[r], 8 * lat.spacing)
        assert way
        legs = np.asarray([problem.start[r], *way])
        assert env.segments_clear(legs[:-1], legs[1:], cl).all()
        near = lat.points[tree.query(way[-1], k=4)[1]]
        assert env.segments_clear(np.repeat(way[-1][None], 4, axis=0), near, cl).any()


def test_office_with_200_robots_plans(tmp_path):
    from planner import PlannerParams, plan

    problem, _ = _office(tmp_path, 1)
    result = plan(problem, PlannerParams(time_limit=30), np.random.default_rng(0))
    found = result[0] if isinstance(result, tuple) else result
    assert found.stats.extra.get("direct") == "grid"
