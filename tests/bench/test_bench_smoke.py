"""Smoke runs of the planner benchmarks, their summaries, and the exact check of peer paths."""

import json
import math
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
if str(ROOT) not in sys.path:  # bench/ is a folder of the repository, not an installed package
    sys.path.insert(0, str(ROOT))

from bench import peers, scaling  # noqa: E402
from bench._common import random_problem, straight_line_waypoints, timed_plan, verify  # noqa: E402
from planner import Polygon, Problem  # noqa: E402

FIG2 = str(ROOT / "scenarios" / "paper" / "fig2-random-to-C.yaml")


def _check_rows(rows, columns):
    assert rows
    for row in rows:
        assert set(columns) <= set(row)
        assert 0.0 <= row["success"] <= 1.0
        t = row["median time [s]"]
        assert math.isnan(t) or t > 0


def _require_ompl():
    # ImportError too, not only a missing module: a broken binary wheel skips as well.
    pytest.importorskip("ompl.geometric", exc_type=ImportError)


def _case(problem: Problem, name="control") -> peers.Case:
    return peers.Case("controls", name, problem.m, lambda rng: problem)


# ----------------------------------------------------------------------------
# exact check of returned paths (negative and positive controls)


def _capt_counterexample() -> Problem:
    """Two robots whose minimum-sum straight lines pass 1.84 apart (separation 2.1).

    Both assignments cost the same and both collide: the robots start
    side by side and their targets sit above and below the gap between them.
    """
    start = np.array([[20.0, 20.0], [22.1, 20.0]])
    target = np.array([[21.05, 21.9], [21.05, 18.1]])
    return Problem(40, 40, (), 1.0, 0.1, start, target).validate()


def _through_obstacle() -> Problem:
    square = Polygon(np.array([[17.0, 17.0], [23.0, 17.0], [23.0, 23.0], [17.0, 23.0]]))
    start = np.array([[5.0, 20.0], [5.0, 30.0]])
    target = np.array([[35.0, 20.0], [35.0, 30.0]])
    return Problem(40, 40, (square,), 1.0, 0.1, start, target).validate()


@pytest.mark.parametrize("problem", [_capt_counterexample(), _through_obstacle()], ids=["robots", "obstacle"])
def test_colliding_straight_lines_count_as_failures(problem):
    check = verify(problem, timed_plan(problem, straight_line_waypoints(problem)))
    assert not check.valid and check.clearance < problem.margin
    (run,) = peers.run_case(_case(problem), 0, 1.0, planners=(peers.STRAIGHT,))
    assert run.invalid and not run.solved
    assert math.isnan(run.makespan_s)
    row = peers.summarize([run])[0]
    assert row["success"] == 0.0 and row["invalid paths"] == 1


def test_clear_straight_lines_count_as_success():
    start = np.array([[5.0, 5.0], [5.0, 10.0]])
    problem = Problem(40, 40, (), 1.0, 0.1, start, start + [20.0, 0.0]).validate()
    (run,) = peers.run_case(_case(problem), 0, 1.0, planners=(peers.STRAIGHT,))
    assert run.solved and not run.invalid
    assert run.makespan_s == pytest.approx(run.lower_bound_s)


def test_random_problem_is_valid_and_seeded():
    a = random_problem(12, 40.0, np.random.default_rng(3))
    b = random_problem(12, 40.0, np.random.default_rng(3))
    assert a.m == 12 and len(a.obstacles) == 3
    np.testing.assert_array_equal(a.start, b.start)
    np.testing.assert_array_equal(a.target, b.target)


# ----------------------------------------------------------------------------
# summaries


def _run(case, seed, planner, solved, time_s, invalid=False):
    return peers.Run("f", case, 5, seed, planner, solved, invalid, time_s,
                     10.0 if solved else math.nan, 5.0, "")


def test_summary_ratios_are_per_run_over_runs_both_solved():
    runs = [
        _run("a", 0, peers.SWARMFORM, True, 0.1),
        _run("a", 1, peers.SWARMFORM, True, 0.2),
        _run("a", 2, peers.SWARMFORM, False, 1.0),
        _run("a", 0, "RRTConnect", True, 2.0),  # 20x
        _run("a", 1, "RRTConnect", True, 1.0),  # 5x
        _run("a", 2, "RRTConnect", True, 3.0),  # swarmform failed: no ratio
        _run("a", 0, peers.STRAIGHT, False, 1e-4, invalid=True),
        _run("a", 1, peers.STRAIGHT, False, 1e-4, invalid=True),
        _run("a", 2, peers.STRAIGHT, False, 1e-4, invalid=True),
    ]
    rows = {r["planner"]: r for r in peers.summarize(runs)}
    sf, rrt, line = rows[peers.SWARMFORM], rows["RRTConnect"], rows[peers.STRAIGHT]
    assert sf["success"] == pytest.approx(2 / 3)
    assert sf["median makespan / LB"] == pytest.approx(2.0)
    assert rrt["success"] == 1.0
    assert rrt["time / swarmform (median)"] == pytest.approx(12.5)
    assert rrt["time / swarmform (min)"] == pytest.approx(5.0)
    assert rrt["under 10x swarmform"] == 1
    assert rrt["solved where swarmform failed"] == 1
    assert math.isnan(rrt["swarmform success where it failed"])  # RRTConnect never failed
    assert line["invalid paths"] == 3
    assert line["swarmform success where it failed"] == pytest.approx(2 / 3)
    assert math.isnan(line["median time [s]"])


