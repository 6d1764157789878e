"""bench.cli_limits runs the whole command in a fresh process and reads its exit code."""

from bench.cli_limits import run_case


def test_a_row_runs_the_command_and_reports_its_exit_and_wall_time():
    row = run_case("room-32-32-4-100.yaml", 100, 10.0)
    assert row["exit"] == 0 and row["wall [s]"] > 0 and row["bar [s]"] == 11.5


def test_a_crowd_that_cannot_be_placed_in_the_limit_exits_1():
    """The control: placing 1500 robots over den312d takes longer than 0.05 s."""
    row = run_case("den312d-scatter-200.yaml", 1500, 0.05)
    assert row["exit"] == 1
