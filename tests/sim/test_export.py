"""``swarmform export``: samples read back exactly, polynomials re-evaluated against the plan."""

from __future__ import annotations

import csv
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from planner import Plan
from sim.output.export import POLY_HEADER, eval_piece, poly_pieces, sample_times

ROOT = Path(__file__).resolve().parents[2]
EXE = str(Path(sys.executable).parent / "swarmform")


def _swarmform(*args):
    return subprocess.run([EXE, *map(str, args)], check=False, capture_output=True, text=True, cwd=ROOT, timeout=120)


@pytest.fixture
def plan_file(tmp_path) -> Path:
    """Three robots over four steps; robot 2 stands still in steps 0 and 2, robot 1 in step 3."""
    w = np.array([
        [[1.0, 1.0], [5.0, 2.0], [9.0, 9.0]],
        [[3.5, 1.2], [6.0, 4.5], [9.0, 9.0]],
        [[3.5, 6.0], [2.0, 4.0], [7.3, 8.1]],
        [[8.0, 6.5], [2.5, 1.0], [7.3, 8.1]],
        [[8.0, 2.0], [2.5, 1.0], [1.0, 8.0]],
    ])
    return Plan.from_waypoints(w, 0.5, 0.1, 1.3, 0.9).save(tmp_path / "plan.json", extra={"seed": 0})


def _plan(path) -> Plan:
    return Plan.load(path)


def test_csv_is_exact_at_its_samples_and_ends_at_the_makespan(plan_file, tmp_path):
    out = tmp_path / "t.csv"
    r = _swarmform("export", plan_file, "--format", "csv", "--rate", "7", "-o", out)
    assert r.returncode == 0, r.stderr
    plan = _plan(plan_file)
    rows = list(csv.DictReader(out.open()))
    assert list(rows[0]) == ["robot", "t", "x", "y", "vx", "vy"]
    by_robot = {}
    for row in rows:
        by_robot.setdefault(int(row["robot"]), []).append([float(row[k]) for k in ("t", "x", "y", "vx", "vy")])
    assert sorted(by_robot) == [0, 1, 2]
    for i, got in by_robot.items():
        got = np.array(got)
        t = got[:, 0]
        assert t[0] == 0.0 and t[-1] == plan.makespan and np.all(np.diff(t) > 0)
        assert np.all(np.diff(t)[:-1] == pytest.approx(1 / 7))
        pos, vel, _ = plan.sample(t)
        assert np.array_equal(got[:, 1:3], pos[:, i]) and np.array_equal(got[:, 3:5], vel[:, i])


def test_origin_shifts_positions_only(plan_file, tmp_path):
    """``--origin X Y`` (a ROS map's origin): every position moved by (X, Y), exactly as the
    plan's own samples plus it; times and velocities unchanged; poly: the constant terms."""
    a, b = tmp_path / "a.csv", tmp_path / "b.csv"
    assert _swarmform("export", plan_file, "--rate", "3", "-o", a).returncode == 0
    r = _swarmform("export", plan_file, "--rate", "3", "--origin", "-10", "2.5", "-o", b)
    assert r.returncode == 0, r.stderr
    ra = np.array([[float(v) for v in row.values()] for row in csv.DictReader(a.open())])
    rb = np.array([[float(v) for v in row.values()] for row in csv.DictReader(b.open())])
    assert ra.shape == rb.shape
    np.testing.assert_array_equal(rb[:, :2], ra[:, :2])
    np.testing.assert_allclose(rb[:, 4:], ra[:, 4:], rtol=0, atol=1e-12)  # shifted ends round differently
    np.testing.assert_allclose(rb[:, 2:4], ra[:, 2:4] + [-10.0, 2.5], rtol=0, atol=1e-12)
    assert not np.allclose(rb[:, 2:4], ra[:, 2:4])  # control: the shift is there
    r = _swarmform("export", plan_file, "--format", "poly", "--origin", "-10", "2.5", "-o", tmp_path / "poly")
    assert r.returncode == 0, r.stderr
    plan = _plan(plan_file)
    first = next(csv.DictReader((tmp_path / "poly" / "robot000.csv").open()))
    assert float(first["x^0"]) == plan.waypoints[0, 0, 0] - 10.0
    assert float(first["y^0"]) == plan.waypoints[0, 0, 1] + 2.5


def test_the_plan_files_origin_is_the_default(plan_file, tmp_path):
    """A plan file's ``origin`` (``swarmform plan`` records a map's) shifts the export;
    ``--origin`` overrides it."""
    d = json.loads(plan_file.read_text())
    d["origin"] = [-12.5, -7.5]
    shifted_plan = tmp_path / "o.json"
    shifted_plan.write_text(json.dumps(d))
    outs = {}
    for key, args in (("none", [plan_file]), ("file", [shifted_plan]), ("zero", [shifted_plan, "--origin", "0", "0"])):
        r = _swarmform("export", *args, "--rate", "2", "-o", tmp_path / f"{key}.csv")
        assert r.returncode == 0, r.stderr
        outs[key] = np.array([[float(v) for v in row.values()] for row in csv.DictReader((tmp_path / f"{key}.csv").open())])
    np.testing.assert_array_equal(outs["zero"], outs["none"])
    np.testing.assert_allclose(outs["file"][:, 2:4], outs["none"][:, 2:4] + [-12.5, -7.5], rtol=0, atol=1e-12)


