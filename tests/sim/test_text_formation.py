"""Text formations read back as their text.

The robots of a text formation are sampled from the glyphs that pygame-ce
renders (``sim.glyphs``): along their stroke skeletons or over their ink.
Read back in the glyph mask's own pixel frame, every robot must lie on the
ink, every glyph must get robots, and the placements, rasterised, must
match their own letter's mask better than any other letter's.  Through a
scenario file, the placement must be that shape, moved rigidly, with the
requested count, separation and clearance; the default count must suit
the text's size.  Bad text and fonts exit 2 naming the field.
"""

from __future__ import annotations

import os
import textwrap
from pathlib import Path

import numpy as np
import pytest
from scipy import ndimage
from scipy.spatial.distance import pdist

from planner.area import area_points
from planner.skeleton import mask_strokes
from planner.strokes import drawing, stroke_points
from sim.scenario import ScenarioError, build_legs, build_problem, read_scenario
from sim.scenario.glyphs import GlyphError, render_text
from sim.scenario.placements import FIT, STROKE_SPACING, default_count, formation_side, make_shape

LETTERS = "ABCDEFHKMNOPRSTUVWXZ"
GRID = 40  # letters compared on a GRID x GRID frame


def _write(tmp_path: Path, text: str, name: str = "case.yaml") -> Path:
    path = tmp_path / name
    path.write_text(textwrap.dedent(text), encoding="utf-8")
    return path


def _strokes_pts(mask, m):
    return stroke_points(drawing(mask_strokes(mask)), m)


def _frame(mask, pts):
    """Mask and points mapped onto a GRID x GRID frame by the mask's ink box."""
    rows, cols = np.nonzero(mask)
    r0, r1, c0, c1 = rows.min(), rows.max() + 1, cols.min(), cols.max() + 1
    side = max(r1 - r0, c1 - c0)
    ys, xs = (np.arange(GRID) + 0.5) * side / GRID + r0, (np.arange(GRID) + 0.5) * side / GRID + c0
    yy, xx = np.meshgrid(ys, xs, indexing="ij")
    inside = (yy < mask.shape[0]) & (xx < mask.shape[1])
    grid = np.zeros((GRID, GRID), bool)
    grid[inside] = mask[yy[inside].astype(int), xx[inside].astype(int)]
    q = None
    if pts is not None:
        q = (pts - [c0, r0]) * GRID / side
    return grid, q


def _raster(q, radius):
    img = np.zeros((GRID, GRID), bool)
    yy, xx = np.mgrid[0:GRID, 0:GRID] + 0.5
    for x, y in q:
        img |= (xx - x) ** 2 + (yy - y) ** 2 <= radius**2
    return img


def _corr(a, b):
    a, b = a.astype(float).ravel(), b.astype(float).ravel()
    return float(np.corrcoef(a, b)[0, 1])


@pytest.fixture(scope="module")
def masks():
    return {ch: render_text(ch).mask for ch in LETTERS}


# ----------------------------------------------------------------------------
# read-back in the glyph frame


@pytest.mark.parametrize("fill", ["strokes", "area"])
def test_every_robot_lies_on_its_glyph(masks, fill):
    for ch, mask in masks.items():
        for m in (12, 30):
            pts = _strokes_pts(mask, m) if fill == "strokes" else area_points(mask, m, np.random.default_rng(0))
            assert pts.shape == (m, 2)
            col, row = np.floor(pts[:, 0]).astype(int), np.floor(pts[:, 1]).astype(int)
            near = ndimage.binary_dilation(mask, iterations=1)
            assert near[row, col].all(), f"{ch}: a robot off the ink"


@pytest.mark.parametrize("fill", ["strokes", "area"])
def test_placements_read_back_as_their_letter(masks, fill):
    """Rasterised robots correlate best with their own letter's mask."""
    frames = {ch: _frame(mask, None)[0] for ch, mask in masks.items()}
    wrong = []
    for ch, mask in masks.items():
        m = 24
        pts = _strokes_pts(mask, m) if fill == "strokes" else area_points(mask, m, np.random.default_rng(1))
        _, q = _frame(mask, pts)
        img = _raster(q, radius=GRID / 12)
        scores = {other: _corr(img, f) for other, f in frames.items()}
        best = max(scores, key=scores.get)
        if best != ch:
            wrong.append((ch, best, round(scores[ch], 3), round(scores[best], 3)))
    assert not wrong, wrong


