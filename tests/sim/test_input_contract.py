"""The input table (docs/inputs.md) is the code's: every numeric range holds at both ends.

For every row of the README's "Input ranges" table whose range is numeric,
a scenario with the field at each closed end must load and one just outside
must be refused, naming the field; an open end must be refused at the end
and accepted just inside.  Changing a bound in the code without the README
(or the reverse) fails here.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import pytest
import yaml

from sim.scenario import ScenarioError, read_scenario

ROOT = Path(__file__).resolve().parents[2]
README = ROOT / "docs" / "inputs.md"  # the input table; the README links it

_NUM = r"-?[0-9.]+(?:e[+-]?[0-9]+)?|2\^63 - 1"
_RANGE = re.compile(rf"([\[(])({_NUM}), ({_NUM})([\])])")

# Fields whose checks need company: the values that make the rest of the file valid.
_BASE = {
    "start": {"formation": "A", "rotation": 0},
    "target": {"formation": "A", "rotation": 0},
    "robots": {"max_speed": 0.001},  # so that sim.dt's bound by robots.radius never binds
}
_COMPANY = {
    "robots.max_speed": {"sim": {"dt": 0.0001}},
    "render.fps": {"render": {"formats": ["mp4"]}},
}
# Rows whose bounds depend on other fields, or that are not one number.
_SKIP = {"obstacles[k].circle.radius", "obstacles[k].random.size", "paper.table, paper.row, paper.time_s",
         "name", "obstacles"}


def _value(text: str) -> float:
    return 2**63 - 1 if text == "2^63 - 1" else float(text)


def _rows():
    text = README.read_text(encoding="utf-8")
    section = text.split("## Input ranges", 1)[1].split("\n\n", 3)
    table = next(part for part in section if part.lstrip().startswith("| field |"))
    for line in table.splitlines()[2:]:
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        field = cells[0].replace("`", "")
        ranges = list(_RANGE.finditer(cells[3]))
        if field in _SKIP or not ranges:
            continue
        found = ranges[-1]  # render.fps: the MP4 range, tested with MP4 alone
        integer = "integer" in cells[3]
        yield field, found.group(1) == "[", _value(found.group(2)), _value(found.group(3)), \
            found.group(4) == "]", integer


ROWS = list(_rows())


def test_the_table_has_the_numeric_fields():
    names = {r[0] for r in ROWS}
    for field in ("seed", "workspace", "robots.radius", "robots.margin", "robots.count", "robots.max_speed",
                  "robots.max_accel", "planner.time_limit", "planner.n", "sim.dt", "sim.substeps",
                  "sim.settle_time", "render.fps", "render.size", "render.speedup", "obstacles[k].random.count"):
        assert field in names, field
    assert len(ROWS) >= 25


def _doc(field: str, value) -> dict:
    doc = yaml.safe_load(yaml.safe_dump(_BASE))
    for key, extra in _COMPANY.get(field, {}).items():
        doc[key] = dict(doc.get(key) or {}, **extra) if key not in ("start", "target") else extra
    if field == "robots.count":  # as many points as robots, so that only the count can be wrong
        n = max(1, min(int(value), 5000))
        doc["start"] = {"points": [[1 + i % 30, 1 + i // 30] for i in range(n)]}
        doc["target"] = {"points": [[1 + i % 30, 1 + i // 30] for i in range(n)]}
    if field == "workspace":
        doc["workspace"] = [value, 40]
    elif field == "obstacles[k].random.count":
        doc["obstacles"] = [{"random": {"count": value, "size": [0.1, 0.2]}}]
    elif field == "obstacles[k].random.seed":
        doc["obstacles"] = [{"random": {"seed": value, "size": [0.1, 0.2]}}]
    else:
        *sections, key = field.split(".")
        node = doc
        for section in sections:  # nested sections (sim.sensing.rate) as mappings
            node[section] = dict(node.get(section) or {})
            node = node[section]
        node[key] = value
    return doc


def _named(field: str) -> str:
    return {"workspace": "workspace[0]", "obstacles[k].random.count": "obstacles[0].random.count",
            "obstacles[k].random.seed": "obstacles[0].random.seed"}.get(field, field)


def _outside(bound: float, integer: bool, direction: int):
    if integer:
        return int(bound) + direction
    step = 1e-9 if bound == 0 else abs(bound) * 1e-6
    return bound + direction * step


def _check(tmp_path, field, value, ok: bool):
    path = tmp_path / "case.yaml"
    path.write_text(yaml.safe_dump(_doc(field, value)))
    if ok:
        read_scenario(path)
    else:
        with pytest.raises(ScenarioError) as info:
            read_scenario(path)
        assert info.value.field == _named(field), str(info.value)


@pytest.mark.parametrize("field, low_closed, low, high, high_closed, integer", ROWS, ids=[r[0] for r in ROWS])
def test_each_range_holds_at_both_ends(tmp_path, field, low_closed, low, high, high_closed, integer):
    cast = int if integer else float
    if low_closed:
        _check(tmp_path, field, cast(low), True)
        _check(tmp_path, field, _outside(low, integer, -1), False)
    else:
        _check(tmp_path, field, cast(low), False)
        _check(tmp_path, field, _outside(low, integer, +1), True)
    if high_closed:
        _check(tmp_path, field, cast(high), True)
        _check(tmp_path, field, _outside(high, integer, +1), False)
    else:
        _check(tmp_path, field, cast(high), False)
    assert math.isfinite(low) and math.isfinite(high)
