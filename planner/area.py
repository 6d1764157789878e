"""Robots spread evenly over the filled area of a mask (Lloyd relaxation).

:func:`area_points` draws ``m`` distinct ink pixels from the run's
generator, then moves every point to the centroid of the ink pixels nearest
to it (Lloyd's algorithm on the pixel centres, a discrete centroidal Voronoi
tessellation) for a fixed number of rounds, and finally snaps each point to
the nearest ink pixel centre, so that every robot lies on the ink.  The
result is close to a hexagonal packing of the ink with about equal spacing;
pairs that still come closer than the caller needs are pushed apart.

Coordinates are those of :mod:`planner.skeleton`: pixel ``(row, col)`` has
its centre at ``(col + 0.5, row + 0.5)``, rows counting upwards.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

__all__ = ["area_points", "ink_points"]

_ROUNDS = 40
_PUSH_ROUNDS = 200
_MAX_PIXELS = 4_000_000


def ink_points(mask: np.ndarray) -> np.ndarray:
    """The centres ``(N, 2)`` of the ink pixels of a boolean mask (y-up)."""
    mask = np.asarray(mask, bool)
    if mask.ndim != 2 or mask.size > _MAX_PIXELS:
        raise ValueError(f"mask must be 2-D with at most {_MAX_PIXELS} pixels, got shape {mask.shape}")
    rows, cols = np.nonzero(mask)
    return np.stack([cols + 0.5, rows + 0.5], axis=1).astype(float)


def area_points(mask: np.ndarray, m: int, rng: np.random.Generator, gap: float = 0.0,
                rounds: int = _ROUNDS) -> np.ndarray:
    """``(m, 2)`` points spread evenly over the ink of ``mask``, each on an ink pixel.

    ``gap`` [px, optional]: the distance the caller needs between two
    points; pairs closer than that after the relaxation are pushed apart
    (each by half the shortfall, then back onto the ink) for a bounded
    number of rounds, as far as the ink leaves room.  Raises ``ValueError``
    when the mask has fewer than ``m`` ink pixels.
    """
    pix = ink_points(mask)
    if m < 1:
        raise ValueError(f"m must be >= 1, got {m}")
    if len(pix) < m:
        raise ValueError(f"the mask has {len(pix)} ink pixels, fewer than the {m} robots")
    sites = pix[np.sort(rng.choice(len(pix), size=m, replace=False))].copy()
    for _ in range(rounds):
        _, near = cKDTree(sites).query(pix)
        count = np.bincount(near, minlength=m)
        sx = np.bincount(near, weights=pix[:, 0], minlength=m)
        sy = np.bincount(near, weights=pix[:, 1], minlength=m)
        has = count > 0
        sites[has, 0] = sx[has] / count[has]
        sites[has, 1] = sy[has] / count[has]
    # On the ink: each site snaps to its nearest pixel, in order; a pixel
    # already taken passes the site on to its next nearest free pixel.
    tree = cKDTree(pix)
    taken = np.zeros(len(pix), bool)
    out = np.empty((m, 2))
    for i, s in enumerate(sites):
        k = 1
        while True:
            _, idx = tree.query(s, k=min(k, len(pix)))
            idx = np.atleast_1d(idx)
            free = idx[~taken[idx]]
            if len(free):
                j = int(free[0])
                break
            k *= 4
        taken[j] = True
        out[i] = pix[j]
    if gap > 0:
        out = _push_apart(out, pix, mask, gap)
    return out


def _push_apart(pts: np.ndarray, pix: np.ndarray, mask: np.ndarray, gap: float) -> np.ndarray:
    """Move pairs closer than ``gap`` apart, keeping every point on the ink."""
    pts = pts.copy()
    tree = cKDTree(pix)
    h, w = mask.shape
    for _ in range(_PUSH_ROUNDS):
        pairs = cKDTree(pts).query_pairs(gap, output_type="ndarray")
        if not len(pairs):
            break
        i, j = pairs[:, 0], pairs[:, 1]
        v = pts[i] - pts[j]
        dist = np.hypot(v[:, 0], v[:, 1])
        u = np.where(dist[:, None] > 0, v / np.maximum(dist, 1e-12)[:, None], [1.0, 0.0])
        shift = 0.5 * (gap - dist)[:, None] * u * 1.05
        move = np.zeros_like(pts)
        np.add.at(move, i, shift)
        np.add.at(move, j, -shift)
        pts = pts + move
        col = np.clip(np.floor(pts[:, 0]).astype(int), 0, w - 1)
        row = np.clip(np.floor(pts[:, 1]).astype(int), 0, h - 1)
        off = ~mask[row, col] | (pts[:, 0] < 0) | (pts[:, 0] >= w) | (pts[:, 1] < 0) | (pts[:, 1] >= h)
        if off.any():
            pts[off] = pix[tree.query(pts[off])[1]]
    return pts
