"""The held-out benchmark's worlds: valid, reproducible per seed, different across seeds."""

import math
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
if str(ROOT) not in sys.path:  # bench/ is a folder of the repository, not an installed package
    sys.path.insert(0, str(ROOT))

from bench import heldout  # noqa: E402
from bench import heldout_worlds as hw  # noqa: E402
from planner import Problem  # noqa: E402

BUILDERS = {
    "letter": lambda seed: hw.letter_problem(30, seed),
    "random": lambda seed: hw.random_problem(40, seed),
    "door": lambda seed: hw.door_problem(2.2, 20, seed),
    "map": lambda seed: hw.map_problem("room-64-64-8", 40, seed),
}


def _arrays(p):
    return [p.start, p.target, np.array([p.width, p.height])] + [np.asarray(o.vertices) for o in p.obstacles]


def _same(a, b) -> bool:
    xs, ys = _arrays(a), _arrays(b)
    return len(xs) == len(ys) and all(x.shape == y.shape and np.array_equal(x, y) for x, y in zip(xs, ys))


@pytest.mark.parametrize("family", sorted(BUILDERS))
def test_worlds_validate_and_repeat(family):
    build = BUILDERS[family]
    a, again, other = build(0), build(0), build(1)
    assert a.validate() is a and other.validate() is other
    assert _same(a, again)  # same seed, same arrays
    assert not _same(a, other)  # negative control: another seed, another world


def test_negative_control_detects_a_changed_array():
    a = BUILDERS["random"](0)
    moved = Problem(a.width, a.height, a.obstacles, a.radius, a.margin, a.start + [0.0, 1e-9], a.target)
    assert not _same(a, moved)


def test_door_is_never_narrower_than_asked():
    for seed in range(20):
        rng = np.random.default_rng(seed)
        _, width = hw.door_walls(60.0, 10.0, 12.0, float(rng.uniform(0.5, 50.0)), 2.2)
        assert width >= 2.2
    p = hw.door_problem(2.2, 20, 0)
    lo, hi = sorted(p.obstacles, key=lambda o: o.vertices[:, 1].min())
    assert hi.vertices[:, 1].min() - lo.vertices[:, 1].max() >= 2.2
    assert np.all(p.start[:, 0] < lo.vertices[:, 0].min()) and np.all(p.target[:, 0] > lo.vertices[:, 0].max())


@pytest.mark.parametrize("seed", range(6))
def test_narrowest_door_lets_a_centre_through_in_floating_point(seed):
    p = hw.door_problem(2.2, 20, seed)
    lo, hi = sorted(p.obstacles, key=lambda o: o.vertices[:, 1].min())
    y0, y1 = lo.vertices[:, 1].max(), hi.vertices[:, 1].min()
    assert 2.2 <= y1 - y0 < 2.2 + 1e-12  # the limit, up to a few ulps
    xs = np.linspace(lo.vertices[:, 0].min(), lo.vertices[:, 0].max(), 9)
    ys = [y0 + (y1 - y0) / 2 + k * np.spacing(y1) for k in (-1, 0, 1)]
    assert max(p.env.point_clearance(np.stack([xs, np.full(9, y)], axis=1)).min() for y in ys) >= p.clearance


def test_letter_line_is_not_axis_aligned_and_glyphs_vary():
    glyphs = set()
    for seed in range(12):
        p, glyph = hw.letter_world(30, seed)
        glyphs.add(glyph)
        d = p.start[-1] - p.start[0]
        angle = math.degrees(math.atan2(d[1], d[0])) % 90.0
        assert 9.0 < angle < 81.0
    assert len(glyphs) >= 3 and glyphs <= set(hw.GLYPHS)


def test_map_cells_are_distinct_free_cells():
    p = hw.map_problem("maze-32-32-2", 60, 3)
    for pts in (p.start, p.target):
        assert len(np.unique(np.round(pts, 6), axis=0)) == len(pts)


def test_judge_and_cases():
    names = [c.name for c in heldout.CASES]
    assert len(names) == len(set(names))
    assert {c.family for c in heldout.CASES} == {"letter", "random", "door", "map"}
    case = next(c for c in heldout.CASES if c.name == "map-room-32-32-4-m400")
    assert heldout.judge(case, {"ok": True, "time_s": 29.0, "x_geo": 1.9}, 60)[1] == "yes"
    assert heldout.judge(case, {"ok": True, "time_s": 31.0, "x_geo": 1.9}, 60)[1] == "no"
    assert heldout.judge(case, {"ok": True, "time_s": 1.0, "x_geo": 2.1}, 60)[1] == "no"
    assert heldout.judge(case, {"ok": True, "time_s": 1.0, "x_geo": math.nan}, 60)[1] == "?"
    assert heldout.judge(case, {"ok": False, "time_s": 1.0}, 60)[1] == "no"
    door = next(c for c in heldout.CASES if c.name == "door-2.2-m200")
    assert heldout.judge(door, {"ok": True, "x_cut": 2.9}, 60)[1] == "yes"
    assert heldout.judge(door, {"ok": True, "x_cut": 3.1}, 60)[1] == "no"
    assert heldout.judge(door, {"ok": False}, 60)[1] == "no"
    wider = next(c for c in heldout.CASES if c.name == "door-2.6-m200")
    assert heldout.judge(wider, {"ok": True, "x_cut": 4.0}, 60)[1] == "yes"  # solved is the target there


def test_help_runs(capsys):
    with pytest.raises(SystemExit) as exc:
        heldout.main(["--help"])
    assert exc.value.code == 0
    assert "--quick" in capsys.readouterr().out
