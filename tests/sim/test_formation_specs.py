"""Scenario fields of the formations: strokes, scatter, ring, chained targets, their bounds.

Each field is read with its documented default and range; values outside
it are refused with ScenarioError naming the field (exit 2 through the
CLI, tested in the bad-input corpus too).  Chained targets build every
placement from one generator, deterministically, and a single target
draws exactly what it always drew.
"""

from __future__ import annotations

import textwrap
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.distance import pdist

from planner.strokes import drawing
from sim.scenario import ScenarioError, build_legs, build_problem, read_scenario

ROOT = Path(__file__).resolve().parents[2]


def _write(tmp_path: Path, text: str, name: str = "case.yaml") -> Path:
    path = tmp_path / name
    path.write_text(textwrap.dedent(text), encoding="utf-8")
    return path


def _fails(tmp_path, text, field, says=""):
    with pytest.raises(ScenarioError) as info:
        sc = read_scenario(_write(tmp_path, text))
        build_legs(sc, np.random.default_rng(sc.seed))
    assert info.value.field == field, str(info.value)
    assert says in info.value.reason, info.value.reason
    return info.value


# ----------------------------------------------------------------------------
# strokes


_STAR = "[[[0.5, 1], [0.2, 0], [1, 0.65], [0, 0.65], [0.8, 0], [0.5, 1]]]"


def test_strokes_scenario(tmp_path):
    sc = read_scenario(_write(tmp_path, f"""\
        workspace: [60, 60]
        start: {{formation: scatter}}
        target: {{formation: {{strokes: {_STAR}}}, scale: 0.6, center: [30, 30]}}
    """))
    assert sc.target.formation == "strokes" and sc.target.rotation == 0.0 and sc.target.scale == 0.6
    assert sc.target.describe() == "strokes (1)"
    problem = build_problem(sc, np.random.default_rng(0))
    assert problem.m == sc.count >= 10  # the default count: from the strokes' length
    assert pdist(problem.target).min() >= 2.1
    # read back: every robot on the star's outline, mapped back to the unit box
    t = problem.target
    unit = (t - t.min(axis=0)) / np.ptp(t, axis=0).max()
    star = drawing([np.array([[0.5, 1], [0.2, 0], [1, 0.65], [0, 0.65], [0.8, 0], [0.5, 1]])])
    lo = np.min([s.at(np.linspace(0, s.length, 200)) for s in star], axis=(0, 1))
    hi = np.max([s.at(np.linspace(0, s.length, 200)) for s in star], axis=(0, 1))
    unit = unit * float(np.max(hi - lo)) + lo
    dist = np.min([s.distance(unit) for s in star], axis=0)
    assert dist.max() < 0.02


@pytest.mark.parametrize(
    "strokes, field, says",
    [
        ("[]", "target.formation.strokes", "1 to 64 strokes"),
        ("[[[0, 0]]]", "target.formation.strokes[0]", "2 to 512 points"),
        ("[[[0, 0], [1.5, 0]]]", "target.formation.strokes[0][1]", "unit box"),
        ("[[[0, 0], [0.5, -0.1]]]", "target.formation.strokes[0][1]", "unit box"),
        ("[[[0, 0], [0.5]]]", "target.formation.strokes[0][1]", "pair"),
        ("[[[0, 0], [0, 0]]]", "target.formation.strokes", "zero length"),
        ("[[[0, 0], [1, 1]], 3]", "target.formation.strokes[1]", "2 to 512 points"),
        ("[[[0, 0], [1, .nan]]]", "target.formation.strokes[0][1][1]", "finite"),
    ],
)
def test_bad_strokes(tmp_path, strokes, field, says):
    _fails(tmp_path, f"""\
        robots: {{count: 8}}
        start: {{formation: line}}
        target: {{formation: {{strokes: {strokes}}}}}
    """, field, says)


