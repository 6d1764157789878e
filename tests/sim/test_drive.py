"""Drive models (:mod:`sim.execute.drive`): each checked against its equations, with negative controls."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from planner.plan import Plan
from planner.problem import Problem
from sim.execute.drive import (
    DifferentialDrive,
    VelocityDrive,
    check_drive,
    drive_timing,
    initial_headings,
    timing_notes,
    unicycle_wheels,
)
from sim.execute.physics import execute
from sim.execute.realism import DelayLine
from sim.execute.world import build_world
from sim.scenario import ScenarioError
from sim.scenario.params import DriveParams, SimParams

H = 1.0 / 240.0  # the default physics step: dt / substeps


def _problem(start, target, size=20.0):
    return Problem(size, size, (), 0.5, 0.1, np.asarray(start, float), np.asarray(target, float))


def _plan(waypoints):
    w = np.asarray(waypoints, float)
    return Plan.from_waypoints(w, 0.5, 0.1, 2.0, 2.0)


def _bench(model: str, **drive):
    """One robot at (10, 10) in an empty world, with the drive of ``model`` and a hand-driven fake run."""
    problem = _problem([[10, 10]], [[10, 10]])
    params = SimParams(drive=DriveParams(model=model, **drive))
    world = build_world(problem, params)
    plan = _plan([[[10, 10]], [[12, 10]]])  # first motion along +x: heading 0
    cls = DifferentialDrive if model == "differential" else VelocityDrive
    drive = cls(world, params, plan)

    def state():
        return world.state()

    run = SimpleNamespace(h=H, working=np.ones(1, bool), line=DelayLine(0.0), valid=True, resist=False,
                          world=world, fresh_state=state)
    return world, drive, run


def _step(world, drive, run, t):
    drive.actuate(run, t)
    world.apply_forces()
    world.space.step(H)


# -- the differential drive ------------------------------------------------------


def test_turn_rate_and_speed_follow_the_wheels_and_nothing_moves_sideways():
    world, drive, run = _bench("differential", wheel_base=0.8, wheel_speed=3.0, wheel_accel=10.0)
    body = world.bodies[0]
    drive.cmd = np.array([[0.5, 1.5]])  # v_l, v_r: a left turn on an arc
    for k in range(300):
        th0, p0 = body.angle, np.array(body.position)
        _step(world, drive, run, k * H)
        vl, vr = drive.wheels[0]
        assert body.angle - th0 == pytest.approx((vr - vl) / 0.8 * H, abs=1e-12)
        assert body.angular_velocity == pytest.approx((vr - vl) / 0.8, abs=1e-12)
        d = np.array(body.position) - p0
        u = np.array([math.cos(th0), math.sin(th0)])
        assert abs(u[0] * d[1] - u[1] * d[0]) < 1e-12  # no sideways motion in this step
        assert float(u @ d) == pytest.approx(0.5 * (vl + vr) * H, abs=1e-12)
    assert drive.wheels[0] == pytest.approx([0.5, 1.5])  # reached at wheel_accel, then held
    assert body.angle == pytest.approx((1.5 - 0.5) / 0.8 * (300 * H) - _ramp_loss(0.5, 1.5, 10.0), abs=1e-9)


def _ramp_loss(vl, vr, accel):
    """Heading lost while the wheels ramp from rest at ``accel`` (discrete, one step of H at a time)."""
    loss, a, b = 0.0, 0.0, 0.0
    while (a, b) != (vl, vr):
        a, b = min(vl, a + accel * H), min(vr, b + accel * H)
        loss += ((vr - vl) - (b - a)) / 0.8 * H
    return loss


def test_wheel_speed_and_acceleration_limits_hold():
    world, drive, run = _bench("differential", wheel_base=0.8, wheel_speed=3.0, wheel_accel=10.0)
    drive.cmd = unicycle_wheels(np.array([[50.0, -40.0]]), np.zeros(1), 0.3, 0.8, 3.0)
    prev = np.zeros(2)
    for k in range(400):
        _step(world, drive, run, k * H)
        w = drive.wheels[0]
        assert np.all(np.abs(w) <= 3.0 + 1e-12)
        assert np.all(np.abs(w - prev) <= 10.0 * H + 1e-12)
        prev = w.copy()
    assert np.abs(prev).max() == pytest.approx(3.0)


def test_saturation_scales_both_wheels_and_keeps_the_curvature():
    u, th = np.array([[4.0, 3.0], [0.1, 0.0]]), np.array([0.3, 0.0])
    raw = unicycle_wheels(u, th, 0.3, 0.8, 1e9)
    sat = unicycle_wheels(u, th, 0.3, 0.8, 1.0)
    assert np.abs(sat[0]).max() == pytest.approx(1.0)
    assert sat[0] / np.abs(sat[0]).max() == pytest.approx(raw[0] / np.abs(raw[0]).max())
    assert sat[1] == pytest.approx(raw[1])  # below the limit: untouched
    # the look-ahead mapping: v = u . heading, omega = u . normal / lookahead
    v, omega = 0.5 * raw[0].sum(), (raw[0, 1] - raw[0, 0]) / 0.8
    assert v == pytest.approx(4 * math.cos(0.3) + 3 * math.sin(0.3))
    assert omega == pytest.approx((3 * math.cos(0.3) - 4 * math.sin(0.3)) / 0.3)


@pytest.mark.parametrize("lateral", [True, False])
def test_a_sideways_push_is_cancelled_only_with_the_lateral_constraint(lateral):
    """Negative control: without the constraint the same push moves the robot sideways."""
    world, drive, run = _bench("differential")
    drive.lateral = lateral
    body = world.bodies[0]
    drive.cmd = np.array([[1.0, 1.0]])
    for k in range(60):
        _step(world, drive, run, k * H)
    y0 = body.position.y
    body.apply_impulse_at_local_point((0.0, 0.5))  # along the body's y axis: sideways (heading 0)
    for k in range(60, 120):
        _step(world, drive, run, k * H)
    sideways = abs(body.position.y - y0)
    if lateral:
        assert sideways < 1e-12
    else:
        assert sideways > 0.1


# -- the velocity drive ----------------------------------------------------------


def _response(tau_true: float, steps: int) -> tuple[np.ndarray, np.ndarray]:
    world, drive, run = _bench("velocity", time_constant=tau_true, max_speed=3.0)
    drive.cmd = np.array([[1.0, 0.0]])
    t, v = [0.0], [0.0]
    for k in range(steps):
        _step(world, drive, run, k * H)
        t.append((k + 1) * H)
        v.append(world.bodies[0].velocity.x)
    return np.array(t), np.array(v)


def _reaches_63_percent_at(t, v, tau) -> bool:
    k = round(tau / H)
    return abs(t[k] - tau) < 1e-12 and v[k] == pytest.approx(1.0 - math.exp(-1.0), abs=1e-9)


def test_the_velocity_step_response_reaches_63_percent_at_tau():
    t, v = _response(0.25, 240)
    assert _reaches_63_percent_at(t, v, 0.25)
    assert v == pytest.approx(1.0 - np.exp(-t / 0.25), abs=1e-9)  # first order all along
    assert not _reaches_63_percent_at(t, v, 0.1)  # negative control: the wrong tau fails the check
    assert not _reaches_63_percent_at(*_response(0.1, 240), 0.25)


def test_velocity_set_points_are_saturated_at_max_speed():
    _, drive, _ = _bench("velocity", max_speed=1.5)
    assert np.hypot(*drive.command(np.array([[3.0, 4.0]]))[0]) == pytest.approx(1.5)
    assert drive.command(np.array([[0.3, 0.4]]))[0] == pytest.approx([0.3, 0.4])


# -- runs ------------------------------------------------------------------------


def _l_shape():
    start = [[2.0, 2.0], [2.0, 8.0]]
    w = [start, [[6.0, 2.0], [2.0, 12.0]], [[6.0, 6.0], [6.0, 12.0]]]
    return _problem(start, w[-1]), _plan(w)


@pytest.mark.parametrize("model", ["differential", "velocity"])
def test_a_drive_runs_in_the_realistic_loop_and_reaches_its_targets(model):
    problem, plan = _l_shape()
    params = SimParams(drive=DriveParams(model=model))
    assert params.realistic and not SimParams().realistic
    r = execute(problem, plan, params, np.random.default_rng(0))
    assert r.ok, r.verdict
    d = r.to_dict()
    assert d["drive"] == model and d["drive_timing"]["model"] == model
    if model == "differential":
        assert r.headings.shape == (len(r.times), 2)
        assert r.headings[0] == pytest.approx([0.0, math.pi / 2])  # along each robot's first motion
        assert r.headings[-1] == pytest.approx([math.pi / 2, 0.0], abs=0.05)
        assert "turning on the spot" in r.verdict
    else:
        assert r.headings is None and "turning" not in r.verdict


def test_holonomic_reports_have_no_drive_keys():
    problem, plan = _l_shape()
    d = execute(problem, plan, SimParams()).to_dict()
    assert "drive" not in d and "drive_timing" not in d
    assert drive_timing(plan, DriveParams()) is None and timing_notes(None) == []


def test_initial_headings_follow_the_first_motion():
    plan = _plan([[[0, 0], [5, 5], [9, 9]], [[0, 0], [5, 5], [9, 8]], [[0, 1], [5, 5], [9, 8]]])
    assert initial_headings(plan) == pytest.approx([math.pi / 2, 0.0, -math.pi / 2])


def test_drive_timing_counts_the_turns_on_the_spot_and_the_peak_speed():
    _, plan = _l_shape()
    d = DriveParams(model="differential", wheel_base=0.8, wheel_speed=3.0)
    t = drive_timing(plan, d)
    rate = 2 * 3.0 / 0.8
    assert t["max_turn_rate"] == pytest.approx(rate)
    assert t["corners"] == 2 and t["turn_time_lost_s"] == pytest.approx((math.pi / 2) / rate)
    assert t["worst_corner"]["step"] == 1 and t["worst_corner"]["angle_deg"] == pytest.approx(90.0)
    peak = max(15 / 8 * 4.0 / dur for dur in plan.durations)
    assert t["plan_peak_speed"] == pytest.approx(peak) and not t["speed_exceeded"]
    slow = drive_timing(plan, DriveParams(model="velocity", max_speed=0.5 * peak))
    assert slow["speed_exceeded"] and "turn_time_lost_s" not in slow
    assert "exceeds the velocity drive's top speed" in timing_notes(slow)[0]
    straight = _plan([[[2, 2]], [[6, 2]], [[9, 2]]])
    assert drive_timing(straight, d)["turn_time_lost_s"] == 0 and timing_notes(drive_timing(straight, d)) == []


def test_programmatic_params_are_checked():
    check_drive(DriveParams(model="velocity"))
    with pytest.raises(ValueError, match=r"sim\.drive\.model: must be one of holonomic, differential, velocity"):
        check_drive(DriveParams(model="tank"))
    with pytest.raises(ValueError, match=r"sim\.drive\.wheel_base: must be a number in \(0, 100\], got 0"):
        check_drive(DriveParams(wheel_base=0))
    problem, plan = _l_shape()
    with pytest.raises(ValueError, match=r"sim\.drive\.time_constant"):
        execute(problem, plan, SimParams(drive=DriveParams(model="velocity", time_constant=-1.0)))


# -- the scenario's sim.drive --------------------------------------------------------



def test_sim_drive_is_read_as_a_mapping_a_name_or_a_set_key(tmp_path, read_case):
    assert read_case("").sim.drive == DriveParams()
    got = read_case("sim: {drive: {model: differential, wheel_base: 1.2, wheel_speed: 2, lookahead: 0.5}}").sim
    assert got.drive == DriveParams(model="differential", wheel_base=1.2, wheel_speed=2.0, lookahead=0.5)
    assert read_case("sim: {drive: velocity}").sim.drive.model == "velocity"
    assert read_case("", {"sim.drive.model": "differential"}).sim.drive.model == "differential"


@pytest.mark.parametrize("body, message", [
    ("sim: {drive: {model: tank}}", "sim.drive.model: must be one of holonomic, differential, velocity"),
    ("sim: {drive: {model: differential, wheel_base: 0}}", "sim.drive.wheel_base: must be a number in (0, 100]"),
    ("sim: {drive: {model: differential, wheel_accel: -1}}", "sim.drive.wheel_accel"),
    ("sim: {drive: {model: velocity, time_constant: 20}}", "sim.drive.time_constant: must be a number in (0, 10]"),
    ("sim: {drive: {model: velocity, kp_v: -1}}", "sim.drive.kp_v: must be a number in [0, 1000]"),
    ("sim: {drive: {model: velocity, wheel_base: 1}}", "sim.drive.wheel_base: is not a setting of the velocity"),
    ("sim: {drive: {wheel_speed: 1}}", "sim.drive.wheel_speed: is not a setting of the holonomic drive"),
    ("sim: {drive: {modle: velocity}}", "sim.drive.modle: unknown key"),
])
def test_bad_drive_settings_name_the_field(tmp_path, body, message, read_case):
    with pytest.raises(ScenarioError) as exc:
        read_case(body)
    assert message in str(exc.value)


def test_frames_draw_headings(tmp_path):
    from sim.output.render import render_frames
    from sim.scenario.params import RenderParams

    problem, plan = _l_shape()
    r = execute(problem, plan, SimParams(drive=DriveParams(model="differential")), np.random.default_rng(0))
    params = RenderParams(size=200, trails=False)
    plain = render_frames(problem, r.times, r.positions, (), params)[0]
    drawn = render_frames(problem, r.times, r.positions, (), params, headings=r.headings)[0]
    assert plain.shape == drawn.shape and (plain != drawn).any()
    with pytest.raises(ValueError, match="headings must be"):
        render_frames(problem, r.times, r.positions, (), params, headings=r.headings[:, :1])


@pytest.mark.parametrize("model", ["differential", "velocity"])
def test_drives_take_the_filters_estimate_and_record_one_heading_per_sample(model):
    from sim.scenario.params import Noise

    problem, plan = _l_shape()
    params = SimParams(drive=DriveParams(model=model), noise=Noise(position=0.002), control_rate=50.0)
    r = execute(problem, plan, params, np.random.default_rng(3))
    assert not r.contacts and r.reached, r.verdict
    if model == "differential":
        assert r.headings.shape == (len(r.times), problem.m)
