"""Video frames of recorded runs: size, motion, colours, contacts, playback speed."""

from dataclasses import dataclass, replace

import numpy as np
import pytest

from planner.problem import Circle, Polygon, Problem
from sim.params import RenderParams
from sim.render import (
    CONTACT,
    Canvas,
    draw_scenario,
    frame_times,
    playback_speedup,
    render_frames,
    robot_colors,
)


@dataclass(frozen=True)
class Contact:
    time: float
    kind: str
    a: int
    b: int
    depth: float = 0.02
    witness: tuple | None = None


def _problem(m=4, radius=0.5, width=10.0, height=8.0):
    xs = np.linspace(2.0, width - 2.0, m)
    start = np.stack([xs, np.full(m, 3.0)], 1)
    target = np.stack([xs, np.full(m, 6.0)], 1)
    obstacles = (Polygon(np.array([[4.5, 4.2], [5.5, 4.2], [5.5, 4.8], [4.5, 4.8]])), Circle((1.0, 7.0), 0.4))
    return Problem(width, height, obstacles, radius, 0.05, start, target)


def _recording(problem, seconds=10.0, rate=60.0):
    """Robots go straight up from start to target over the whole run."""
    t = np.arange(0.0, seconds + 1e-9, 1.0 / rate)
    u = (t / seconds)[:, None, None]
    return t, problem.start[None] + u * (problem.target - problem.start)[None]


def _params(**kw):
    return replace(RenderParams(fps=10, size=200, trails=True, speedup=None, video_seconds=5.0), **kw)


def _is_red(img):
    r, g, b = (img[..., k].astype(int) for k in range(3))
    return (r > 200) & (g < 60) & (b < 60)


def _at(t, pos, time):
    """Robot centres ``(m, 2)`` at ``time``, interpolated from the recording."""
    return np.stack([[np.interp(time, t, pos[:, i, d]) for d in (0, 1)] for i in range(pos.shape[1])])


def _frame_at(frames, ft, time):
    """The index of the first drawn frame showing ``time`` or later."""
    return int(np.flatnonzero(ft >= time - 1e-9)[0])


def test_frames_are_even_uint8_rgb():
    p = _problem()
    t, pos = _recording(p)
    for size in (200, 151):
        frames = list(render_frames(p, t, pos, [], _params(size=size)))
        h, w = frames[0].shape[:2]
        assert h % 2 == 0 and w % 2 == 0
        for f in frames:
            assert f.dtype == np.uint8 and f.shape == (h, w, 3)
        cv = Canvas(p, size)
        assert (h, w) == (cv.height_px, cv.width_px)


def test_frames_change_when_robots_move_and_not_when_they_stay():
    p = _problem()
    t, pos = _recording(p)
    cv = Canvas(p, 200)
    moving = list(render_frames(p, t, pos, [], _params()))
    still = list(render_frames(p, t, np.broadcast_to(pos[:1], pos.shape), [], _params()))
    ws = slice(cv.header, None)  # the workspace, below the header band
    assert not np.array_equal(moving[0][ws], moving[5][ws])
    assert np.array_equal(still[0][ws], still[5][ws])
    # the header (sim time) changes in both
    assert not np.array_equal(still[0][: cv.header], still[5][: cv.header])


