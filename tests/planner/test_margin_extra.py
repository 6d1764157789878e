"""``planner.margin_extra``: plan with an inflated margin, validate against the real one, report both."""

import numpy as np
import pytest

from planner import Circle, NoPlanFound, PlannerParams, Problem, ProblemError, check_plan, min_clearance, plan

R = 1.0
MARGIN = 0.1


def _problem():
    # Four robots swap sides past a pillar: the plain plan passes at the margin.
    start = np.array([[3.0, 4.0], [3.0, 8.0], [3.0, 12.0], [3.0, 16.0]])
    target = start + [14.0, 0.0]
    return Problem(20.0, 20.0, (Circle((10.0, 10.0), 2.0),), R, MARGIN, start, target)


def test_plan_keeps_the_inflated_margin_and_reports_both():
    problem = _problem()
    extra = 0.4
    p, stats = plan(problem, PlannerParams(margin_extra=extra), np.random.default_rng(1))
    exact = min_clearance(problem, p).value
    assert exact >= MARGIN + extra - 1e-9
    assert stats.min_clearance == pytest.approx(exact)
    assert p.margin == MARGIN  # the plan file records the real margin
    assert stats.extra["margin"] == MARGIN and stats.extra["margin_extra"] == extra
    assert check_plan(problem, p).value == pytest.approx(exact)
    assert p.stats is stats
    # Negative control: without the extra, the plan comes closer than margin + extra.
    plain, plain_stats = plan(problem, PlannerParams(), np.random.default_rng(1))
    assert min_clearance(problem, plain).value < MARGIN + extra
    assert "margin_extra" not in plain_stats.extra


def test_extra_that_the_placements_cannot_keep_names_the_parameter():
    problem = _problem()
    with pytest.raises(ProblemError) as info:
        plan(problem, PlannerParams(margin_extra=3.0), np.random.default_rng(0))
    assert info.value.field == "planner.margin_extra"
    assert "margin + margin_extra = 3.1" in info.value.reason


def test_no_plan_with_the_extra_says_so():
    # A door 2.6 wide: 2.2 fits robots with the margin, not with margin + 0.5.
    from planner import Polygon

    wall = (Polygon(np.array([[9.0, 0.0], [11.0, 0.0], [11.0, 8.7], [9.0, 8.7]])),
            Polygon(np.array([[9.0, 11.3], [11.0, 11.3], [11.0, 20.0], [9.0, 20.0]])))
    problem = Problem(20.0, 20.0, wall, R, MARGIN, np.array([[4.0, 10.0]]), np.array([[16.0, 10.0]]))
    plan(problem, PlannerParams(time_limit=5.0), np.random.default_rng(0))
    with pytest.raises(NoPlanFound) as info:
        plan(problem, PlannerParams(margin_extra=0.5, time_limit=1.0), np.random.default_rng(0))
    assert info.value.stats.extra["margin_extra"] == 0.5


def test_a_placement_into_an_obstacle_or_wall_is_named_and_a_clear_one_passes():
    """The exact clearance test runs first; what a robot hits is named only when one fails."""
    import re

    from planner import Polygon, Problem
    from planner.problem import ProblemError, check_placement

    block = Polygon(np.array([[4.0, 4.0], [6.0, 4.0], [6.0, 6.0], [4.0, 6.0]]))
    problem = Problem(10.0, 10.0, (block,), 0.5, 0.1, [[1.0, 1.0]], [[1.0, 1.0]])
    check_placement(problem, np.array([[1.0, 1.0], [3.3, 5.0], [8.0, 8.0]]), "start")  # 0.7 from the block
    with pytest.raises(ProblemError, match=re.escape("start[1]: robot 1 at (3.5, 5) hits obstacle 0")):
        check_placement(problem, np.array([[1.0, 1.0], [3.5, 5.0]]), "start")
    with pytest.raises(ProblemError, match=re.escape("target[0]: robot 0 at (9.5, 5) hits the")):
        check_placement(problem, np.array([[9.5, 5.0]]), "target")
