"""Chained targets: one plan through every target, one physics run, one video.

The chained plan must start at the start, be on each target (as a set: the
problem is unlabeled) when its leg ends, rest there for the leg's hold
with nobody moving, pass the exact validator as a whole, and run in
physics with zero contacts.  A single target is exactly what
``planner.plan`` returns.  A leg that cannot be planned is named.  The
video marks the current leg's target.  Negative controls: a chain whose
legs are joined wrongly, or whose robots swap through each other, is
caught by the same checks.
"""

from __future__ import annotations

import json
import textwrap
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from planner import NoPlanFound, Plan, PlannerParams, check_plan, plan
from planner.validate import PlanInvalid
from sim.execute.legs import plan_legs
from sim.output.render import TARGET_MARK, Canvas, render_frames
from sim.runner import run_scenario
from sim.scenario import build_legs, read_scenario
from sim.scenario.params import RenderParams

ROOT = Path(__file__).resolve().parents[2]

_CHAIN = """\
    name: chain
    workspace: [40, 40]
    robots: {count: 10, max_speed: 4.0, max_accel: 4.0}
    obstacles: [{polygon: [[17, 17], [23, 17], [23, 23], [17, 23]]}]
    start: {formation: line, rotation: 0, center: [20, 6]}
    targets:
      - {formation: ring, scale: 0.55, center: [20, 20]}
      - {formation: scatter, hold: 1.5}
      - {formation: A, rotation: 0, center: [20, 31], hold: 0}
    render: {size: 160, fps: 5, formats: [gif], speedup: 10}
"""


def _same_set(a, b, tol=1e-6):
    from scipy.optimize import linear_sum_assignment

    cost = np.linalg.norm(a[:, None] - b[None], axis=2)
    r, c = linear_sum_assignment(cost)
    return bool(cost[r, c].max() <= tol)


@pytest.fixture(scope="module")
def chain(tmp_path_factory):
    path = tmp_path_factory.mktemp("chain") / "chain.yaml"
    path.write_text(textwrap.dedent(_CHAIN), encoding="utf-8")
    sc = read_scenario(path)
    rng = np.random.default_rng(sc.seed)
    problem, targets = build_legs(sc, rng)
    result, stats, times = plan_legs(problem, targets, sc.planner, rng, holds=[t.hold for t in sc.legs],
                                     labels=[t.describe() for t in sc.legs])
    return path, sc, problem, targets, result, stats, times


def test_chain_visits_every_target_in_turn(chain):
    _, sc, problem, targets, result, stats, times = chain
    assert len(times) == 4 and times[0] == 0.0 and times[-1] == pytest.approx(result.makespan)
    np.testing.assert_array_equal(result.start, problem.start)
    for k, target in enumerate(targets):
        hold = sc.legs[k].hold
        arrive = times[k + 1] - hold
        pos, vel, _ = result.state(arrive)
        assert _same_set(pos, target), f"not on target {k} at {arrive:.2f} s"
        if hold > 0:  # a rest: nobody moves
            later, vel2, _ = result.state(times[k + 1] - 1e-6)
            np.testing.assert_allclose(later, pos, atol=1e-9)
            assert np.abs(vel2).max() < 1e-6
    assert _same_set(result.end, problem.target)


def test_chain_is_exactly_valid_and_stats_add_up(chain):
    _, sc, problem, targets, result, stats, times = chain
    c = check_plan(problem, result)
    assert c.value >= problem.margin and stats.min_clearance == pytest.approx(c.value)
    legs = stats.extra["legs"]
    assert [leg["target"] for leg in legs] == ["ring", "scatter", "A"]
    assert stats.steps == result.steps == sum(leg["steps"] for leg in legs) + 2  # two rests
    assert stats.makespan_s == pytest.approx(sum(leg["makespan_s"] + leg["hold_s"] for leg in legs))
    assert stats.planning_time_s == pytest.approx(sum(leg["planning_time_s"] for leg in legs))
    assert stats.makespan_lower_bound_s <= stats.makespan_s


