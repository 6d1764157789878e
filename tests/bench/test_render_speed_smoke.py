"""bench.render_speed runs and prints its tables (tiny settings)."""

import pytest

from bench import render_speed


@pytest.mark.slow
def test_render_speed_prints_its_tables(capsys):
    render_speed.main(["--robots", "3", "--size", "128", "--no-default", "--long", "40"])
    out = capsys.readouterr().out
    assert "| robots | frames | size | render | GIF encode |" in out
    assert "| 3 | 421 (x3) |" in out
    long_rows = [line for line in out.splitlines() if line.startswith("| 61 |")]  # 41 drawn, 20 held
    assert len(long_rows) == 1 and "GIF" in long_rows[0] and "MB" in long_rows[0]
