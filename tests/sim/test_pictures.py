"""Pictures that say their scale and whose legends match what is drawn; the tracking plot of a big swarm."""

import numpy as np
import pytest

from planner.problem import Problem
from sim.output.canvas import BACKGROUND, SCALE, Canvas, nice_length, robot_colors
from sim.output.plots import _tracking_figure, worst_robot
from sim.output.render import draw_scenario, render_frames
from sim.scenario.params import RenderParams

_SCENARIO_LEGEND = [("start", "start (hollow)"), ("target", "target (filled)")]


def _problem(m=4, width=10.0, height=8.0, radius=0.5):
    xs = np.linspace(1.5, width - 1.5, m)
    start = np.stack([xs, np.full(m, 2.0)], axis=1)
    target = np.stack([xs, np.full(m, height - 2.0)], axis=1)
    return Problem(width, height, (), radius, 0.1, start, target)


def test_nice_lengths_are_one_two_or_five_times_a_power_of_ten():
    assert [nice_length(x) for x in (0.7, 1.0, 1.9, 2.0, 4.99, 7.0, 10.0, 33.0, 0.033)] == [
        0.5, 1.0, 1.0, 2.0, 2.0, 5.0, 10.0, 20.0, 0.02]
    with pytest.raises(ValueError):
        nice_length(0.0)


@pytest.mark.parametrize("width, height", [(10.0, 8.0), (200.0, 120.0), (1.0, 1.0)])
def test_scale_bar_is_drawn_where_the_canvas_says_and_not_without_it(width, height):
    p = _problem(width=width, height=height, radius=min(width, height) / 40)
    img = draw_scenario(p)
    cv = Canvas(p, legend=_SCENARIO_LEGEND)  # the layout draw_scenario uses
    rect = cv.scale_bar_rect
    assert rect is not None and rect.width == round(cv.scale_length * cv.scale)
    assert cv.scale_length == nice_length(cv.scale_length)  # a round length
    assert rect.centerx > img.shape[1] // 2 and rect.top >= cv.height_px - cv.footer  # the bottom right corner
    bar = img[rect.top : rect.bottom, rect.left : rect.right]
    assert np.all(bar == SCALE)
    # the negative control: the same picture without the bar has the background there
    plain = Canvas(p, legend=_SCENARIO_LEGEND, scale_bar=False)
    assert plain.scale_bar_rect is None and plain.scale_length is None
    bare = Canvas.to_array(plain.surface())
    if bare.shape == img.shape:
        assert np.all(bare[rect.top : rect.bottom, rect.left : rect.right] == BACKGROUND)


def test_wall_ticks_sit_every_scale_length_and_not_between():
    p = _problem()
    cv = Canvas(p, legend=_SCENARIO_LEGEND)
    img = Canvas.to_array(cv.surface())
    bare = Canvas.to_array(Canvas(p, legend=_SCENARIO_LEGEND, scale_bar=False).surface())
    step = cv.scale_length
    x0, y0 = cv.to_px(np.array([0.0, 0.0]))[0]
    below = int(y0) + cv.border - 2  # in the border under the bottom wall, past the wall's line
    tick = round(x0 + step * cv.scale)
    between = round(x0 + 0.5 * step * cv.scale)
    assert np.all(img[below, tick] == SCALE) and np.all(bare[below, tick] == BACKGROUND)
    assert np.all(img[below, between] == BACKGROUND)
    left = int(x0) - cv.border + 2
    ytick = round(y0 - step * cv.scale)
    assert np.all(img[ytick, left] == SCALE) and np.all(bare[ytick, left] == BACKGROUND)


def test_video_frames_carry_the_scale_bar_and_a_many_coloured_robot_swatch():
    p = _problem(m=2)
    t = np.linspace(0.0, 2.0, 21)
    pos = np.broadcast_to(p.start, (len(t), 2, 2)).copy()
    fr = render_frames(p, t, pos, (), RenderParams(formats=("gif",), trails=False))
    img, cv = fr[0], fr.canvas
    rect = cv.scale_bar_rect
    assert np.all(img[rect.top : rect.bottom, rect.left : rect.right] == SCALE)
    # the legend's robot glyph shows several robot colours (robots are drawn one colour each),
    # here even the third one that this two-robot run does not use
    legend = img[cv.height_px - cv.footer :]
    for colour in robot_colors(3):
        assert np.all(legend == colour, axis=-1).sum() >= 4, colour
    # and every colour of the legend is in the GIF palette's fixed colours
    palette = {tuple(c) for c in fr.colours}
    assert set(robot_colors(3)) <= palette and SCALE in palette