def test_checks_catch_a_broken_chain(chain):
    """Negative controls: a leg that starts where the last did not end; robots swapping through each other."""
    _, _, problem, targets, result, _, _ = chain
    w = np.array(result.waypoints)
    jump = Plan(result.radius, result.margin, np.r_[result.durations, 5.0],
                np.concatenate([w, [targets[0]]]), result.max_speed, result.max_accel)
    with pytest.raises(PlanInvalid):
        check_plan(problem, jump)  # ends on the ring, not on the last target
    swap = w[-1].copy()
    swap[[0, 1]] = swap[[1, 0]]
    crossing = Plan(result.radius, result.margin, np.r_[result.durations, 5.0],
                    np.concatenate([w, [swap]]), result.max_speed, result.max_accel)
    with pytest.raises(PlanInvalid, match="margin"):
        check_plan(problem, crossing)


def test_single_target_is_the_planner_itself():
    path = ROOT / "scenarios" / "paper" / "fig2-random-to-C.yaml"
    sc = read_scenario(path)
    a_rng, b_rng = np.random.default_rng(1), np.random.default_rng(1)
    problem, targets = build_legs(sc, a_rng)
    build_legs(sc, b_rng)
    a, _, times = plan_legs(problem, targets, sc.planner, a_rng)
    b, _ = plan(problem, sc.planner, b_rng)
    a.stats.planning_time_s = b.stats.planning_time_s = 0.0
    assert a.to_json() == b.to_json()
    np.testing.assert_allclose(times, [0.0, b.makespan])


def test_a_failing_leg_is_named():
    """A wall cuts the workspace in two: the second leg's target is out of reach."""
    from planner import Polygon, Problem

    wall = Polygon(np.array([[19, 0], [21, 0], [21, 40], [19, 40]], float))
    left = np.array([[5, 5], [5, 10], [5, 15]], float)
    problem = Problem(40, 40, (wall,), 1.0, 0.1, left, left + [30, 0])
    targets = [left + [6, 0], left + [30, 0]]
    params = replace(PlannerParams(), time_limit=1.0)
    with pytest.raises(NoPlanFound, match=r"leg 2 of 2 \(right\)") as info:
        plan_legs(problem, targets, params, np.random.default_rng(0), labels=["left", "right"])
    assert info.value.stats.found is False
    assert [leg["target"] for leg in info.value.stats.extra["legs"]] == ["left"]


def test_run_writes_legs_and_marks_the_current_target(chain, tmp_path):
    path = chain[0]
    result = run_scenario(path, out_dir=tmp_path, out=None)
    assert result.exit_code == 0, result.report
    report = json.loads((tmp_path / "chain.json").read_text())
    assert report["sim"]["contacts"] == 0 and report["sim"]["reached"]
    assert [leg["target"] for leg in report["plan"]["legs"]] == ["ring", "scatter", "A"]
    assert (tmp_path / "chain.gif").exists()


def test_frames_mark_the_current_legs_target(chain):
    _, sc, problem, targets, result, _, times = chain
    t = np.linspace(0, result.makespan, 60)
    pos = result.sample(t)[0]
    params = RenderParams(size=200, fps=5, speedup=result.makespan / 4, trails=False)
    legs = list(zip(times[:-1], targets))
    frames = list(render_frames(problem, t, pos, (), params, targets=legs))
    cv = Canvas(problem, 200)

    mark = np.all(np.abs(np.stack(frames).astype(int) - TARGET_MARK) <= 8, axis=-1)  # (F, H, W)
    r = cv.r_px

    def marked(k, placement):
        """The fraction of the placement's spots that show marker pixels in frame ``k``."""
        px = np.round(cv.to_px(placement)).astype(int)
        return np.mean([mark[k, y - r : y + r + 1, x - r : x + r + 1].any() for x, y in px])

    # the first frame after leg 2 (the scatter) began: the robots still stand on the ring
    k = int(np.ceil(times[1] * params.fps / params.speedup + 1e-9))
    assert marked(0, targets[0]) > 0.8  # the ring's markers show first...
    assert marked(0, targets[1]) < 0.3  # ...and the scatter's do not
    assert marked(k, targets[1]) > 0.8  # then the scatter's do
    with pytest.raises(ValueError, match="targets"):
        list(render_frames(problem, t, pos, (), params, targets=[(0.0, targets[0][:3])]))


@pytest.mark.slow
@pytest.mark.parametrize("path", sorted((ROOT / "scenarios" / "showcase").glob("*.yaml")), ids=lambda p: p.stem)
def test_showcase_runs_clean(path, tmp_path):
    result = run_scenario(path, out_dir=tmp_path, render=False, out=None)
    assert result.exit_code == 0, result.report
    assert result.report["sim"]["contacts"] == 0 and result.report["sim"]["reached"]
    assert len(result.report["plan"]["legs"]) >= 3
