"""The scenario's realism fields (``sim:``) and ``planner.margin_extra``: read, defaulted, bounded."""

from __future__ import annotations

import textwrap

import pytest

from sim.cli import main
from sim.scenario import ScenarioError, read_scenario
from sim.scenario.params import Failure, Impulse, Noise, Pushes, Recovery, SimParams

HEAD = """
name: case
workspace: [20, 20]
robots: {radius: 1.0, margin: 0.1, count: 4}
start: {formation: line, rotation: 0, center: [10, 5]}
target: {formation: line, rotation: 0, center: [10, 15]}
"""


def _write(tmp_path, body: str):
    path = tmp_path / "case.yaml"
    path.write_text(textwrap.dedent(HEAD) + textwrap.dedent(body), encoding="utf-8")
    return path


def test_defaults_are_ideal_robots(tmp_path):
    sc = read_scenario(_write(tmp_path, ""))
    assert sc.sim == SimParams() and not sc.sim.realistic
    assert sc.sim.force_limit == 200.0 and sc.sim.control_rate is None
    assert sc.planner.margin_extra == 0.0


def test_every_field_is_read(tmp_path):
    sc = read_scenario(_write(tmp_path, """
        planner: {margin_extra: 0.2}
        sim:
          force_limit: 20
          control_rate: 50
          latency: 0.04
          noise: {position: 0.02, velocity: 0.03}
          mass_error: 0.1
          friction: 0.2
          disturbances:
            - {robot: 3, time: 5.0, impulse: [4.0, 0.0]}
          pushes: {rate: 0.05, impulse: 2.0}
          failures:
            - {robot: 2, time: 8.0}
          recovery: {replan: true, trigger: 0.05, time_limit: 3, max_replans: 4}
    """))
    s = sc.sim
    assert s.realistic
    assert (s.force_limit, s.control_rate, s.latency, s.mass_error, s.friction) == (20, 50, 0.04, 0.1, 0.2)
    assert s.noise == Noise(0.02, 0.03)
    assert s.disturbances == (Impulse(3, 5.0, (4.0, 0.0)),)
    assert s.pushes == Pushes(0.05, 2.0)
    assert s.failures == (Failure(2, 8.0),)
    assert s.recovery == Recovery(True, 0.05, 3.0, 4)
    assert sc.planner.margin_extra == 0.2


@pytest.mark.parametrize("rate", [0, "null"])
def test_control_rate_zero_or_null_is_every_control_step(tmp_path, rate):
    assert read_scenario(_write(tmp_path, f"sim: {{control_rate: {rate}}}\n")).sim.control_rate is None


@pytest.mark.parametrize("body, field, words", [
    ("sim: {force_limit: 0}", "sim.force_limit", "in (0, 1e+06]"),
    ("sim: {control_rate: 0.5}", "sim.control_rate", "in [1, 10000]"),
    ("sim: {control_rate: 1000000}", "sim.control_rate", "in [1, 10000]"),
    ("sim: {latency: -0.1}", "sim.latency", "in [0, 1]"),
    ("sim: {latency: 2}", "sim.latency", "in [0, 1]"),
    ("sim: {noise: {position: -1}}", "sim.noise.position", "in [0, 10]"),
    ("sim: {noise: {acceleration: 1}}", "sim.noise.acceleration", "unknown key"),
    ("sim: {noise: 0.1}", "sim.noise", "must be a mapping"),
    ("sim: {mass_error: 0.95}", "sim.mass_error", "in [0, 0.9]"),
    ("sim: {friction: 11}", "sim.friction", "in [0, 10]"),
    ("sim: {disturbances: [{robot: 4, time: 1, impulse: [1, 0]}]}", "sim.disturbances[0].robot", "below 4"),
    ("sim: {disturbances: [{robot: 0, time: 1}]}", "sim.disturbances[0].impulse", "required"),
    ("sim: {disturbances: [{robot: 0, time: 1, impulse: [100000, 0]}]}", "sim.disturbances[0].impulse", "1e4"),
    ("sim: {disturbances: [{robot: 0, time: -1, impulse: [1, 0]}]}", "sim.disturbances[0].time", "in [0, 100000]"),
    ("sim: {disturbances: {robot: 0}}", "sim.disturbances", "must be a list"),
    ("sim: {pushes: {rate: 1000, impulse: 1}}", "sim.pushes.rate", "in [0, 100]"),
    ("sim: {failures: [{robot: 1, time: 1}, {robot: 1, time: 2}]}", "sim.failures[1].robot", "already fails"),
    ("sim: {failures: [{robot: -1, time: 1}]}", "sim.failures[0].robot", ">= 0"),
    ("sim: {recovery: {replan: yes please}}", "sim.recovery.replan", "true or false"),
    ("sim: {recovery: {trigger: 0}}", "sim.recovery.trigger", "in (0, 100]"),
    ("sim: {recovery: {max_replans: 1000}}", "sim.recovery.max_replans", "<= 100"),
    ("sim: {recovery: {time_limit: 1000000000}}", "sim.recovery.time_limit", "in (0, 600]"),
    ("planner: {margin_extra: -0.1}", "planner.margin_extra", "in [0, 100]"),
    ("planner: {margin_extra: 1000}", "planner.margin_extra", "in [0, 100]"),
])
def test_bad_values_name_the_field(tmp_path, body, field, words):
    path = _write(tmp_path, body + "\n")
    with pytest.raises(ScenarioError) as info:
        read_scenario(path)
    assert info.value.field == field
    assert words in info.value.reason


def test_cli_exit_code_2_for_a_bad_realism_field(tmp_path, capsys):
    path = _write(tmp_path, "sim: {failures: [{robot: 9, time: 1}]}\n")
    assert main(["run", str(path), "--no-render", "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "sim.failures[0].robot" in err[0]
    assert not (tmp_path / "out").exists()


def test_margin_extra_that_does_not_fit_the_placements_is_bad_input(tmp_path, capsys):
    # Explicit points 2.2 apart: fine for the margin 0.1, not for 0.1 + 1.
    path = tmp_path / "points.yaml"
    path.write_text(textwrap.dedent("""
        workspace: [20, 20]
        robots: {radius: 1.0, margin: 0.1}
        start: {points: [[5, 5], [7.2, 5]]}
        target: {points: [[5, 15], [9, 15]]}
        planner: {margin_extra: 1.0}
    """), encoding="utf-8")
    assert main(["run", str(path), "--no-render", "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "planner.margin_extra" in err[0] and "start[0]" in err[0]


def test_formations_are_spaced_for_the_planning_margin(tmp_path):
    import numpy as np
    from scipy.spatial.distance import pdist

    from sim.scenario import build_problem

    sc = read_scenario(_write(tmp_path, "planner: {margin_extra: 0.5}\n"))
    problem = build_problem(sc, np.random.default_rng(0))
    assert problem.margin == 0.1  # the problem keeps the real margin
    assert pdist(problem.start).min() >= 2 * 1.0 + 0.1 + 0.5 - 1e-9
