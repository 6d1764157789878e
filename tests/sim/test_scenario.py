"""Scenario files: every shipped scenario builds, deterministically, with documented defaults.

Every file under ``scenarios/`` is read and built with the generator made
from its seed; the problem must be valid (separated, clear robots, checked
here independently of the loader), and the same seed must give the same
bytes, in this process and in fresh interpreters with different hash seeds.
Small files written on the fly pin the defaults and the robot-count rules.
"""

from __future__ import annotations

import hashlib
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.distance import pdist

from planner.problem import Circle, Polygon, Problem
from sim.scenario import RandomObstacles, ScenarioError, build_problem, read_scenario

ROOT = Path(__file__).resolve().parents[2]
SCENARIO_FILES = sorted((ROOT / "scenarios").rglob("*.yaml"))
IDS = [str(p.relative_to(ROOT / "scenarios")) for p in SCENARIO_FILES]


def _build(path, seed=None):
    scenario = read_scenario(path)
    rng = np.random.default_rng(scenario.seed if seed is None else seed)
    return scenario, build_problem(scenario, rng)


def _write(tmp_path: Path, text: str, name: str = "case.yaml") -> Path:
    path = tmp_path / name
    path.write_text(textwrap.dedent(text), encoding="utf-8")
    return path


def _is_random(spec) -> bool:
    return spec.points is None and (
        spec.formation in ("random", "scatter") or spec.rotation is None or spec.center is None
        or (spec.text is not None and spec.fill == "area")  # Lloyd's relaxation starts from random pixels
    )


def _fingerprint(problem: Problem) -> bytes:
    parts = [problem.start.tobytes(), problem.target.tobytes()]
    for ob in problem.obstacles:
        parts.append(np.asarray(ob.vertices if isinstance(ob, Polygon) else [*ob.center, ob.radius]).tobytes())
    return b"".join(parts)


# ----------------------------------------------------------------------------
# the shipped scenarios


def test_there_are_scenarios():
    assert len(SCENARIO_FILES) >= 12
    assert {p.parent.name for p in SCENARIO_FILES} >= {"paper", "letters"}


@pytest.mark.parametrize("path", SCENARIO_FILES, ids=IDS)
def test_scenario_builds_a_valid_problem(path):
    scenario, problem = _build(path)
    assert isinstance(problem, Problem)
    assert problem.validate() is problem
    m = scenario.count
    assert problem.m == m >= 2
    assert problem.start.shape == problem.target.shape == (m, 2)
    assert (problem.width, problem.height) == (scenario.width, scenario.height)
    assert (problem.radius, problem.margin) == (scenario.radius, scenario.margin)
    sep, clear = 2 * scenario.radius + scenario.margin, scenario.radius + scenario.margin
    for pts in (problem.start, problem.target):
        assert np.all(np.isfinite(pts))
        assert pdist(pts).min() >= sep - 1e-9
        walls = np.minimum(pts, [scenario.width, scenario.height] - pts).min(axis=1)
        assert walls.min() >= clear - 1e-9
        assert problem.env.point_clearance(pts).min() >= clear - 1e-9
        for ob in problem.obstacles:
            if isinstance(ob, Circle):
                assert (np.linalg.norm(pts - ob.center, axis=1) - ob.radius).min() >= clear - 1e-9
    # the problem's arrays cannot be changed behind its back
    with pytest.raises(ValueError):
        problem.start[0, 0] = 0.0


@pytest.mark.parametrize("path", SCENARIO_FILES, ids=IDS)
def test_same_seed_gives_identical_bytes(path):
    _, a = _build(path)
    _, b = _build(path)
    assert a.start.tobytes() == b.start.tobytes()
    assert a.target.tobytes() == b.target.tobytes()
    assert _fingerprint(a) == _fingerprint(b)


@pytest.mark.parametrize("path", SCENARIO_FILES, ids=IDS)
def test_seed_moves_exactly_the_random_parts(path):
    """Another seed moves a randomly placed formation and leaves a fixed one alone."""
    scenario, a = _build(path, seed=1000)
    _, b = _build(path, seed=1001)
    random_obstacles = any(isinstance(o, RandomObstacles) and o.seed is None for o in scenario.obstacles)
    for key in ("start", "target"):
        same = np.array_equal(getattr(a, key), getattr(b, key))
        if _is_random(getattr(scenario, key)):
            assert not same, f"{key} is random but did not change with the seed"
        elif not random_obstacles:
            assert same, f"{key} is fixed but changed with the seed"


