"""The scenario reader's checks, pinned at their boundaries (sim/scenario/reader.py).

Each field check is driven at its exact edge (the largest value allowed and the first
refused) and the one-line message is compared whole: the field, the allowed range as
written, and the value received.  These are the tests that mutation testing of
``sim/scenario/reader.py`` relies on (see ``tests/mutation/``).
"""

import math

import pytest

from sim.scenario import ScenarioError
from sim.scenario.fields import _numeric_text_hint, _Reader, _span


class _R:
    """A fresh reader per use (a reader made at import would escape mutation testing)."""

    def __getattr__(self, name):
        return getattr(_Reader("s.yaml"), name)


R = _R()


def refused(fn, *args, **kwargs) -> str:
    with pytest.raises(ScenarioError) as e:
        fn(*args, **kwargs)
    return str(e.value)


def test_span_writes_the_range():
    assert _span(None, None, None, None) == ""
    assert _span(0, None, None, None) == " > 0"
    assert _span(None, 1, None, None) == " >= 1"
    assert _span(None, None, 5, None) == " <= 5"
    assert _span(None, None, None, 5) == " < 5"
    assert _span(0, None, 10, None) == " in (0, 10]"
    assert _span(None, 0, None, 1) == " in [0, 1)"
    assert _span(None, 0, 2**63 - 1, None) == " in [0, 2^63 - 1]"
    assert _span(None, 0.5, 1e6, None) == " in [0.5, 1e+06]"


def test_numeric_text_hint():
    hint = " (text; write a number such as 1.0e+3 without quotes)"
    assert _numeric_text_hint("1e3") == hint
    assert _numeric_text_hint("  2.5 ") == hint
    assert _numeric_text_hint("x1") == ""
    assert _numeric_text_hint(1.0) == ""
    assert _numeric_text_hint("1" * 40) == hint
    assert _numeric_text_hint("1" * 41) == ""


def test_mapping():
    assert R.mapping(None, "sim", ("dt",)) == {}
    assert R.mapping({"dt": 1}, "sim", ("dt", "kp")) == {"dt": 1}
    assert refused(R.mapping, [1], "sim", ("dt",)) == "s.yaml: sim: must be a mapping, got a list of 1"
    assert refused(R.mapping, {"dt": 1, "kq": 2}, "sim", ("dt", "kp")) == (
        "s.yaml: sim.kq: unknown key; allowed here: dt, kp"
    )
    assert refused(R.mapping, {"nmae": 1}, "", ("name", "seed")) == "s.yaml: nmae: unknown key; allowed here: name, seed"


def test_number_bounds_are_exact():
    assert R.number(0.5, "f", gt=0) == 0.5 and isinstance(R.number(3, "f"), float)
    assert refused(R.number, 0, "f", gt=0) == "s.yaml: f: must be a number > 0, got 0"
    assert R.number(0, "f", ge=0) == 0.0
    assert refused(R.number, -1e-9, "f", ge=0) == "s.yaml: f: must be a number >= 0, got -1e-09"
    assert R.number(10, "f", le=10) == 10.0
    assert refused(R.number, 10.5, "f", le=10) == "s.yaml: f: must be a number <= 10, got 10.5"
    assert R.number(0.999, "f", lt=1) == 0.999
    assert refused(R.number, 1, "f", lt=1) == "s.yaml: f: must be a number < 1, got 1"
    assert refused(R.number, 11, "f", gt=0, le=10) == "s.yaml: f: must be a number in (0, 10], got 11"
    assert refused(R.number, True, "f", gt=0) == "s.yaml: f: must be a number > 0, got boolean True"
    assert refused(R.number, "1e3", "f") == (
        "s.yaml: f: must be a number, got string '1e3' (text; write a number such as 1.0e+3 without quotes)"
    )
    assert refused(R.number, None, "f", ge=0) == "s.yaml: f: must be a number >= 0, got nothing (null)"
    assert refused(R.number, math.inf, "f", gt=0) == "s.yaml: f: must be a finite number > 0, got inf"
    assert refused(R.number, math.nan, "f") == "s.yaml: f: must be a finite number, got nan"
    assert refused(R.number, 2**1001, "f") == "s.yaml: f: must be a number, got an integer of about 302 digits"
    assert R.number(2**999, "f") == float(2**999)  # 1000 bits
    assert refused(R.number, 2**1000, "f") == "s.yaml: f: must be a number, got an integer of about 302 digits"


