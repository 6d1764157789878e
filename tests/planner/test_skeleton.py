"""Skeletons of masks and robots over masks: thinning, tracing, pruning, area fill.

Shapes with a known middle line (a bar, a plus, a ring, an L) must thin to
it: the right number of strokes, closed where the ink is a loop, every
stroke point inside the ink and near the true middle.  The area sampler
must put exactly ``m`` distinct robots on ink pixels, evenly (every ink
pixel near a robot), and keep a requested gap where the ink has room.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import cKDTree
from scipy.spatial.distance import pdist

from planner.area import area_points, ink_points
from planner.skeleton import mask_strokes, thin
from planner.strokes import drawing, stroke_points


def _bar(h=60, w=120, t=12):
    m = np.zeros((h, w), bool)
    m[h // 2 - t // 2 : h // 2 + t // 2, 10 : w - 10] = True
    return m


def _plus():
    m = np.zeros((100, 100), bool)
    m[44:56, 10:90] = True
    m[10:90, 44:56] = True
    return m


def _ring(r_out=40, r_in=28, n=100):
    y, x = np.mgrid[0:n, 0:n] + 0.5
    d = np.hypot(x - n / 2, y - n / 2)
    return (d <= r_out) & (d >= r_in)


def _ell():
    m = np.zeros((100, 100), bool)
    m[10:90, 10:22] = True
    m[10:22, 10:80] = True
    return m


def _inside(mask, pts, slack=1.0):
    """Whether each point lies within ``slack`` pixels of an ink pixel centre."""
    d, _ = cKDTree(ink_points(mask)).query(pts)
    return d <= slack


def _stroke_points(lines, step=0.5):
    out = []
    for p in lines:
        seg = np.linalg.norm(np.diff(p, axis=0), axis=1)
        for a, b, s in zip(p[:-1], p[1:], seg):
            t = np.linspace(0, 1, max(2, int(s / step) + 1))[:, None]
            out.append(a + t * (b - a))
        out.append(p[:1])
    return np.concatenate(out)


def test_thin_keeps_topology_and_is_one_pixel_wide():
    ring = _ring()
    sk = thin(ring)
    assert sk.any() and not (sk & ~ring).any()
    # one loop: the background splits into two parts (inside, outside) as for the ring
    from scipy import ndimage

    assert ndimage.label(~sk)[1] == ndimage.label(~ring)[1] == 2
    # one pixel wide: no 2 x 2 block of skeleton pixels
    blocks = sk[:-1, :-1] & sk[1:, :-1] & sk[:-1, 1:] & sk[1:, 1:]
    assert not blocks.any()


@pytest.mark.parametrize(
    "name, mask, strokes, closed",
    [("bar", _bar(), 1, 0), ("plus", _plus(), 4, 0), ("ring", _ring(), 1, 1), ("ell", _ell(), 1, 0)],
)
def test_traced_strokes(name, mask, strokes, closed):
    lines = mask_strokes(mask)
    assert len(lines) == strokes, [len(p) for p in lines]
    is_closed = [bool(np.allclose(p[0], p[-1])) and len(p) > 2 for p in lines]
    assert sum(is_closed) == closed
    pts = _stroke_points(lines)
    assert _inside(mask, pts).all()


def test_ell_is_cut_at_its_corner():
    lines = mask_strokes(_ell())
    st = drawing(lines)
    assert len(st) == 2  # the corner splits the one traced stroke
    pts = stroke_points(st, 9)
    corner = np.asarray(st[0].points[-1])
    assert np.min(np.linalg.norm(pts - corner, axis=1)) < 1e-9


def test_bar_skeleton_is_its_middle_line():
    mask = _bar()
    (line,) = mask_strokes(mask)
    pts = _stroke_points([line])
    np.testing.assert_allclose(pts[:, 1], 30.0, atol=1.0)
    # spurs at the corners are pruned; the line runs most of the bar's length
    assert np.ptp(pts[:, 0]) >= 100 - 12 - 2


def test_plus_meets_at_its_centre():
    lines = mask_strokes(_plus())
    ends = np.concatenate([[p[0], p[-1]] for p in lines])
    centre = np.array([50.0, 50.0])
    near = np.linalg.norm(ends - centre, axis=1) < 3.0
    assert near.sum() == 4  # every arm starts at the junction
    # and the sampler puts one robot on the junction, not four
    pts = stroke_points(drawing(lines), 13)
    assert np.sum(np.linalg.norm(pts - ends[near][0], axis=1) < 1e-9) <= 1
    assert pdist(pts).min() > 3.0


def test_ring_samples_evenly():
    lines = mask_strokes(_ring())
    pts = stroke_points(drawing(lines), 20)
    r = np.hypot(*(pts - 50.0).T)
    np.testing.assert_allclose(r, 34.0, atol=2.0)
    d = np.sort(np.linalg.norm(pts[:, None] - pts[None], axis=2), axis=1)[:, 1]
    assert d.max() / d.min() < 1.3


def test_dot_is_a_zero_length_stroke():
    m = np.zeros((20, 20), bool)
    m[9:11, 9:11] = True
    lines = mask_strokes(m)
    assert len(lines) == 1 and np.allclose(lines[0][0], lines[0][-1])


def test_bad_masks():
    with pytest.raises(ValueError):
        mask_strokes(np.zeros((10, 10), bool))
    with pytest.raises(ValueError):
        mask_strokes(np.zeros((3000, 3000), bool))


# ----------------------------------------------------------------------------
# area


@pytest.mark.parametrize("m", [1, 7, 40, 120])
def test_area_points_lie_on_the_ink(m):
    mask = _plus()
    pts = area_points(mask, m, np.random.default_rng(m))
    assert pts.shape == (m, 2)
    col, row = np.floor(pts[:, 0]).astype(int), np.floor(pts[:, 1]).astype(int)
    assert mask[row, col].all()
    assert len(np.unique(pts, axis=0)) == m


def test_area_points_cover_the_ink_evenly():
    """Every ink pixel is close to a robot: no empty patches, no clumps."""
    mask = np.zeros((80, 80), bool)
    mask[10:70, 10:70] = True
    m = 36  # a 6 x 6 lattice would be 10 px apart
    pts = area_points(mask, m, np.random.default_rng(0))
    d, _ = cKDTree(pts).query(ink_points(mask))
    assert d.max() <= 10.0
    nn = cKDTree(pts).query(pts, k=2)[0][:, 1]
    assert nn.min() >= 0.7 * 10.0


def test_area_gap_is_kept_where_there_is_room():
    mask = _ring()
    pts = area_points(mask, 15, np.random.default_rng(1), gap=12.0)
    assert pdist(pts).min() >= 12.0 - 1e-9
    assert _inside(mask, pts, slack=0.0).all()


def test_area_is_deterministic_per_seed():
    a = area_points(_ell(), 20, np.random.default_rng(5))
    b = area_points(_ell(), 20, np.random.default_rng(5))
    c = area_points(_ell(), 20, np.random.default_rng(6))
    assert a.tobytes() == b.tobytes() and not np.array_equal(a, c)


def test_area_needs_enough_ink():
    m = np.zeros((10, 10), bool)
    m[2:4, 2:4] = True
    with pytest.raises(ValueError, match="4 ink pixels"):
        area_points(m, 5, np.random.default_rng(0))