def test_read_back_sees_a_wrong_letter(masks):
    """Negative control: robots of an O do not read back as an X."""
    frames = {ch: _frame(mask, None)[0] for ch, mask in masks.items()}
    _, q = _frame(masks["O"], _strokes_pts(masks["O"], 24))
    img = _raster(q, radius=GRID / 12)
    assert _corr(img, frames["X"]) < _corr(img, frames["O"])
    assert max(frames, key=lambda k: _corr(img, frames[k])) != "X"


@pytest.mark.parametrize("fill", ["strokes", "area"])
def test_every_glyph_gets_robots(fill):
    g = render_text("SWARM\nHELLO")
    assert [b[0] for b in g.boxes] == list("SWARMHELLO")
    m = 60
    pts = _strokes_pts(g.mask, m) if fill == "strokes" else area_points(g.mask, m, np.random.default_rng(0))
    for ch, x0, y0, x1, y1 in g.boxes:
        inside = (pts[:, 0] >= x0) & (pts[:, 0] <= x1) & (pts[:, 1] >= y0) & (pts[:, 1] <= y1)
        assert inside.sum() >= 3, f"{ch} got {inside.sum()} robots"


# ----------------------------------------------------------------------------
# through a scenario


_TEXT = """\
    workspace: [80, 80]
    robots: {margin: 0.1%s}
    obstacles:
      - circle: {center: [10, 10], radius: 4}
    start: {formation: scatter}
    target: {formation: {text: %s%s}, center: [40, 44]}
"""


@pytest.mark.parametrize("fill", ["strokes", "area"])
def test_scenario_places_the_shape_rigidly(tmp_path, fill):
    fill_key = "" if fill == "strokes" else ", fill: area"
    path = _write(tmp_path, _TEXT % ("", "SWARM", fill_key))
    sc = read_scenario(path)
    assert sc.target.text == "SWARM" and sc.target.fill == fill
    assert sc.target.rotation == 0.0 and sc.target.scale is None  # text defaults: upright, as big as fits
    side = formation_side(sc.target, 80, 80, 1.1)
    assert side == pytest.approx(FIT * (80 - 2.2))  # a word is wide: its width binds
    problem = build_problem(sc, np.random.default_rng(sc.seed))
    m = sc.count
    assert problem.m == m and m == default_count(sc.target, 80, 80, 2.1)
    sep, clear = 2.1, 1.1
    for pts in (problem.start, problem.target):
        assert pdist(pts).min() >= sep
        assert problem.env.point_clearance(pts).min() >= clear
    if fill == "strokes":  # the strokes shape draws nothing from the generator
        shape = make_shape(sc.target, m, side, sep, np.random.default_rng(0))
        np.testing.assert_allclose(problem.target, shape + [40, 44], atol=1e-9)
        # at the default count the text keeps its requested size (no enlargement)
        assert float(np.ptp(problem.target, axis=0).max()) == pytest.approx(side, rel=0.02)


def test_default_count_suits_the_size(tmp_path):
    """Twice the scale holds about twice the robots; bigger robots need fewer."""
    base = read_scenario(_write(tmp_path, _TEXT % ("", "HELLO", ", fill: strokes")))
    n = default_count(base.target, 80, 80, 2.1)
    assert 30 <= n <= 80
    from dataclasses import replace

    half = default_count(replace(base.target, scale=0.4), 80, 80, 2.1)
    assert 0.4 * n <= half <= 0.6 * n
    assert default_count(base.target, 80, 80, 1.05) >= 1.8 * n
    # the spacing along the strokes is about STROKE_SPACING separations
    problem = build_problem(base, np.random.default_rng(0))
    nn = np.sort(np.linalg.norm(problem.target[:, None] - problem.target[None], axis=2), axis=1)[:, 1]
    assert np.median(nn) == pytest.approx(STROKE_SPACING * 2.1, rel=0.25)


