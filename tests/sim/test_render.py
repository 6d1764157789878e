"""Video frames of recorded runs: size, motion, colours, legend, labels, text, contacts, playback speed."""

from dataclasses import dataclass, replace

import numpy as np
import pygame
import pytest
from numpy.lib.stride_tricks import sliding_window_view

from planner.problem import Circle, Polygon, Problem
from sim.output.canvas import BACKGROUND, MAX_SIZE, MIN_SIZE, TEXT, fit_text, frame_size, label_font
from sim.output.playback import MAX_VIDEO_SECONDS
from sim.output.render import (
    CONTACT,
    START_MARK,
    TARGET_MARK,
    Canvas,
    _interpolate,  # noqa: I001
    draw_scenario,
    frame_times,
    playback_speedup,
    render_frames,
    robot_colors,
)
from sim.scenario.params import RenderParams


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


def _frame_at(ft, time):
    """The index of the first drawn frame showing ``time`` or later."""
    return int(np.flatnonzero(ft >= time - 1e-9)[0])


def _above_legend(frame, cv):
    """The frame without the legend band (whose contact glyph is always red)."""
    return frame[: cv.height_px - cv.footer]


def _text(font, text, color=TEXT, background=BACKGROUND):
    s = font.render(text, True, color, background)
    w, h = s.get_size()
    return np.frombuffer(pygame.image.tobytes(s, "RGB"), np.uint8).reshape(h, w, 3)


def _shows(img, patch) -> bool:
    """Whether ``patch`` occurs in ``img`` pixel for pixel."""
    h, w = patch.shape[:2]
    if h > img.shape[0] or w > img.shape[1]:
        return False
    win = sliding_window_view(img, (h, w, 3))[:, :, 0]
    return bool(np.all(win == patch, axis=(2, 3, 4)).any())


# ----------------------------------------------------------------------------
# shape and motion


def test_frames_are_even_uint8_rgb():
    p = _problem()
    t, pos = _recording(p)
    for size in (200, 151):
        fr = render_frames(p, t, pos, [], _params(size=size))
        frames = list(fr)
        h, w = frames[0].shape[:2]
        assert h % 2 == 0 and w % 2 == 0
        for f in frames:
            assert f.dtype == np.uint8 and f.shape == (h, w, 3)
        assert (h, w) == (fr.canvas.height_px, fr.canvas.width_px)


def test_frames_change_when_robots_move_and_not_when_they_stay():
    p = _problem()
    t, pos = _recording(p)
    moving = render_frames(p, t, pos, [], _params())
    still = render_frames(p, t, np.broadcast_to(pos[:1], pos.shape), [], _params())
    cv = moving.canvas
    ws = cv.workspace_rows
    assert not np.array_equal(moving[0][ws], moving[5][ws])
    assert np.array_equal(still[0][ws], still[5][ws])
    # the header (sim time) changes in both
    assert not np.array_equal(still[0][: cv.header], still[5][: cv.header])