def test_integer_bounds_are_exact():
    assert R.integer(1, "n", ge=1) == 1 and R.integer(10, "n", le=10) == 10
    assert refused(R.integer, 0, "n", ge=1) == "s.yaml: n: must be an integer >= 1, got 0"
    assert refused(R.integer, 11, "n", ge=1, le=10) == "s.yaml: n: must be an integer in [1, 10], got 11"
    assert refused(R.integer, 2.0, "n", ge=1) == "s.yaml: n: must be an integer >= 1, got number 2.0"
    assert refused(R.integer, False, "n") == "s.yaml: n: must be an integer, got boolean False"


def test_int_or_auto():
    assert R.int_or_auto("auto", "g") is None
    assert R.int_or_auto(1, "g") == 1 and R.int_or_auto(5, "g", le=5) == 5
    assert refused(R.int_or_auto, "x", "g") == "s.yaml: g: must be 'auto' or an integer >= 1, got string 'x'"
    assert refused(R.int_or_auto, True, "g", le=9) == "s.yaml: g: must be 'auto' or an integer in [1, 9], got boolean True"
    assert refused(R.int_or_auto, 0, "g") == "s.yaml: g: must be an integer >= 1, got 0"
    assert refused(R.int_or_auto, 2.5, "g", ge=2) == "s.yaml: g: must be 'auto' or an integer >= 2, got number 2.5"


def test_boolean_pair_and_inside():
    assert R.boolean(False, "b") is False
    assert refused(R.boolean, 1, "b") == "s.yaml: b: must be true or false, got number 1"
    assert R.pair([1, 2.5], "p") == (1.0, 2.5) and R.pair((0, 0), "p", ge=0) == (0.0, 0.0)
    assert refused(R.pair, [1, 2, 3], "p") == "s.yaml: p: must be a pair [x, y], got a list of 3"
    assert refused(R.pair, "1, 2", "p") == "s.yaml: p: must be a pair [x, y], got string '1, 2'"
    assert refused(R.pair, [1, -1], "p", ge=0) == "s.yaml: p[1]: must be a number >= 0, got -1"
    assert refused(R.pair, [-1, 1], "p", ge=0) == "s.yaml: p[0]: must be a number >= 0, got -1"
    assert R.inside([0, 0], "q", 10, 5) == (0.0, 0.0) and R.inside([10, 5], "q", 10, 5) == (10.0, 5.0)
    assert refused(R.inside, [1, 2, 3], "q", 10, 5) == "s.yaml: q: must be a pair [x, y], got a list of 3"
    assert refused(R.inside, [1, "a"], "q", 10, 5) == "s.yaml: q[1]: must be a number, got string 'a'"
    for bad in ([10.5, 1], [1, 5.5], [-0.5, 1], [1, -0.5]):
        msg = refused(R.inside, bad, "q", 10, 5)
        assert msg == f"s.yaml: q: ({bad[0]:g}, {bad[1]:g}) lies outside the 10 x 5 workspace"


def test_overrides_are_applied_and_blamed(tmp_path):
    from pathlib import Path

    from sim.scenario import read_scenario

    src = Path(__file__).resolve().parents[2] / "scenarios"
    path = sorted(src.rglob("*.yaml"))[0]
    base = read_scenario(path)
    moved = read_scenario(path, {"robots.margin": 0.25})
    assert moved.margin == 0.25 != base.margin and moved.path == base.path == str(path)
    assert read_scenario(str(path), {}).margin == base.margin
    with pytest.raises(ScenarioError) as e:
        read_scenario(path, {"robots.margin": -1.0})
    assert str(e.value) == "--set robots.margin: must be a number in [0, 100], got -1"