# ----------------------------------------------------------------------------
# smoke runs of the benchmarks' main functions


def test_peers_main_smoke_without_ompl(capsys, tmp_path):
    out_json = tmp_path / "runs.json"
    rows = peers.main(["--seeds", "2", "--time-limit", "2", "--scenarios", FIG2, "--dense", "8",
                       "--planners", "swarmform", "straight", "--json", str(out_json)])
    _check_rows(rows, peers.COLUMNS)
    assert {r["family"] for r in rows} == {"paper", "dense"}
    assert {r["planner"] for r in rows} == {peers.SWARMFORM, peers.STRAIGHT}
    assert all(r["runs"] == 2 for r in rows)
    out = capsys.readouterr().out
    assert "| planner | runs | success |" in out and "## paper" in out and "## dense" in out
    assert "- python:" in out and "- date:" in out
    records = json.loads(out_json.read_text())
    assert len(records) == 2 * 2 * 2  # cases x seeds x planners
    assert {"case", "seed", "planner", "solved", "invalid", "time_s"} <= set(records[0])


def test_peers_main_smoke_with_ompl(capsys):
    _require_ompl()
    rows = peers.main(["--seeds", "1", "--time-limit", "0.5", "--scenarios", FIG2, "--dense", "6"])
    _check_rows(rows, peers.COLUMNS)
    assert {r["planner"] for r in rows} == set(peers.PLANNERS)
    for r in rows:
        if r["planner"] in peers.OMPL_PLANNERS:
            assert r["invalid paths"] == 0  # the motion validator is exact
    assert "ompl: 2." in capsys.readouterr().out


def test_ompl_paths_pass_the_exact_validator():
    _require_ompl()
    problem = _through_obstacle()
    for name in peers.OMPL_PLANNERS:
        out = peers.run_ompl(problem, name, time_limit=3.0, seed=1)
        assert out.plan is not None, f"{name}: {out.status}"
        assert out.plan.steps >= 2  # the straight line is blocked
        assert verify(problem, out.plan).valid
        assert 0 < out.time_s < 3.0 + 1.0 + 5.0


def test_scaling_main_smoke(capsys):
    rows = scaling.main(["--seeds", "2", "--sizes", "5", "9", "--time-limit", "10"])
    _check_rows(rows, scaling.COLUMNS)
    assert [r["m"] for r in rows] == [5, 9]
    for r in rows:
        assert r["runs"] == 2
        assert r["peak RSS growth [MiB]"] >= 0
        assert r["side"] == pytest.approx(scaling.side_for(r["m"]))
    out = capsys.readouterr().out
    assert "| m | side | runs | success |" in out and "Fitted exponent" in out


def test_fit_exponent_recovers_a_power_law():
    rows = [{"m": m, "median time [s]": 0.01 * m**1.5} for m in (7, 11, 20, 50, 100)]
    assert scaling.fit_exponent(rows) == pytest.approx(1.5)
    rows.append({"m": 200, "median time [s]": math.nan})  # a size with no solved run is left out
    assert scaling.fit_exponent(rows, min_m=20) == pytest.approx(1.5)


def test_frontier_proves_the_pocket_and_plans_a_door():
    from bench import frontier

    rows = frontier.main(["--cases", "unsolvable-pocket", "door-4.4", "--seeds", "1", "--time-limit", "20"])
    pocket, door = (next(r for r in rows if r["case"] == n) for n in ("unsolvable-pocket", "door-4.4"))
    assert pocket["proven unsolvable"] == 1 and pocket["planned"] == 0 and pocket["proof max [s]"] < 1.0
    assert door["solved"] == "1/1" and door["makespan / bound (median)"] >= 1.0
    assert "no plan exists: the component around" in pocket["records"][0]["reason"]


def test_frontier_time_limit_rows():
    from bench import frontier

    rows = frontier.limit_rows(names=("clutter-10-m20",), limits=(0.5,), seeds=1)
    (row,) = rows
    assert row["case"] == "clutter-10-m20" and row["runs"] == 1
    assert row["bar [s]"] == pytest.approx(1.1 * 0.5 + 0.5)
    assert row["within bar"] == ("yes" if row["max wall [s]"] <= row["bar [s]"] else "no")
    assert row["within bar"] == "yes"


def test_maps_bench_scatter_rows_plan_on_the_cells():
    """``bench.maps --scatter``: robots off the cells, in the largest free part, planned by the
    grid stage and checked exactly; the obstacle-respecting bound sits beside."""
    from bench import maps

    p = maps.scatter_problem("room-32-32-4", 40, 1)
    assert maps.map_problem("room-32-32-4", 40, 1).m == p.m == 40
    from planner.gridstage import detect_grid

    assert detect_grid(p) is None  # off every grid
    row = maps.run_one("room-32-32-4", 40, 1, 20.0, lacam=True, scattered=True)
    assert row["ok"] and row["stage"] == "grid" and "lacam_ok" not in row
    assert row["x_geo"] <= row["x_straight"] and row["x_geo"] < 3