@pytest.mark.parametrize("radius", [0.15, 0.6])
def test_each_disc_has_its_robot_colour(radius):
    p = _problem(m=5, radius=radius)
    t, pos = _recording(p)
    params = _params(size=240)
    frames = list(render_frames(p, t, pos, [], params))
    ft = frame_times(t[-1], playback_speedup(t[-1], params), params.fps)
    cv = Canvas(p, params.size)
    colors = robot_colors(p.m)
    assert len(set(colors)) == p.m
    for k in (0, len(frames) // 3):
        for i, (x, y) in enumerate(cv.to_px(_at(t, pos, ft[k]))):
            if cv.r_px < 6:  # no label: the centre pixel is the robot's colour
                assert tuple(frames[k][int(y), int(x)]) == colors[i]
            else:  # a label sits at the centre: the colour still fills most of the disc
                yy, xx = np.mgrid[-cv.r_px : cv.r_px + 1, -cv.r_px : cv.r_px + 1]
                inside = (xx**2 + yy**2) <= (0.8 * cv.r_px) ** 2
                patch = frames[k][int(y) + yy[inside], int(x) + xx[inside]]
                assert np.mean(np.all(patch == colors[i], axis=1)) > 0.5


def test_contact_turns_the_robots_red_only_from_its_time_on():
    p = _problem(m=4)
    t, pos = _recording(p)
    params = _params()
    tc = 4.0
    contacts = [Contact(tc, "robot-robot", 1, 2), Contact(tc, "robot-wall", 3, -1)]
    frames = list(render_frames(p, t, pos, contacts, params))
    ft = frame_times(t[-1], playback_speedup(t[-1], params), params.fps)
    cv = Canvas(p, params.size)
    hit = _frame_at(frames, ft, tc)
    r = cv.r_px + 3

    def red_near(k, i):
        x, y = cv.to_px(_at(t, pos, ft[k])[i])[0]
        return _is_red(frames[k][int(y) - r : int(y) + r + 1, int(x) - r : int(x) + r + 1]).any()

    ws = slice(cv.header, None)
    for k in range(hit):  # before the contact: no red anywhere, header included
        assert not _is_red(frames[k]).any(), f"frame {k} at t = {ft[k]:.2f} s has red pixels"
    for i in (1, 2, 3):
        assert red_near(hit, i)
    assert not red_near(hit, 0)
    # the wall contact point: red on the wall nearest to robot 3 (at x = 8: the right wall)
    x3 = cv.to_px(np.array([p.width, _at(t, pos, tc)[3, 1]]))[0]
    near_wall = frames[hit][int(x3[1]) - 4 : int(x3[1]) + 5, int(x3[0]) - 4 : int(x3[0]) + 5]
    assert _is_red(near_wall).any()
    # the header counts contacts from then on, the flash ends after half a video second
    assert _is_red(frames[hit][: cv.header]).any()
    late = _frame_at(frames, ft, tc + 0.5 * playback_speedup(t[-1], params) + 0.5)
    assert not _is_red(frames[late][ws]).any()
    assert _is_red(frames[late][: cv.header]).any()


def test_contact_witness_marks_the_obstacle_point():
    p = _problem(m=2)
    t, pos = _recording(p)
    params = _params()
    w = (5.0, 4.8)  # on the top edge of the box obstacle
    frames = list(render_frames(p, t, pos, [Contact(2.0, "robot-obstacle", 0, 0, witness=w)], params))
    ft = frame_times(t[-1], playback_speedup(t[-1], params), params.fps)
    cv = Canvas(p, params.size)
    x, y = cv.to_px(w)[0].astype(int)
    k = _frame_at(frames, ft, 2.0)
    assert _is_red(frames[k][y - 1 : y + 2, x - 1 : x + 2]).all()
    assert not _is_red(frames[k - 1][y - 1 : y + 2, x - 1 : x + 2]).any()


def test_auto_speedup_fits_the_video_length():
    p = _problem()
    for seconds, video in ((120.0, 10.0), (47.0, 8.0), (300.0, 20.0)):
        t, pos = _recording(p, seconds=seconds, rate=20.0)
        params = _params(video_seconds=video, size=128)
        s = playback_speedup(seconds, params)
        assert s >= 1
        mant = s / 10 ** np.floor(np.log10(s))
        assert any(np.isclose(mant, v) for v in (1, 1.5, 2, 2.5, 3, 4, 5, 6, 8))
        n = sum(1 for _ in render_frames(p, t, pos, [], params))
        hold = params.fps
        assert abs((n - hold) / (params.fps * video) - 1) < 0.25


def test_short_runs_play_in_real_time_and_the_end_is_held():
    p = _problem()
    t, pos = _recording(p, seconds=2.05)
    params = _params(video_seconds=20.0)
    assert playback_speedup(2.05, params) == 1.0
    ft = frame_times(2.05, 1.0, params.fps)
    drawn = ft[: len(ft) - params.fps]
    assert drawn[-1] == pytest.approx(2.05) and drawn[-2] == pytest.approx(2.0)
    assert np.all(ft[-params.fps :] == pytest.approx(2.05))
    frames = list(render_frames(p, t, pos, [], params))
    assert len(frames) == len(ft)
    assert np.array_equal(frames[-1], frames[-params.fps - 1])


def test_explicit_speedup_is_used():
    p = _problem()
    t, pos = _recording(p, seconds=10.0)
    params = _params(speedup=2.0)
    frames = list(render_frames(p, t, pos, [], params))
    assert len(frames) == 10.0 / 2.0 * params.fps + 1 + params.fps


def test_text_stays_in_the_header():
    p = _problem()
    t, pos = _recording(p)
    a = list(render_frames(p, t, pos, [], _params(), title="x"))
    b = list(
        render_frames(
            p, t, pos, [], _params(), title="a very long title " * 10, step_times=np.array([0.0, 3.0, 7.0, 10.0])
        )
    )
    cv = Canvas(p, 200)
    for fa, fb in zip(a, b):
        assert np.array_equal(fa[cv.header :], fb[cv.header :])
    assert not np.array_equal(a[0][: cv.header], b[0][: cv.header])


def test_trails_follow_the_robots():
    p = _problem()
    t, pos = _recording(p)
    cv = Canvas(p, 200)
    with_trails = list(render_frames(p, t, pos, [], _params(trails=True)))
    without = list(render_frames(p, t, pos, [], _params(trails=False)))
    assert np.array_equal(with_trails[0], without[0])  # nothing to trail yet
    k = len(with_trails) // 2
    diff = np.any(with_trails[k] != without[k], axis=2)
    assert diff[cv.header :].any()
    assert not diff[: cv.header].any()


def test_bad_input_is_named():
    p = _problem()
    t, pos = _recording(p)
    with pytest.raises(ValueError, match="positions"):
        render_frames(p, t, pos[:, :2], [], _params())
    with pytest.raises(ValueError, match="times"):
        render_frames(p, t[::-1], pos, [], _params())
    with pytest.raises(ValueError, match=r"contacts\[0\]"):
        render_frames(p, t, pos, [Contact(1.0, "robot-robot", 0, 9)], _params())
    with pytest.raises(ValueError, match="step_times"):
        render_frames(p, t, pos, [], _params(), step_times=[0.0, 5.0, 2.0])


def test_contact_colour_is_not_a_robot_colour():
    for c in robot_colors(200):
        assert not _is_red(np.array([[c]], np.uint8)).any()
    assert _is_red(np.array([[CONTACT]], np.uint8)).all()


def test_draw_scenario_still_works():
    p = _problem()
    img = draw_scenario(p, size=200, title="scenario")
    cv = Canvas(p, 200)
    assert img.dtype == np.uint8 and img.shape == (cv.height_px, cv.width_px, 3)
    x, y = cv.to_px(p.target[0])[0].astype(int)
    assert tuple(img[y, x]) == (236, 120, 40)  # targets are filled


def test_one_contact_seen_by_two_detectors_counts_once():
    p = _problem(m=4)
    t, pos = _recording(p)
    params = _params()
    once = [Contact(3.0, "robot-wall", 0, -1, witness="pymunk")]
    twice = once + [Contact(3.05, "robot-wall", 0, -1, witness="monitor")]
    two = once + [Contact(3.05, "robot-robot", 1, 2, witness="monitor")]
    cv = Canvas(p, params.size)
    last = {}
    for name, cs in (("once", once), ("twice", twice), ("two", two)):
        last[name] = list(render_frames(p, t, pos, cs, params))[-1][: cv.header]
    assert np.array_equal(last["once"], last["twice"])  # "CONTACTS: 1" in both
    assert not np.array_equal(last["once"], last["two"])  # "CONTACTS: 2"