_HASH_SCRIPT = """
import hashlib, sys
from pathlib import Path
import numpy as np
from sim.scenario import build_problem, read_scenario
for path in sys.argv[1:]:
    s = read_scenario(path)
    p = build_problem(s, np.random.default_rng(s.seed))
    h = hashlib.sha256(p.start.tobytes() + p.target.tobytes())
    for ob in p.obstacles:
        h.update(repr(ob.to_dict()).encode())
    print(Path(path).name, h.hexdigest())
"""


def test_build_does_not_depend_on_the_hash_seed():
    """Two fresh interpreters with different PYTHONHASHSEED print the same bytes."""
    procs = []
    for hash_seed in ("0", "1"):
        env = dict(os.environ, PYTHONHASHSEED=hash_seed)
        procs.append(
            subprocess.Popen(
                [sys.executable, "-c", _HASH_SCRIPT, *map(str, SCENARIO_FILES)],
                cwd=ROOT,
                env=env,
                stdout=subprocess.PIPE,
                stderr=subprocess.PIPE,
                text=True,
            )
        )
    outs = []
    for proc in procs:
        out, err = proc.communicate(timeout=120)
        assert proc.returncode == 0, err
        outs.append(out)
    assert outs[0] == outs[1]
    assert len(outs[0].splitlines()) == len(SCENARIO_FILES)
    # and the same as this process computes
    line = outs[0].splitlines()[0].split()
    _, p = _build(SCENARIO_FILES[0])
    h = hashlib.sha256(p.start.tobytes() + p.target.tobytes())
    for ob in p.obstacles:
        h.update(repr(ob.to_dict()).encode())
    assert line == [SCENARIO_FILES[0].name, h.hexdigest()]


# ----------------------------------------------------------------------------
# defaults


def test_defaults_apply_when_omitted(tmp_path):
    path = _write(tmp_path, "start: {formation: A}\ntarget: {formation: A}\n", "minimal.yaml")
    s = read_scenario(path)
    assert s.name == "minimal"
    assert s.seed == 0
    assert (s.width, s.height) == (40.0, 40.0)
    assert (s.radius, s.margin) == (1.0, 0.1)
    assert s.count == 10
    assert s.obstacles == ()
    for spec in (s.start, s.target):
        assert spec.formation == "A"
        assert spec.scale == 0.3
        assert spec.rotation is None and spec.center is None and spec.points is None
    assert s.planner.g is None and s.planner.q is None
    assert s.planner.time_limit == 60.0
    problem = build_problem(s, np.random.default_rng(s.seed))
    assert problem.m == 10
    # the default seed is 0: building with it reproduces the file's problem
    again = build_problem(read_scenario(path), np.random.default_rng(0))
    assert again.start.tobytes() == problem.start.tobytes()


def test_explicit_values_override_the_defaults(tmp_path):
    path = _write(
        tmp_path,
        """
        name: custom
        seed: 9
        workspace: [30, 20]
        robots: {radius: 0.5, margin: 0.3, count: 6}
        start: {formation: line, scale: 0.5, rotation: 0, center: [15, 4]}
        target: {formation: random, scale: 0.4}
        planner: {g: 3, q: 20, time_limit: 5}
        """,
    )
    s = read_scenario(path)
    assert (s.name, s.seed, s.width, s.height) == ("custom", 9, 30.0, 20.0)
    assert (s.radius, s.margin, s.count) == (0.5, 0.3, 6)
    assert (s.start.scale, s.start.rotation, s.start.center) == (0.5, 0.0, (15.0, 4.0))
    assert s.target.scale == 0.4
    assert (s.planner.g, s.planner.q, s.planner.time_limit) == (3, 20, 5.0)
    p = build_problem(s, np.random.default_rng(s.seed))
    np.testing.assert_allclose(p.start[:, 1], 4.0)  # a horizontal line through the centre
    np.testing.assert_allclose(p.start.mean(axis=0), [15.0, 4.0])
    # the line is scale * min(W, H) = 10 long: robots 2 apart, 1.3 needed, no enlarging
    assert np.ptp(p.start[:, 0]) == pytest.approx(10.0)


# ----------------------------------------------------------------------------
# robot counts


