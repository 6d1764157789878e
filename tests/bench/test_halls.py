"""bench.packing's halls with pillars: drawn from their seed alone, valid, crowded."""

from __future__ import annotations

import math

import numpy as np

from bench.packing import hall_problem, main


def test_a_hall_is_the_same_from_its_seed_and_crowded():
    a, b = hall_problem(15), hall_problem(15)
    assert a is not None and b is not None
    assert np.array_equal(a.start, b.start) and np.array_equal(a.target, b.target)
    assert 1 <= len(a.obstacles) <= 8 and 6 <= a.width <= 16 and 6 <= a.height <= 16
    covered = a.m * math.pi * a.radius**2 / (a.width * a.height)
    assert 0.17 <= covered <= 0.38
    assert hall_problem(4) is None  # its robots do not fit


def test_the_halls_table_prints_a_row_per_hall(capsys):
    rows = main(["--halls", "1", "--time-limit", "5"])
    assert len(rows) == 1 and rows[0]["outcome"] == "found"
    assert "| seed | world | radius |" in capsys.readouterr().out