def test_random_access_draws_the_same_frames_as_iteration():
    p = _problem()
    t, pos = _recording(p)
    fr = render_frames(p, t, pos, [Contact(4.0, "robot-robot", 1, 2)], _params())
    frames = list(fr)
    assert len(frames) == len(fr) == fr.timing.frames
    for k in (0, 7, len(fr) // 2, len(fr) - 1):
        assert np.array_equal(fr[k], frames[k])
    assert np.array_equal(fr[-1], frames[-1])
    assert len(fr[2:5]) == 3
    with pytest.raises(IndexError):
        fr[len(fr)]


@pytest.mark.parametrize("radius", [0.15, 0.6])
def test_each_disc_has_its_robot_colour(radius):
    p = _problem(m=5, radius=radius)
    t, pos = _recording(p)
    params = _params(size=240)
    fr = render_frames(p, t, pos, [], params)
    ft = frame_times(t[-1], fr.speedup, params.fps)
    cv = fr.canvas
    colors = robot_colors(p.m)
    assert len(set(colors)) == p.m
    labelled = label_font(cv.r, p.m) is not None
    assert labelled == (radius == 0.6)
    for k in (0, len(fr) // 3):
        frame = fr[k]
        for i, (x, y) in enumerate(cv.to_px(_at(t, pos, ft[k]))):
            if not labelled:  # no label: the centre pixel is the robot's colour
                assert tuple(frame[int(round(y)), int(round(x))]) == colors[i]
            else:  # a label sits at the centre: the colour still fills most of the disc
                r = int(cv.r)
                yy, xx = np.mgrid[-r : r + 1, -r : r + 1]
                inside = (xx**2 + yy**2) <= (0.8 * r) ** 2
                patch = frame[int(round(y)) + yy[inside], int(round(x)) + xx[inside]]
                assert np.mean(np.all(patch == colors[i], axis=1)) > 0.5


def _blends(patch, color) -> int:
    """Pixels strictly between ``color`` and the background, channel by channel."""
    lo = np.minimum(np.array(color), np.array(BACKGROUND))
    hi = np.maximum(np.array(color), np.array(BACKGROUND))
    between = np.all((patch >= lo) & (patch <= hi), axis=-1)
    exact = np.all(patch == color, axis=-1) | np.all(patch == BACKGROUND, axis=-1)
    return int((between & ~exact).sum())


def test_discs_are_antialiased():
    p = _problem(m=1, radius=0.9)
    p = Problem(p.width, p.height, (), p.radius, p.margin, [[5.0, 4.0]], [[5.0, 4.0]])
    t = np.array([0.0])
    pos = p.start[None]
    fr = render_frames(p, t, pos, [], _params(size=400, trails=False))
    cv = fr.canvas
    x, y = cv.to_px(p.start[0])[0]
    r = int(cv.r) + 4
    ring = fr[0][int(y) - r : int(y) + r, int(x) - r : int(x) + r]
    # the disc's rim has a dark outline: blends of the colour, outline and background
    assert len(np.unique(ring.reshape(-1, 3), axis=0)) > 8
    # target disc (under the robot at t = 0, so draw it alone): its rim blends into the background
    img = draw_scenario(Problem(p.width, p.height, (), p.radius, p.margin, [[2.0, 2.0]], [[7.0, 6.0]]), size=400)
    tx, ty = cv.to_px(np.array([7.0, 6.0]))[0]
    patch = img[int(ty) - r : int(ty) + r, int(tx) - r : int(tx) + r]
    from sim.output.canvas import TARGET

    assert _blends(patch, TARGET) >= 8
    # negative control: an aliased disc has no such pixels
    s = pygame.Surface((2 * r, 2 * r))
    s.fill(BACKGROUND)
    pygame.draw.circle(s, TARGET, (r, r), cv.r)
    aliased = np.frombuffer(pygame.image.tobytes(s, "RGB"), np.uint8).reshape(2 * r, 2 * r, 3)
    assert _blends(aliased, TARGET) == 0


# ----------------------------------------------------------------------------
# conventions, legend, labels, size


def test_legend_and_conventions_match_the_scenario_picture():
    p = _problem(m=3, radius=0.3)
    t, pos = _recording(p)
    fr = render_frames(p, t, pos, [], _params(size=320))
    cv = fr.canvas
    legend = fr[0][cv.height_px - cv.footer :]
    for label in ("robot", "start (hollow)", "target (filled)", "trail", "contact"):
        assert _shows(legend, _text(cv.font, label)), label
    for color in (START_MARK, TARGET_MARK, CONTACT):
        assert np.all(legend == color, axis=-1).any()
    # in the video: at t = 0 a target is a filled disc; at the end a start is a hollow ring
    x, y = np.round(cv.to_px(p.target[1])[0]).astype(int)
    assert tuple(fr[0][y, x]) == TARGET_MARK
    x, y = np.round(cv.to_px(p.start[1])[0]).astype(int)
    last = fr[len(fr) - 1]
    assert tuple(last[y, x]) == BACKGROUND
    r = int(round(cv.r))
    ring = last[y - r - 1 : y + r + 2, x - r - 1 : x + r + 2]
    assert np.all(ring == START_MARK, axis=-1).sum() >= 4
    # the scenario picture: the same shapes and legend words (small discs: no labels)
    p = _problem(m=3, radius=0.15)
    img = draw_scenario(p, size=320)
    scv = Canvas(p, 320, legend=[("start", "start (hollow)"), ("target", "target (filled)")])
    assert img.shape == (scv.height_px, scv.width_px, 3)
    x, y = np.round(scv.to_px(p.target[0])[0]).astype(int)
    assert tuple(img[y, x]) == (236, 120, 40)  # targets are filled
    x, y = np.round(scv.to_px(p.start[0])[0]).astype(int)
    assert tuple(img[y, x]) == BACKGROUND  # starts are hollow
    for label in ("start (hollow)", "target (filled)"):
        assert _shows(img[scv.height_px - scv.footer :], _text(scv.font, label))


def test_labels_only_where_discs_are_big_enough():
    for m in (9, 40, 200):
        widest = str(m - 1)
        for r in np.arange(2.0, 30.0, 0.5):
            font = label_font(r, m)
            if font is not None:
                assert font.size(widest)[0] <= 1.6 * r and font.get_ascent() <= 1.3 * r
        assert label_font(6.0, m) is None
        assert label_font(20.0, m) is not None
    # in frames: 40 robots on 6-pixel discs carry no text, on 12-pixel discs they do
    for size, labelled in ((480, False), (960, True)):
        m = 40
        xs = (np.arange(m) % 8) * 6.0 + 4.0
        ys = (np.arange(m) // 8) * 6.0 + 4.0
        start = np.stack([xs, ys], 1)
        p = Problem(50.0, 34.0, (), 0.6, 0.05, start, start)
        fr = render_frames(p, np.array([0.0]), start[None], [], _params(size=size, trails=False))
        frame = fr[0]
        dark = 0
        for c in fr.canvas.to_px(start):
            x, y = np.round(c).astype(int)
            patch = frame[y - 2 : y + 3, x - 3 : x + 4]
            dark += int((patch.astype(int).sum(axis=-1) < 150).sum())
        assert (fr.canvas.r < 7) == (not labelled)
        assert (dark > 0) == labelled


def test_default_size_grows_with_the_workspace_and_m_and_is_bounded():
    def prob(side, m, radius=1.0):
        xs = np.linspace(2, side - 2, m)
        pts = np.stack([xs, np.full(m, side / 2)], 1)
        return Problem(side, side, (), radius, 0.1, pts, pts)

    sizes = [frame_size(prob(side, 10)) for side in (20, 40, 80, 100, 120, 400)]
    assert sizes == sorted(sizes) and sizes[0] == MIN_SIZE and sizes[-1] == MAX_SIZE
    assert len(set(sizes)) >= 4
    def grid(m):
        k = int(np.ceil(np.sqrt(m)))
        pts = (np.stack(np.divmod(np.arange(m), k), 1) + 0.5) * (50.0 / k)
        return Problem(50.0, 50.0, (), 1.0, 0.1, pts, pts)

    by_m = [frame_size(grid(m)) for m in (10, 100, 150, 200, 1000)]
    assert by_m == sorted(by_m) and len(set(by_m)) >= 3
    assert all(s % 2 == 0 and MIN_SIZE <= s <= MAX_SIZE for s in sizes + by_m)
    p = prob(120, 10)
    t = np.array([0.0])
    fr = render_frames(p, t, p.start[None], [], _params(size=None))
    assert fr.canvas.width_px == frame_size(p)


# ----------------------------------------------------------------------------
# the header


def test_speedup_is_written_out():
    p = _problem()
    t, pos = _recording(p, seconds=10.0)
    for speed, other in ((2.0, "3x speed"), (3.0, "2x speed")):
        fr = render_frames(p, t, pos, [], _params(speedup=speed, size=320))
        header = fr[0][: fr.canvas.header]
        assert _shows(header, _text(fr.canvas.font, f"{speed:g}x speed"))
        assert not _shows(header, _text(fr.canvas.font, other))


def test_steps_are_counted_from_one_and_settling_is_said():
    p = _problem()
    t, pos = _recording(p, seconds=10.0)
    params = _params(speedup=1.0, size=400)
    fr = render_frames(p, t, pos, [], params, step_times=np.array([0.0, 3.0, 6.0, 8.0]))
    font = fr.canvas.font
    ft = frame_times(10.0, 1.0, params.fps)

    def status(k, tail):
        return _text(font, f"t = {ft[k]:.1f} s / 10.0 s   {tail}")

    head = lambda k: fr[k][: fr.canvas.header]  # noqa: E731
    assert _shows(head(0), status(0, "step 1/3"))
    assert not _shows(head(0), status(0, "step 0/3"))
    k = _frame_at(ft, 4.0)
    assert _shows(head(k), status(k, "step 2/3"))
    k = _frame_at(ft, 7.0)
    assert _shows(head(k), status(k, "step 3/3"))
    for k in (_frame_at(ft, 8.5), len(fr) - 1):
        assert _shows(head(k), status(k, "plan done (3 steps), settling"))
    one = render_frames(p, t, pos, [], params, step_times=np.array([0.0, 5.0]))
    k = _frame_at(ft, 6.0)
    assert _shows(one[k][: one.canvas.header], status(k, "plan done (1 step), settling"))


def test_after_a_replan_the_header_follows_the_new_plan():
    from types import SimpleNamespace

    p = _problem()
    t, pos = _recording(p, seconds=10.0)
    params = _params(speedup=1.0, size=400)
    replans = [SimpleNamespace(time=4.0, planned_at=5.0, steps=6)]
    fr = render_frames(p, t, pos, [], params, step_times=np.array([0.0, 3.0, 6.0, 8.0]), replans=replans)
    font = fr.canvas.font
    ft = frame_times(10.0, 1.0, params.fps)

    def shows(k, tail):
        return _shows(fr[k][: fr.canvas.header], _text(font, f"t = {ft[k]:.1f} s / 10.0 s   {tail}"))

    k = _frame_at(ft, 3.5)
    assert shows(k, "step 2/3")
    k = _frame_at(ft, 4.5)
    assert shows(k, "braking for replan 1") and not shows(k, "step 2/3")
    for k in (_frame_at(ft, 7.0), len(fr) - 1):
        assert shows(k, "replan 1: 6 steps")
        assert not shows(k, "step 3/3") and not shows(k, "plan done (3 steps), settling")
    with pytest.raises(ValueError, match="replans need"):
        render_frames(p, t, pos, [], params, replans=[object()])


def test_a_failed_robot_is_drawn_grey_with_a_cross_from_its_failure_on():
    from sim.output.canvas import FAILED

    p = _problem()
    t, pos = _recording(p, seconds=10.0)
    params = _params(speedup=1.0, size=400, trails=False)
    fr = render_frames(p, t, pos, [], params, failures=[(1, 5.0)])
    plain = render_frames(p, t, pos, [], params)
    ft = frame_times(10.0, 1.0, params.fps)

    def centre(frames, k):
        x, y = frames.canvas.to_px(_interpolate(t, pos, np.array([ft[k]]))[0])[1]
        return frames[k][int(round(y)) - 3 : int(round(y)) + 4, int(round(x)) - 8 : int(round(x)) + 9]

    def grey(img):
        return np.all(np.abs(img.astype(int) - np.array(FAILED)) <= 8, axis=-1)

    before, after = _frame_at(ft, 4.0), _frame_at(ft, 6.0)
    assert not grey(centre(fr, before)).any()
    assert grey(centre(fr, after)).sum() > 10  # the grey disc around the cross
    assert (centre(fr, after).max(axis=-1) < 100).any()  # the dark cross
    assert np.array_equal(fr[before][fr.canvas.workspace_rows], plain[before][plain.canvas.workspace_rows])
    assert not grey(centre(plain, after)).any()  # negative control: no failure, no grey robot
    legend = fr[0][fr.canvas.workspace_rows.stop :]
    assert _shows(legend, _text(fr.canvas.font, "failed"))
    assert not _shows(plain[0][plain.canvas.workspace_rows.stop :], _text(plain.canvas.font, "failed"))
    for c in robot_colors(200):
        assert not grey(np.array([[c]], np.uint8)).any()
    with pytest.raises(ValueError, match="failures must name robots"):
        render_frames(p, t, pos, [], params, failures=[(9, 1.0)])


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


def test_title_fitting_does_not_grow_with_the_title():
    pygame.font.init()
    calls = []

    class Counting:
        def __init__(self, font):
            self.font = font

        def size(self, text):
            calls.append(len(text))
            return self.font.size(text)

    font = pygame.font.Font(None, 16)
    for n in (1000, 1_000_000):
        calls.clear()
        out = fit_text(Counting(font), "w" * n, 300)
        assert out.endswith("...") and font.size(out)[0] <= 300
        assert len(calls) <= 14 and max(calls) <= 305
    assert fit_text(font, "short", 300) == "short"
    assert fit_text(font, "a\x00b\nc", 300) == "a?b?c"
    assert fit_text(font, "anything", 0) == ""
    # a 1 MB title gives the same header as any other title cut at the same place
    p = _problem()
    t, pos = _recording(p, seconds=2.0)
    huge = render_frames(p, t, pos, [], _params(), title="w" * 1_000_000)[0]
    long = render_frames(p, t, pos, [], _params(), title="w" * 1000)[0]
    assert np.array_equal(huge, long)


# ----------------------------------------------------------------------------
# contacts


def test_contact_turns_the_robots_red_only_from_its_time_on():
    p = _problem(m=4)
    t, pos = _recording(p)
    params = _params()
    tc = 4.0
    contacts = [Contact(tc, "robot-robot", 1, 2), Contact(tc, "robot-wall", 3, -1)]
    fr = render_frames(p, t, pos, contacts, params)
    frames = list(fr)
    ft = frame_times(t[-1], fr.speedup, params.fps)
    cv = fr.canvas
    hit = _frame_at(ft, tc)
    r = cv.r_px + 3

    def red_near(k, i):
        x, y = cv.to_px(_at(t, pos, ft[k])[i])[0]
        return _is_red(frames[k][int(y) - r : int(y) + r + 1, int(x) - r : int(x) + r + 1]).any()

    ws = cv.workspace_rows
    for k in range(hit):  # before the contact: no red anywhere above the legend, header included
        assert not _is_red(_above_legend(frames[k], cv)).any(), f"frame {k} at t = {ft[k]:.2f} s has red pixels"
    for i in (1, 2, 3):
        assert red_near(hit, i)
    # the wall contact point: red on the wall nearest to robot 3 (at x = 8: the right wall)
    x3 = cv.to_px(np.array([p.width, _at(t, pos, tc)[3, 1]]))[0]
    near_wall = frames[hit][int(x3[1]) - 4 : int(x3[1]) + 5, int(x3[0]) - 4 : int(x3[0]) + 5]
    assert _is_red(near_wall).any()
    # the header counts contacts from then on, the flash ends after half a video second
    assert _is_red(frames[hit][: cv.header]).any()
    late = _frame_at(ft, tc + 0.5 * fr.speedup + 0.5)
    assert not _is_red(frames[late][ws]).any()
    assert _is_red(frames[late][: cv.header]).any()


def test_contact_flash_frames_the_picture_and_rings_the_place():
    p = _problem(m=4, radius=0.3)
    t, pos = _recording(p)
    params = _params(size=320)
    tc = 4.0
    fr = render_frames(p, t, pos, [Contact(tc, "robot-robot", 1, 2)], params)
    ft = frame_times(t[-1], fr.speedup, params.fps)
    cv = fr.canvas
    hit = _frame_at(ft, tc)
    frame = fr[hit]
    pad = cv.pad
    edge = np.concatenate([frame[:pad].reshape(-1, 3), frame[-pad:].reshape(-1, 3),
                           frame[:, :pad].reshape(-1, 3), frame[:, -pad:].reshape(-1, 3)])
    assert _is_red(edge).all()
    for k in (hit - 1, _frame_at(ft, tc + 0.5 * fr.speedup + 0.5)):  # before and after: no frame
        assert not _is_red(fr[k][:pad]).any()
    # a big red ring around the middle of the pair (the discs alone are much smaller)
    mid = cv.to_px(_at(t, pos, ft[hit])[[1, 2]].mean(axis=0))[0]
    yy, xx = np.nonzero(_is_red(frame[cv.workspace_rows]))
    d = np.hypot(xx - mid[0], yy + cv.header - mid[1])
    assert (np.abs(d - max(2.5 * cv.r, 12.0)) < 2).sum() > 30
    # the header shows it too, white on red while it flashes
    flash = _text(cv.font, " CONTACT  (1 contact) ", color=(255, 255, 255), background=CONTACT)
    assert _shows(frame[: cv.header], flash)
    assert not _shows(fr[hit - 1][: cv.header], flash)


def test_contact_witness_marks_the_obstacle_point():
    p = _problem(m=2)
    t, pos = _recording(p)
    params = _params()
    w = (5.0, 4.8)  # on the top edge of the box obstacle
    fr = render_frames(p, t, pos, [Contact(2.0, "robot-obstacle", 0, 0, witness=w)], params)
    ft = frame_times(t[-1], fr.speedup, params.fps)
    x, y = np.round(fr.canvas.to_px(w)[0]).astype(int)
    k = _frame_at(ft, 2.0)
    assert _is_red(fr[k][y - 1 : y + 2, x - 1 : x + 2]).all()
    assert not _is_red(fr[k - 1][y - 1 : y + 2, x - 1 : x + 2]).any()


def test_one_contact_seen_by_two_detectors_counts_once():
    p = _problem(m=4)
    t, pos = _recording(p)
    params = _params(size=320)
    once = [Contact(3.0, "robot-wall", 0, -1, witness="pymunk")]
    twice = once + [Contact(3.05, "robot-wall", 0, -1, witness="monitor")]
    two = once + [Contact(3.05, "robot-robot", 1, 2, witness="monitor")]
    for name, cs, text in (("once", once, "1 contact"), ("twice", twice, "1 contact"), ("two", two, "2 contacts")):
        fr = render_frames(p, t, pos, cs, params)
        header = fr[len(fr) - 1][: fr.canvas.header]
        assert _shows(header, _text(fr.canvas.font, text, color=CONTACT)), name


def test_contact_colour_is_not_a_robot_colour():
    for c in robot_colors(200):
        assert not _is_red(np.array([[c]], np.uint8)).any()
    assert _is_red(np.array([[CONTACT]], np.uint8)).all()


# ----------------------------------------------------------------------------
# playback


def test_auto_speedup_fits_the_video_length():
    p = _problem()
    for seconds, video in ((120.0, 10.0), (47.0, 8.0), (300.0, 20.0)):
        t, pos = _recording(p, seconds=seconds, rate=20.0)
        params = _params(video_seconds=video, size=128)
        s = playback_speedup(seconds, params)
        assert s >= 1
        mant = s / 10 ** np.floor(np.log10(s))
        assert any(np.isclose(mant, v) for v in (1, 1.5, 2, 2.5, 3, 4, 5, 6, 8))
        n = len(render_frames(p, t, pos, [], params))
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
    fr = render_frames(p, t, pos, [], params)
    assert len(fr) == len(list(fr)) == 10.0 / 2.0 * params.fps + 1 + params.fps
    assert not fr.timing.raised and fr.timing.to_dict()["speedup_asked"] == 2.0


@pytest.mark.parametrize("seconds, speedup", [(10.0, 1e-9), (1e9, None), (1e9, 1.0), (4000.0, 1.0)])
def test_the_video_length_is_bounded(seconds, speedup):
    p = _problem()
    t = np.array([0.0, seconds])
    pos = np.stack([p.start, p.target])
    params = _params(speedup=speedup, fps=20, video_seconds=1e6)
    fr = render_frames(p, t, pos, [], params)
    assert fr.timing.raised
    assert fr.timing.drawn <= MAX_VIDEO_SECONDS * params.fps + 2
    assert len(fr) <= (MAX_VIDEO_SECONDS + 1) * params.fps + 2
    assert fr.timing.video_seconds > 0.5 * MAX_VIDEO_SECONDS  # raised just enough
    # negative control: what was asked for would have been longer
    asked = speedup or seconds / params.video_seconds
    assert seconds / asked > MAX_VIDEO_SECONDS
    d = fr.timing.to_dict()
    assert d["speedup_raised"] is True and d["speedup"] == fr.speedup > (speedup or 0)
    header = fr[0][: fr.canvas.header]
    assert _shows(header, _text(fr.canvas.font, f"{fr.speedup:g}x speed"))
    # the last frame shows the end of the run
    assert fr.timing.time(fr.timing.drawn - 1) == pytest.approx(seconds)


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
    with pytest.raises(ValueError, match="fps"):
        render_frames(p, t, pos, [], _params(fps=1000))
    with pytest.raises(ValueError, match="size"):
        render_frames(p, t, pos, [], _params(size=20000))
    with pytest.raises(ValueError, match="speedup"):
        render_frames(p, t, pos, [], _params(speedup=float("nan")))


@pytest.mark.parametrize("render, field", [("{fps: 1000000000, formats: [mp4]}", "render.fps"),
                                           ("{size: 20000}", "render.size"), ("{size: 10}", "render.size")])
def test_render_settings_out_of_range_are_input_errors(tmp_path, render, field):
    from sim.scenario import ScenarioError, read_scenario

    path = tmp_path / "s.yaml"
    path.write_text("workspace: [10, 10]\nrobots: {radius: 0.5, margin: 0.1}\n"
                    "start: {points: [[2, 2], [2, 5]]}\ntarget: {points: [[8, 2], [8, 5]]}\n"
                    f"render: {render}\n")
    with pytest.raises(ScenarioError, match=field.replace(".", r"\.")):
        read_scenario(path)
    path.write_text(path.read_text().replace(f"render: {render}", "render: {size: auto, fps: 120, formats: [mp4]}"))
    sc = read_scenario(path)
    assert sc.render.size is None and sc.render.fps == 120