def test_json_is_exact_at_its_samples(plan_file):
    r = _swarmform("export", plan_file, "--format", "json")
    assert r.returncode == 0, r.stderr
    d = json.loads(r.stdout)
    plan = _plan(plan_file)
    assert d["rate"] == 20 and d["makespan"] == plan.makespan and len(d["robots"]) == plan.m
    for i, rob in enumerate(d["robots"]):
        t = np.array(rob["t"])
        assert t[-1] == plan.makespan and len(t) == len(sample_times(plan.makespan, 20))
        pos, vel, _ = plan.sample(t)
        for key, want in (("x", pos[:, i, 0]), ("y", pos[:, i, 1]), ("vx", vel[:, i, 0]), ("vy", vel[:, i, 1])):
            assert np.array_equal(rob[key], want), key


def _read_poly(path: Path) -> np.ndarray:
    lines = path.read_text().splitlines()
    assert lines[0] == POLY_HEADER
    return np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)


def _poly_error(rows: np.ndarray, plan: Plan, i: int, height: float) -> float:
    """Largest gap between the pieces and the plan (position and velocity, x and y; z; yaw)."""
    assert rows.shape == (plan.steps, 33)
    assert np.array_equal(rows[:, 0], plan.durations)
    worst = 0.0
    t0 = 0.0
    for _k, row in enumerate(rows):
        tau = np.linspace(0.0, row[0], 41)
        pos, vel, _ = plan.sample(t0 + tau)
        for axis, lo in ((0, 1), (1, 9)):
            p, v = eval_piece(row[lo:lo + 8], tau)
            worst = max(worst, np.abs(p - pos[:, i, axis]).max(), np.abs(v - vel[:, i, axis]).max())
        z, dz = eval_piece(row[17:25], tau)
        yaw, _ = eval_piece(row[25:33], tau)
        worst = max(worst, np.abs(z - height).max(), np.abs(dz).max(), np.abs(yaw).max())
        t0 += row[0]
    return worst


def test_poly_pieces_are_the_plan_exactly(plan_file, tmp_path):
    out = tmp_path / "poly"
    r = _swarmform("export", plan_file, "--format", "poly", "--height", "1.5", "-o", out)
    assert r.returncode == 0, r.stderr
    plan = _plan(plan_file)
    files = sorted(out.glob("robot*.csv"))
    assert [f.name for f in files] == ["robot000.csv", "robot001.csv", "robot002.csv"]
    for i, f in enumerate(files):
        rows = _read_poly(f)
        assert _poly_error(rows, plan, i, 1.5) < 1e-9
        assert np.all(rows[:, 7:9] == 0) and np.all(rows[:, 15:17] == 0)  # degree 5: x^6, x^7 zero
    still = _read_poly(files[2])[0]  # robot 2 stands still in step 0: a constant piece
    assert still[1] == 9.0 and np.all(still[2:9] == 0) and still[9] == 9.0 and np.all(still[10:17] == 0)


def test_a_perturbed_coefficient_is_caught(plan_file):
    """Negative control: the re-evaluation sees one coefficient changed by 1e-6."""
    plan = _plan(plan_file)
    pieces = poly_pieces(plan)
    assert _poly_error(pieces[0], plan, 0, 0.0) < 1e-9
    bad = pieces[0].copy()
    assert bad[1, 9 + 4] != 0  # robot 0 moves in y in step 1
    bad[1, 9 + 4] *= 1 + 1e-6  # y^4 of step 1
    assert _poly_error(bad, plan, 0, 0.0) > 1e-9


def test_a_perturbed_sample_is_caught(plan_file, tmp_path):
    """Negative control for the samples: one digit changed in the CSV no longer matches the plan."""
    out = tmp_path / "t.csv"
    assert _swarmform("export", plan_file, "-o", out).returncode == 0
    lines = out.read_text().splitlines()
    cells = lines[5].split(",")
    cells[2] = repr(float(cells[2]) + 1e-12)
    t, x = float(cells[1]), float(cells[2])
    pos, _, _ = _plan(plan_file).sample(np.array([t]))
    assert x != pos[0, int(cells[0]), 0]


def test_sample_times_end_at_the_makespan_once():
    assert sample_times(1.0, 4).tolist() == [0.0, 0.25, 0.5, 0.75, 1.0]
    assert sample_times(1.1, 4).tolist() == [0.0, 0.25, 0.5, 0.75, 1.0, 1.1]


@pytest.mark.parametrize("content, says", [
    ("{not json", "plan.json: "),
    ('{"radius": 1, "margin": 0.1, "durations": [1.0], "waypoints": [[[0, 0]]]}', "plan.json: "),
    ('{"radius": -1, "margin": 0.1, "durations": [], "waypoints": [[[0, 0]]]}', "radius"),
])
def test_bad_plan_file_is_one_line_exit_2(content, says, tmp_path):
    path = tmp_path / "plan.json"
    path.write_text(content)
    for fmt in ("csv", "json", "poly"):
        r = _swarmform("export", path, "--format", fmt, "-o", tmp_path / f"out-{fmt}")
        assert r.returncode == 2, r.stdout + r.stderr
        assert len(r.stderr.strip().splitlines()) == 1 and says in r.stderr
        assert not (tmp_path / f"out-{fmt}").exists()


@pytest.mark.parametrize("args, says", [
    (["--rate", "0"], "--rate"),
    (["--rate", "nan"], "--rate"),
    (["--format", "xml"], "--format"),
    (["--height", "inf"], "--height"),
    (["--origin", "nan", "0"], "--origin"),
    (["--origin", "1"], "--origin"),
    (["--origin", "1e10", "0"], "--origin"),
])
def test_bad_options_are_one_line_exit_2(args, says, plan_file):
    r = _swarmform("export", plan_file, *args)
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1 and says in r.stderr


def test_missing_plan_file_is_exit_2(tmp_path):
    r = _swarmform("export", tmp_path / "none.json")
    assert r.returncode == 2 and "none.json" in r.stderr and len(r.stderr.strip().splitlines()) == 1
