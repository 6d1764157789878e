"""Fuzzing the readers: any document, any bytes either load or raise the input error, quickly.

The scenario loader (:func:`sim.scenario.read_scenario`, then
:func:`build_problem` for what it accepts) and the plan-file loader
(:func:`planner.plan.read_plan_file`) get documents drawn by hypothesis:
arbitrary YAML and JSON values (huge and tiny numbers, infinities, NaN,
booleans, odd strings, deep and wide nesting), documents shaped like
scenarios with every known key holding arbitrary values, shipped
scenarios with random edits, and arbitrary bytes.  Each must either load
or raise :class:`ScenarioError` / :class:`PlanFileError` whose message is one
line of bounded length, within a second.  The examples are derandomised, so
the suite is the same on every run.
"""

from __future__ import annotations

import json
import math
import time
from pathlib import Path

import numpy as np
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from planner.plan import PlanFileError, read_plan_file
from sim.scenario import ScenarioError, build_problem, read_scenario

ROOT = Path(__file__).resolve().parents[2]
SHIPPED = sorted((ROOT / "scenarios").rglob("*.yaml"))
SECONDS = 1.0  # per document, reading and building
FUZZ = settings(max_examples=150, deadline=None, derandomize=True,
                suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])

numbers = st.one_of(
    st.integers(),
    st.integers(min_value=-(10**60), max_value=10**60),
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([0, 1, 2, -1, 0.5, 1e-300, 1e300, 10**40, 2**63, 1000, 1001, 0.001]),
)
scalars = st.one_of(st.none(), st.booleans(), numbers, st.text(max_size=40),
                    st.sampled_from(["auto", "random", "A", "line", "phi", "gif", "mp4", "II", ""]))
values = st.recursive(
    scalars,
    lambda inner: st.one_of(st.lists(inner, max_size=6), st.dictionaries(st.text(max_size=10), inner, max_size=6)),
    max_leaves=40,
)
points = st.lists(st.lists(numbers, min_size=2, max_size=2), min_size=1, max_size=6)
KEYS = {
    "name": st.one_of(scalars, st.from_regex(r"[A-Za-z0-9][A-Za-z0-9._-]{0,70}", fullmatch=True)),
    "seed": numbers,
    "workspace": st.one_of(values, st.lists(numbers, min_size=2, max_size=2)),
    "robots": st.dictionaries(st.sampled_from(["radius", "margin", "count", "max_speed", "max_accel"]),
                              st.one_of(numbers, scalars), max_size=5),
    "obstacles": st.lists(st.one_of(
        st.fixed_dictionaries({"polygon": st.one_of(points, values)}),
        st.fixed_dictionaries({"circle": st.fixed_dictionaries({"center": st.one_of(points, values),
                                                                "radius": numbers})}),
        st.fixed_dictionaries({"random": st.dictionaries(st.sampled_from(["count", "size", "seed"]),
                                                         st.one_of(numbers, points), max_size=3)}),
        values,
    ), max_size=4),
    "start": st.one_of(
        st.fixed_dictionaries({"points": st.one_of(points, values)}),
        st.dictionaries(st.sampled_from(["formation", "scale", "rotation", "center"]), values, max_size=4),
        st.fixed_dictionaries({"formation": st.sampled_from(["A", "C", "M", "N", "lambda", "phi", "line", "random"])},
                              optional={"scale": numbers, "rotation": numbers}),
    ),
    "planner": st.dictionaries(st.sampled_from(["g", "q", "time_limit", "n", "extra", "concurrent"]), scalars,
                               max_size=6),
    "sim": st.dictionaries(st.sampled_from(["mass", "kp", "kd", "dt", "substeps", "force_limit", "settle_time",
                                            "tolerance"]), numbers, max_size=8),
    "render": st.dictionaries(st.sampled_from(["fps", "size", "trails", "formats", "speedup", "video_seconds"]),
                              scalars, max_size=6),
    "paper": values,
}
KEYS["target"] = KEYS["start"]
scenario_like = st.fixed_dictionaries({}, optional=KEYS)


