"""Routing with steps of two cells (planner.superflow): the pair rule derived from the
geometry, routings that are legal, exactly separated and shorter in time."""

from __future__ import annotations

import math

import numpy as np

from planner import Plan, check_plan
from planner.geometry import closest_approach
from planner.gridstage import build_grid, detect_grid, grid_plan, grid_waypoints, step_separated
from planner.profile import step_duration
from planner.superflow import MOVES, _heads, conflict_offsets, kinds_of, super_route

from .test_grid_stage import CELL, _cells_problem

RIGHT, UP, LEFT, WAIT, TWO_RIGHT = 0, 1, 2, 4, 5
SEP_C = 2.1 / CELL  # 0.875


def test_one_cell_rules_come_out_of_the_geometry():
    off = conflict_offsets(SEP_C)
    assert (-1, 0) in off[(RIGHT, LEFT)]  # a swap
    assert (-1, 0) in off[(RIGHT, UP)]  # entering a cell whose occupant leaves sideways
    assert (-1, 0) not in off[(RIGHT, RIGHT)]  # following straight on
    assert (-1, 0) not in conflict_offsets(0.7)[(RIGHT, UP)]  # coarse grid: turns are safe
    assert (-2, 0) not in off[(RIGHT, LEFT)]  # meeting on one vertex is the capacity's business


def test_two_cell_moves_may_not_pass_a_standing_robot_or_an_oncoming_one():
    off = conflict_offsets(SEP_C)
    assert (-1, 0) in off[(TWO_RIGHT, WAIT)]
    assert (-2, 0) in off[(TWO_RIGHT, LEFT)]  # they would cross
    assert (-3, 0) not in off[(TWO_RIGHT, LEFT)]  # they would meet on one vertex: capacity
    assert (-1, 1) not in off[(TWO_RIGHT, WAIT)]  # a row beside is 1 cell off


def test_offsets_match_the_exact_closest_approach():
    """Every pair of moves at every offset: listed exactly when the exact closest approach
    (planner.geometry) is below the separation and the moves do not end on one point."""
    off = conflict_offsets(SEP_C)
    for a in range(len(MOVES)):
        for b in range(len(MOVES)):
            listed = set(off[(a, b)])
            for x in range(-5, 6):
                for y in range(-5, 6):
                    pa, pb = np.array([[x, y]], float), np.zeros((1, 2))
                    qa, qb = pa + MOVES[a], pb + MOVES[b]
                    if (x, y) == (0, 0) or np.array_equal(qa, qb):
                        continue
                    close = float(closest_approach(pa * CELL, qa * CELL, pb * CELL, qb * CELL)[0]) < 2.1 - 1e-9
                    assert close == ((x, y) in listed), (a, b, x, y)


def _hall(m: int):
    """An open hall 14 x 8 cells, ``m`` robots packed on the left shifted 8 cells right."""
    blocked = np.zeros((8, 14), bool)
    cells = [(r, c) for c in range(5) for r in range(8)][:m]
    return _cells_problem(blocked, cells, [(r, c + 8) for r, c in cells])


def test_two_cell_routing_is_legal_separated_and_faster():
    p = _hall(40)
    lat, ij, vid = build_grid(p, *detect_grid(p))
    sv = np.array([vid[tuple(k)] for k in np.round((p.start - 0.5 * CELL) / CELL).astype(int)])
    gv = np.array([vid[tuple(k)] for k in np.round((p.target - 0.5 * CELL) / CELL).astype(int)])
    t1, t2 = (step_duration(d, p.max_speed, p.max_accel) for d in (CELL, 2 * CELL))
    beat = 8 * t1  # the shortest routing of single cells: eight steps
    kinds, where = super_route(lat, ij, vid, sv, gv, SEP_C, t1, t2, beat, math.inf, 30.0)
    assert sum(kinds) >= 8 and 2 in kinds
    assert sum(t1 if k == 1 else t2 for k in kinds) < beat
    heads = _heads(lat)
    prev = sv
    for k, cur in zip(kinds, where):
        assert len(np.unique(cur)) == len(cur)
        allowed = heads[:, : 9 if k == 2 else 5]
        assert all(b in allowed[a] for a, b in zip(prev, cur))
        assert step_separated(p, lat.points[prev], lat.points[cur], k * CELL * (1 + 1e-9))
        prev = cur
    assert sorted(where[-1]) == sorted(gv)


def test_the_exact_check_catches_a_two_cell_move_past_a_standing_robot():
    """Negative control: the move the pair rule forbids fails the exact check."""
    p = _cells_problem(np.zeros((3, 6), bool), [(1, 0), (1, 1)], [(1, 2), (1, 1)])
    a, b = p.start, p.target
    assert not step_separated(p, a, b, 2 * CELL * (1 + 1e-9))


def test_grid_plan_uses_two_cell_steps_and_checks():
    p = _hall(40)
    raw = grid_waypoints(p, math.inf)
    one = Plan.from_waypoints(np.asarray(raw), p.radius, p.margin, p.max_speed, p.max_accel).makespan
    w, _ = grid_plan(p, math.inf, rng=np.random.default_rng(0))
    plan = Plan.from_waypoints(np.asarray(w), p.radius, p.margin, p.max_speed, p.max_accel)
    check_plan(p, plan)
    steps = np.diff(np.asarray(w), axis=0)
    assert np.linalg.norm(steps, axis=2).max() > 1.5 * CELL  # some robot went two cells at once
    assert plan.makespan < one


def test_kinds_split_the_single_steps_between_the_ends():
    assert kinds_of(3, 2) == [1, 2, 2, 1, 1]
    assert kinds_of(0, 3) == [2, 2, 2]


def test_a_program_with_no_move_at_all_is_no_routing():
    """A robot one diagonal away from its target, to beat two one-cell steps: the only
    candidate, one step of two cells, has no move that gets there (every variable pruned),
    which is no routing rather than an error from the solver."""
    p = _cells_problem(np.zeros((3, 3), bool), [(1, 0)], [(0, 1)])
    lat, ij, vid = build_grid(p, *detect_grid(p))
    sv = np.array([vid[tuple(k)] for k in np.round((p.start - 0.5 * CELL) / CELL).astype(int)])
    gv = np.array([vid[tuple(k)] for k in np.round((p.target - 0.5 * CELL) / CELL).astype(int)])
    t1, t2 = (step_duration(d, p.max_speed, p.max_accel) for d in (CELL, 2 * CELL))
    assert super_route(lat, ij, vid, sv, gv, SEP_C, t1, t2, 2 * t1, math.inf, 10.0) is None
    assert super_route(lat, ij, vid, sv, gv, SEP_C, t1, t2, 2 * t1 + 1e-6 + t2, math.inf, 10.0) is not None