def test_twice_the_count_still_reads(tmp_path, masks):
    """2x the default count (robots half the size): more robots, same letters."""
    one = read_scenario(_write(tmp_path, _TEXT % ("", "SWARM", ""), "one.yaml"))
    m = one.count
    two = read_scenario(_write(tmp_path, _TEXT % (f", count: {2 * m}, radius: 0.5", "SWARM", ""), "two.yaml"))
    p = build_problem(two, np.random.default_rng(0))
    assert p.m == 2 * m and pdist(p.target).min() >= 1.1


def test_text_is_deterministic(tmp_path):
    path = _write(tmp_path, _TEXT % ("", "OK", ", fill: area"))
    sc = read_scenario(path)
    a = build_problem(sc, np.random.default_rng(3)).target
    b = build_problem(sc, np.random.default_rng(3)).target
    assert a.tobytes() == b.tobytes()


def test_font_file_is_used(tmp_path):
    """An explicit font (here pygame-ce's own file, by path, relative to the scenario)."""
    import pygame

    src = Path(pygame.__file__).parent / "freesansbold.ttf"
    (tmp_path / "fonts").mkdir()
    (tmp_path / "fonts" / "mine.ttf").write_bytes(src.read_bytes())
    path = _write(tmp_path, _TEXT % (", count: 40", "Hi", ", font: fonts/mine.ttf"))
    sc = read_scenario(path)
    assert sc.target.font == str(tmp_path / "fonts" / "mine.ttf")
    assert build_problem(sc, np.random.default_rng(0)).m == 40


# ----------------------------------------------------------------------------
# bad text and fonts


@pytest.mark.parametrize(
    "formation, field, says",
    [
        ("{text: ''}", "target.formation.text", "at least one visible"),
        ("{text: '   '}", "target.formation.text", "at least one visible"),
        ("{text: " + "A" * 41 + "}", "target.formation.text", "at most 40 characters"),
        ("{text: \"A\\nB\\nC\\nD\\nE\"}", "target.formation.text", "at most 4 lines"),
        ("{text: \"A\\tB\"}", "target.formation.text", "control character"),
        ("{text: [A]}", "target.formation.text", "must be a string"),
        ("{text: \"\u4e2d\"}", "target.formation.text", "no glyph"),
        ("{text: A, fill: dots}", "target.formation.fill", "strokes or area"),
        ("{text: A, font: nowhere.ttf}", "target.formation.font", "no such file"),
        ("{text: A, font: .}", "target.formation.font", "not a regular file"),
        ("{text: A, font: empty.ttf}", "target.formation.font", "is empty"),
        ("{text: A, font: junk.ttf}", "target.formation.font", "does not load as a font"),
        ("{text: A, font: huge.ttf}", "target.formation.font", "at most 16777216"),
        ("{text: A, font: 7}", "target.formation.font", "path to a TrueType"),
        ("{text: A, colour: red}", "target.formation.colour", "unknown key"),
        ("{words: A}", "target.formation.words", "unknown key"),
    ],
)
def test_bad_text_is_refused(tmp_path, formation, field, says):
    (tmp_path / "empty.ttf").write_bytes(b"")
    (tmp_path / "junk.ttf").write_bytes(os.urandom(4096))
    with open(tmp_path / "huge.ttf", "wb") as fh:
        fh.truncate(16 * 1024 * 1024 + 1)  # sparse: no disk used
    path = _write(tmp_path, f"""\
        workspace: [80, 80]
        robots: {{count: 10}}
        start: {{formation: line}}
        target: {{formation: {formation}}}
    """)
    with pytest.raises(ScenarioError) as info:
        read_scenario(path)
    assert info.value.field == field, str(info.value)
    assert says in info.value.reason
    assert "\n" not in str(info.value) and len(str(info.value)) < 400


def test_glyph_errors_name_text_or_font():
    with pytest.raises(GlyphError) as info:
        render_text("x" * 100)
    assert info.value.field == "text"


def test_text_too_big_for_the_workspace(tmp_path):
    path = _write(tmp_path, _TEXT % (", count: 300", "SWARM", ""))
    with pytest.raises(ScenarioError) as info:
        build_legs(read_scenario(path), np.random.default_rng(0))
    assert info.value.field == "target" and "does not fit" in info.value.reason