def _load_or_refuse(path: Path) -> None:
    t0 = time.perf_counter()
    try:
        scenario = read_scenario(path)
        build_problem(scenario, np.random.default_rng(scenario.seed))
    except ScenarioError as exc:
        text = str(exc)
        assert "\n" not in text and len(text) < 400, text[:500]
        assert exc.field and exc.reason
    assert time.perf_counter() - t0 < SECONDS


def _dump(doc) -> str:
    return yaml.safe_dump(doc, default_flow_style=None, allow_unicode=True, width=10**9)


@FUZZ
@given(doc=values)
def test_any_yaml_value_loads_or_is_refused(tmp_path, doc):
    path = tmp_path / "fuzz.yaml"
    path.write_text(_dump(doc), encoding="utf-8")
    _load_or_refuse(path)


@FUZZ
@given(doc=scenario_like)
def test_any_scenario_shaped_document_loads_or_is_refused(tmp_path, doc):
    path = tmp_path / "fuzz.yaml"
    path.write_text(_dump(doc), encoding="utf-8")
    _load_or_refuse(path)


@FUZZ
@given(data=st.binary(max_size=600))
def test_any_bytes_load_or_are_refused(tmp_path, data):
    path = tmp_path / "fuzz.yaml"
    path.write_bytes(data)
    _load_or_refuse(path)


@FUZZ
@given(which=st.integers(0, len(SHIPPED) - 1),
       edits=st.lists(st.tuples(st.floats(0, 1), st.sampled_from(["delete", "insert", "replace"]),
                                st.sampled_from(list("0123456789.-+e:[]{},&*!|>'\"#\t\n x_") + ["inf", ".nan"])),
                      min_size=1, max_size=5))
def test_edited_scenarios_load_or_are_refused(tmp_path, which, edits):
    text = SHIPPED[which].read_text()
    for where, op, piece in edits:
        k = int(where * len(text))
        if op == "delete":
            text = text[:k] + text[k + 1:]
        elif op == "insert":
            text = text[:k] + piece + text[k:]
        else:
            text = text[:k] + piece + text[k + 1:]
    path = tmp_path / "fuzz.yaml"
    path.write_text(text, encoding="utf-8")
    _load_or_refuse(path)


json_values = st.recursive(
    st.one_of(st.none(), st.booleans(), st.integers(), st.floats(allow_nan=True, allow_infinity=True),
              st.text(max_size=20)),
    lambda inner: st.one_of(st.lists(inner, max_size=5), st.dictionaries(st.text(max_size=10), inner, max_size=5)),
    max_leaves=30,
)
plan_like = st.fixed_dictionaries({}, optional={
    "radius": st.one_of(numbers, scalars), "margin": st.one_of(numbers, scalars),
    "durations": st.one_of(st.lists(numbers, max_size=4), json_values),
    "waypoints": st.one_of(st.lists(points, max_size=4), json_values),
    "profile": st.one_of(st.just("minimum_jerk"), scalars), "max_speed": numbers, "max_accel": numbers,
    "seed": numbers, "stats": json_values,
})


def _plan_load_or_refuse(path: Path) -> None:
    t0 = time.perf_counter()
    try:
        plan, extra = read_plan_file(path)
        assert np.all(np.isfinite(plan.waypoints)) and np.all(plan.durations > 0)
        assert math.isfinite(plan.radius) and plan.radius > 0
    except PlanFileError as exc:
        text = str(exc)
        assert "\n" not in text and len(text) < 400, text[:500]
    assert time.perf_counter() - t0 < SECONDS


@FUZZ
@given(doc=st.one_of(json_values, plan_like))
def test_any_json_plan_loads_or_is_refused(tmp_path, doc):
    path = tmp_path / "plan.json"
    path.write_text(json.dumps(doc, allow_nan=True), encoding="utf-8")
    _plan_load_or_refuse(path)


@FUZZ
@given(data=st.binary(max_size=400))
def test_any_bytes_as_a_plan_load_or_are_refused(tmp_path, data):
    path = tmp_path / "plan.json"
    path.write_bytes(data)
    _plan_load_or_refuse(path)