# ----------------------------------------------------------------------------
# the tracking-error plot


def _lines(fig):
    ax = fig.axes[0]
    return ax, {line.get_label(): line for line in ax.get_lines() if not line.get_label().startswith("_")}


def _tracking(m, worst=None, n=80):
    t = np.linspace(0.0, 8.0, n)
    rng = np.random.default_rng(0)
    err = 0.01 * rng.random((n, m))
    if worst is not None:
        err[:, worst] += 0.05 * np.sin(t / 8.0 * np.pi)
    return t, err


def test_a_big_swarm_gets_median_band_and_its_worst_robot():
    t, err = _tracking(20, worst=13)
    err[5, 2] = np.nan  # a failed robot's sample is ignored
    fig = _tracking_figure({}, t, err)
    ax, lines = _lines(fig)
    assert set(lines) == {"median robot", "robot 13 (the worst)"}
    np.testing.assert_allclose(lines["median robot"].get_ydata(), np.nanmedian(err, axis=1))
    np.testing.assert_array_equal(lines["robot 13 (the worst)"].get_ydata(), err[:, 13])
    (band,) = [c for c in ax.collections if c.get_label() == "10-90 % of the 20 robots"]
    y = band.get_paths()[0].vertices[:, 1]
    lo, hi = np.nanpercentile(err, [10, 90], axis=1)
    assert y.min() == pytest.approx(lo.min()) and y.max() == pytest.approx(hi.max())
    labels = ax.get_legend_handles_labels()[1]
    assert labels == ["10-90 % of the 20 robots", "median robot", "robot 13 (the worst)"]
    assert worst_robot(err) == 13 and worst_robot(np.full((3, 2), np.nan)) == -1


@pytest.mark.parametrize("m", [1, 10])
def test_a_small_swarm_keeps_one_line_per_robot(m):
    t, err = _tracking(m)
    ax, lines = _lines(_tracking_figure({}, t, err))
    assert set(lines) == {f"robot {i}" for i in range(m)} and not ax.collections


def _walled_in(free_side=10.0, width=100.0, height=80.0, corner=(20.0, 30.0)):
    """A workspace blocked but for a square of ``free_side`` at ``corner``: a ROS map, mostly unknown."""
    from planner.problem import Polygon

    x0, y0 = corner
    x1, y1 = x0 + free_side, y0 + free_side
    rects = [(0, 0, width, y0), (0, y1, width, height), (0, y0, x0, y1), (x1, y0, width, y1)]
    obstacles = tuple(Polygon(np.array([[a, b], [c, b], [c, d], [a, d]], float)) for a, b, c, d in rects)
    start = np.array([[x0 + 2.0, y0 + 2.0], [x0 + 7.0, y0 + 2.0]])
    return Problem(width, height, obstacles, 0.5, 0.1, start, start + [0.0, 5.0])


def test_a_mostly_blocked_map_is_drawn_cropped_to_its_free_space():
    """The free square of 10 fills 1.25 % of the workspace: the picture shows that square
    (padded by two radii and 2 %) at a scale eight times larger, robots inside the frame;
    the control: the same square free in an open workspace is drawn whole."""
    from sim.output.canvas import view_box

    p = _walled_in()
    x0, y0, x1, y1 = view_box(p)
    assert (x0, y0) == pytest.approx((20 - 1.2, 30 - 1.2)) and (x1, y1) == pytest.approx((30 + 1.2, 40 + 1.2))
    cv = Canvas(p, 600, legend=_SCENARIO_LEGEND)
    whole = Canvas(_problem(width=100.0, height=80.0), 600, legend=_SCENARIO_LEGEND)
    assert cv.scale == pytest.approx(whole.scale * 100 / 12.4)
    px = cv.to_px(p.start)
    assert (px[:, 0] > cv.border).all() and (px[:, 0] < cv.width_px - cv.border).all()
    img = draw_scenario(p, size=600)
    mid = cv.to_px(np.array([[25.0, 35.0]]))[0].astype(int)
    assert tuple(img[mid[1], mid[0]]) == BACKGROUND  # free space, not obstacle, in the middle
    assert view_box(_problem(width=100.0, height=80.0)) == (0.0, 0.0, 100.0, 80.0)
    assert view_box(_walled_in(free_side=70.0, corner=(5.0, 5.0))) == (0.0, 0.0, 100.0, 80.0)  # 70 %: whole