def test_too_many_stroke_points(tmp_path):
    line = "[" + ", ".join(["[0.5, 0.5]"] * 511 + ["[0.6, 0.5]"]) + "]"
    _fails(tmp_path, f"""\
        robots: {{count: 8}}
        start: {{formation: line}}
        target: {{formation: {{strokes: [{", ".join([line] * 3)}]}}}}
    """, "target.formation.strokes", "more than 1024 points")


# ----------------------------------------------------------------------------
# scatter and ring


def test_scatter_and_ring_scenario(tmp_path):
    sc = read_scenario(_write(tmp_path, """\
        workspace: [50, 40]
        robots: {count: 24}
        obstacles: [{circle: {center: [25, 20], radius: 4}}]
        start: {formation: scatter, region: [0, 0, 20, 40]}
        target: {formation: ring, scale: 0.7, center: [25, 20]}
    """))
    assert sc.start.region == (0.0, 0.0, 20.0, 40.0) and sc.target.rotation is None
    p = build_problem(sc, np.random.default_rng(1))
    assert p.start[:, 0].max() <= 20.0
    r = np.linalg.norm(p.target - [25, 20], axis=1)
    assert np.ptp(r) < 0.05 * r.mean()  # around the disc


@pytest.mark.parametrize(
    "start, field, says",
    [
        ("{formation: scatter, scale: 0.5}", "start.scale", "does not apply to scatter"),
        ("{formation: scatter, rotation: 0}", "start.rotation", "does not apply to scatter"),
        ("{formation: scatter, center: [5, 5]}", "start.center", "does not apply to scatter"),
        ("{formation: scatter, region: [0, 0, 50, 10]}", "start.region", "inside the workspace"),
        ("{formation: scatter, region: [10, 0, 5, 10]}", "start.region", "x0 < x1"),
        ("{formation: scatter, region: [0, 0, 10]}", "start.region", "[x0, y0, x1, y1]"),
        ("{formation: scatter, region: [0, 0, 10, a]}", "start.region[3]", "number"),
        ("{formation: line, region: [0, 0, 10, 10]}", "start.region", "scatter only"),
        ("{formation: scatter, region: [0, 0, 6, 6]}", "start", "at most"),
        ("{formation: scatter, hold: 2}", "start.hold", "unknown key"),
    ],
)
def test_bad_scatter(tmp_path, start, field, says):
    _fails(tmp_path, f"""\
        workspace: [40, 40]
        robots: {{count: 12}}
        start: {start}
        target: {{formation: line}}
    """, field, says)


def test_too_many_to_scatter_exits_2(tmp_path):
    """Through the CLI: exit 2, one line with the field and the achievable maximum."""
    import subprocess
    import sys

    path = _write(tmp_path, """\
        workspace: [30, 30]
        robots: {count: 150}
        start: {formation: scatter}
        target: {formation: scatter}
    """)
    exe = str(Path(sys.executable).parent / "swarmform")
    r = subprocess.run([exe, "show", str(path), "-o", str(tmp_path / "x.png")], capture_output=True, text=True)
    assert r.returncode == 2, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and f"{path}: start: scatter: 150 robots do not fit" in lines[0]
    assert "at most" in lines[0] and not (tmp_path / "x.png").exists()


# ----------------------------------------------------------------------------
# chained targets


_CHAIN = """\
    workspace: [50, 50]
    robots: {count: 16}
    obstacles: [{polygon: [[22, 22], [28, 22], [28, 28], [22, 28]]}]
    start: {formation: line, rotation: 0, center: [25, 8]}
    targets:
      - {formation: ring, scale: 0.6, center: [25, 25]}
      - {formation: {text: HI}, scale: 0.3, center: [25, 40], hold: 1.5}
      - {formation: scatter, hold: 0}
"""