@pytest.mark.parametrize(
    "start, target, count",
    [
        ("A", "A", 10),
        ("line", "phi", 11),
        ("random", "C", 7),
        ("M", "random", 11),
        ("lambda", "line", 7),
        ("N", "A", 10),  # both 10: no count needed
    ],
)
def test_count_from_table_one(tmp_path, start, target, count):
    path = _write(tmp_path, f"start: {{formation: {start}}}\ntarget: {{formation: {target}}}\n")
    s = read_scenario(path)
    assert s.count == count
    assert build_problem(s, np.random.default_rng(0)).m == count


def test_robots_count_overrides_table_one(tmp_path):
    path = _write(tmp_path, "robots: {count: 5}\nstart: {formation: A}\ntarget: {formation: M}\n")
    s = read_scenario(path)
    assert s.count == 5
    assert build_problem(s, np.random.default_rng(0)).m == 5


def test_count_from_points(tmp_path):
    path = _write(
        tmp_path,
        """
        start: {points: [[5, 5], [10, 5], [15, 5]]}
        target: {formation: line, rotation: 0, center: [20, 30]}
        """,
    )
    s = read_scenario(path)
    assert s.count == 3
    p = build_problem(s, np.random.default_rng(0))
    np.testing.assert_array_equal(p.start, [[5, 5], [10, 5], [15, 5]])
    assert p.target.shape == (3, 2)


def test_points_agreeing_with_robots_count(tmp_path):
    path = _write(
        tmp_path,
        """
        robots: {count: 2}
        start: {points: [[5, 5], [10, 5]]}
        target: {points: [[30, 30], [30, 35]]}
        """,
    )
    assert read_scenario(path).count == 2


@pytest.mark.parametrize(
    "text, field",
    [
        ("start: {formation: line}\ntarget: {formation: random}\n", "robots.count"),
        ("start: {formation: A}\ntarget: {formation: M}\n", "robots.count"),
        ("robots: {count: 1}\nstart: {formation: line}\ntarget: {formation: line}\n", "robots.count"),
        ("robots: {count: 4}\nstart: {points: [[5, 5], [10, 5]]}\ntarget: {formation: line}\n", "robots.count"),
        ("start: {points: [[5, 5], [10, 5]]}\ntarget: {points: [[5, 25]]}\n", "target.points"),
    ],
)
def test_count_errors_name_the_field(tmp_path, text, field):
    path = _write(tmp_path, text)
    with pytest.raises(ScenarioError) as info:
        read_scenario(path)
    assert info.value.field == field
    assert info.value.path == str(path)


# ----------------------------------------------------------------------------
# random obstacles and error records


def test_random_obstacles_are_seeded(tmp_path):
    text = """
        obstacles:
          - random: {count: 3, size: [3, 5]}
          - random: {count: 2, size: [2, 3], seed: 7}
        start: {points: [[5, 4], [10, 4], [15, 4], [20, 4], [25, 4], [30, 4]]}
        target: {points: [[5, 36], [10, 36], [15, 36], [20, 36], [25, 36], [30, 36]]}
        """
    path = _write(tmp_path, text)
    s = read_scenario(path)
    a = build_problem(s, np.random.default_rng(1))
    b = build_problem(s, np.random.default_rng(1))
    c = build_problem(s, np.random.default_rng(2))
    assert len(a.obstacles) == 5
    assert all(isinstance(o, Polygon) for o in a.obstacles)
    assert _fingerprint(a) == _fingerprint(b)
    # the first three follow the run's generator, the last two their own seed
    va = [o.vertices for o in a.obstacles]
    vc = [o.vertices for o in c.obstacles]
    assert not np.array_equal(va[0], vc[0])
    for u, v in zip(va[3:], vc[3:]):
        np.testing.assert_array_equal(u, v)
    # they keep clear of the explicit points
    for pts in (a.start, a.target):
        assert a.env.point_clearance(pts).min() >= s.radius + s.margin - 1e-9


def test_scenario_error_is_one_line_with_file_and_field(tmp_path):
    path = _write(tmp_path, "robots: {radius: -2}\nstart: {formation: A}\ntarget: {formation: A}\n")
    with pytest.raises(ScenarioError) as info:
        read_scenario(path)
    exc = info.value
    assert (exc.path, exc.field) == (str(path), "robots.radius")
    assert str(exc) == f"{path}: robots.radius: {exc.reason}"
    assert "\n" not in str(exc)
    assert "-2" in exc.reason