def test_chained_targets_build_every_placement(tmp_path):
    sc = read_scenario(_write(tmp_path, _CHAIN))
    assert [t.describe() for t in sc.legs] == ["ring", "text 'HI'", "scatter"]
    assert [t.hold for t in sc.targets] == [2.0, 1.5, 0.0]
    assert sc.target is sc.targets[-1]
    assert sc.describe() == "line -> ring -> text 'HI' -> scatter"
    problem, targets = build_legs(sc, np.random.default_rng(0))
    assert len(targets) == 3
    np.testing.assert_array_equal(problem.target, targets[-1])
    for t in targets:
        assert t.shape == (16, 2) and pdist(t).min() >= 2.1
        assert problem.env.point_clearance(t).min() >= 1.1
    again = build_legs(sc, np.random.default_rng(0))[1]
    assert all(a.tobytes() == b.tobytes() for a, b in zip(targets, again))


def test_single_target_builds_as_before(tmp_path):
    """build_problem of a one-target file draws the same numbers whether or not legs exist."""
    path = ROOT / "scenarios" / "paper" / "fig2-random-to-C.yaml"
    sc = read_scenario(path)
    rng_a, rng_b = np.random.default_rng(4), np.random.default_rng(4)
    a = build_problem(sc, rng_a)
    b, legs = build_legs(sc, rng_b)
    assert a.target.tobytes() == b.target.tobytes() == legs[0].tobytes()
    assert rng_a.integers(1 << 60) == rng_b.integers(1 << 60)


@pytest.mark.parametrize(
    "body, field, says",
    [
        ("target: {formation: line}\ntargets: [{formation: ring}]", "targets", "not both"),
        ("targets: []", "targets", "1 to 16"),
        ("targets: {formation: ring}", "targets", "1 to 16"),
        ("targets: [" + ", ".join(["{formation: ring}"] * 17) + "]", "targets", "1 to 16"),
        ("targets: [{formation: ring, hold: -1}]", "targets[0].hold", "in [0, 60]"),
        ("targets: [{formation: ring, hold: 61}]", "targets[0].hold", "in [0, 60]"),
        ("targets: [{formation: ring}, {formation: kite}]", "targets[1].formation", "unknown formation"),
        ("targets: [{points: [[5, 5], [9, 5]]}]", "targets[0].points", "has 2 robots"),
        ("", "target", "is required"),
    ],
)
def test_bad_chains(tmp_path, body, field, says):
    _fails(tmp_path, "robots: {count: 3}\nstart: {points: [[5, 5], [10, 5], [15, 5]]}\n" + body, field, says)


def test_chain_count_defaults_must_agree(tmp_path):
    _fails(tmp_path, """\
        workspace: [60, 60]
        start: {formation: A}
        targets: [{formation: M}]
    """, "robots.count", "count mismatch: start A has 10 robots, targets[0] M has 11")


def test_chain_count_comes_from_any_leg(tmp_path):
    sc = read_scenario(_write(tmp_path, """\
        workspace: [60, 60]
        start: {formation: scatter}
        targets: [{formation: ring}, {formation: phi}, {formation: line}]
    """))
    assert sc.count == 11


def test_scale_fit_fills_the_workspace(tmp_path):
    """scale: fit (any shape): the unrotated box fills 90 % of the workspace less the wall clearance."""
    sc = read_scenario(_write(tmp_path, """\
        workspace: [60, 30]
        robots: {count: 10}
        start: {formation: line, scale: fit, rotation: 0, center: [30, 10]}
        target: {formation: ring, scale: fit, center: [30, 15]}
    """))
    assert sc.start.scale is None and sc.target.scale is None
    p = build_problem(sc, np.random.default_rng(0))
    assert np.ptp(p.start[:, 0]) == pytest.approx(0.9 * (60 - 2.2))  # a line: its width binds
    assert np.ptp(p.target, axis=0).max() <= 0.9 * (30 - 2.2) + 1e-9  # a ring: the height binds
    assert np.ptp(p.target, axis=0).max() >= 0.8 * (30 - 2.2)
