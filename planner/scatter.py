"""Scatter: robots spread uniformly over the free space (Poisson-disc sampling).

:func:`poisson_disc` is Bridson's algorithm ("Fast Poisson disk sampling in
arbitrary dimensions", 2007) over the free part of a rectangular region:
points at least a spacing ``d`` apart, grown from random seeds by trying
``k`` candidates in the annulus ``[d, 1.1 d]`` around an active point (a
background grid of cell ``d / sqrt 2`` finds the neighbours), with every
candidate checked *exactly* against the walls and obstacles
(:meth:`planner.geometry.Environment.points_clear`).  When no point is
active any more, random darts over the whole region look for a gap that
the growth did not reach (free pockets cut off by obstacles); the run ends
when a round of darts finds none: the sample is then saturated.

:func:`scatter` picks the spacing for ``m`` robots: it searches ``d >=
2 r + margin`` for a saturated sample of at least ``m`` points (at most 5 %
over ``m``, or as few over as 8 samples find) and drops the surplus at
random.  When even the
densest spacing (the separation itself) saturates below ``m`` it raises
:class:`planner.problem.ProblemError` naming the field and the count that
saturated run reached: what this sampler achieves, an honest maximum for
the region.  Where obstacles split the free space, scenarios scatter over
its largest connected component only (:func:`largest_part`; the MovingAI
benchmark's scenarios do the same): a robot in a pocket could never reach
a target outside it.  The narrow annulus (Bridson's is ``[d, 2d]``) packs about 0.64
of a hexagonal packing at saturation where the wide one packs about 0.55, so
more robots fit at the same spacing; a hexagonal lattice could hold about
1.5x more, but it is not random.
"""

from __future__ import annotations

import math
import time

import numpy as np

from .geometry import Environment
from .problem import ProblemError
from .visible import Late

__all__ = ["largest_part", "poisson_disc", "scatter"]

_K = 30  # candidates per active point (Bridson's k)
_RING = 1.1  # candidates lie between d and _RING * d from the active point
_DARTS = 512  # random darts per gap-search round
_BATCH = 32  # active points whose candidates are tested at once
_RUNS = 8  # spacing search: saturated samples at most
_MAX_POINTS = 200_000  # a region and spacing that would need more are refused


def _free_fraction(env: Environment, region, clearance: float, rng: np.random.Generator, n: int = 4096,
                   part=None):
    lo, hi = np.asarray(region[:2], float), np.asarray(region[2:], float)
    pts = rng.uniform(lo, hi, size=(n, 2))
    ok = env.points_clear(pts, clearance)
    if part is not None and ok.any():
        ok[ok] = _within(part)(pts[ok])
    return float(ok.mean())


def largest_part(problem):
    """The largest connected component of the free space (a shapely polygon) when the
    free space has several, else ``None`` (:func:`planner.feasibility.free_space_parts`).

    Scatter spreads over it, as the MovingAI benchmark's scenarios do: robots in a
    pocket cut off from the rest could never reach targets elsewhere."""
    from .feasibility import _islands_apart, free_space_parts

    if not problem.obstacles or _islands_apart(problem):
        return None
    got = free_space_parts(problem)
    if got is None or len(got[0]) <= 1:
        return None
    return max(got[0], key=lambda g: g.area)


def _within(part):
    """A vectorised test ``(n, 2) -> (n,)`` of lying strictly inside ``part`` (``None``: everywhere)."""
    if part is None:
        return None
    import shapely

    shapely.prepare(part)
    return lambda c: shapely.contains_xy(part, c[:, 0], c[:, 1])


def poisson_disc(env: Environment, region, spacing: float, clearance: float,
                 rng: np.random.Generator, k: int = _K, part=None, deadline: float = math.inf) -> np.ndarray:
    """A saturated Poisson-disc sample ``(N, 2)`` of the free part of ``region``.

    ``region`` is ``(x0, y0, x1, y1)``; points lie in it, keep ``clearance``
    from walls and obstacles (exact) and ``spacing`` from each other; with
    ``part`` (a shapely polygon, :func:`largest_part`) only inside it.
    Raises :class:`planner.visible.Late` when ``deadline`` passes first.
    """
    within = _within(part)
    x0, y0, x1, y1 = (float(v) for v in region)
    d = float(spacing)
    if not (d > 0 and x1 > x0 and y1 > y0):
        raise ValueError(f"need spacing > 0 and a non-empty region, got {spacing}, {region}")
    cell = d / math.sqrt(2.0)
    nx_, ny_ = int(math.ceil((x1 - x0) / cell)) + 1, int(math.ceil((y1 - y0) / cell)) + 1
    if (x1 - x0) * (y1 - y0) / (0.5 * d * d) > _MAX_POINTS or nx_ * ny_ > 4 * _MAX_POINTS:
        raise ValueError(f"spacing {d:g} is too fine for the region (over {_MAX_POINTS} points)")
    grid = np.full((ny_ + 4, nx_ + 4), -1, np.int64)  # padded by 2 cells on each side
    pts: list[np.ndarray] = []
    arr = np.empty((0, 2))
    d2 = d * d
    offs = np.array([(a, b) for a in range(-2, 3) for b in range(-2, 3)])

    def cells(p):
        return (np.floor((p[..., 1] - y0) / cell).astype(np.int64) + 2,
                np.floor((p[..., 0] - x0) / cell).astype(np.int64) + 2)

    def far(c):
        """Which candidates ``(n, 2)`` keep the spacing from every point so far."""
        if not pts:
            return np.ones(len(c), bool)
        r, q = cells(c)
        nb = grid[r[:, None] + offs[None, :, 0], q[:, None] + offs[None, :, 1]]  # (n, 25)
        has = nb >= 0
        if not has.any():
            return np.ones(len(c), bool)
        other = arr[np.where(has, nb, 0)]
        dist2 = ((other - c[:, None, :]) ** 2).sum(-1)
        return ~np.any(has & (dist2 < d2), axis=1)

    def add(p):
        nonlocal arr
        r, q = cells(p)
        grid[int(r), int(q)] = len(pts)
        pts.append(p)
        if len(pts) > len(arr):
            grow = np.empty((max(16, 2 * len(arr)), 2))
            grow[: len(arr)] = arr
            arr = grow
        arr[len(pts) - 1] = p

    def inside(c):
        box = (c[:, 0] >= x0) & (c[:, 0] <= x1) & (c[:, 1] >= y0) & (c[:, 1] <= y1)
        if within is not None and box.any():
            box[box] = within(c[box])
        return box

    active: list[int] = []
    while True:
        # darts: a seed for the first point, then the gaps the growth missed
        darts = rng.uniform([x0, y0], [x1, y1], size=(_DARTS, 2))
        ok = inside(darts)
        ok[ok] = far(darts[ok])
        if ok.any():
            ok[ok] = env.points_clear(darts[ok], clearance)
        if not ok.any():
            break
        for p in darts[ok]:
            if far(p[None])[0]:  # darts of one round may crowd each other
                add(p)
                active.append(len(pts) - 1)
        while active:
            if time.perf_counter() > deadline:
                raise Late("scatter: past the deadline")
            # A batch of active points, their candidates tested against the obstacles in one
            # call (one call per point costs about a millisecond on a map of 2000 rectangles);
            # then each point in turn takes its first candidate that keeps the spacing from
            # every point so far (the points before the batch were tested with the rest), or
            # leaves the active list.
            pick = rng.choice(len(active), size=min(len(active), _BATCH), replace=False)
            base = arr[np.asarray(active)[pick]]
            rad = np.sqrt(rng.uniform(d2, _RING**2 * d2, size=(len(pick), k)))
            ang = rng.uniform(0, 2 * math.pi, size=(len(pick), k))
            c = base[:, None, :] + np.stack([rad * np.cos(ang), rad * np.sin(ang)], axis=2)
            flat = c.reshape(-1, 2)
            good = inside(flat)
            good[good] = far(flat[good])
            good[good] = env.points_clear(flat[good], clearance)
            good = good.reshape(len(pick), k)
            done = []
            before = len(pts)  # the candidates keep the spacing from these; only the batch's own points are left
            for row, j in enumerate(pick):
                cand = c[row][good[row]]
                if len(cand) and len(pts) > before:
                    new = arr[before : len(pts)]
                    cand = cand[~np.any(((new[None, :, :] - cand[:, None, :]) ** 2).sum(-1) < d2, axis=1)]
                if len(cand):
                    add(cand[0])
                    active.append(len(pts) - 1)
                else:
                    done.append(int(j))
            for j in sorted(done, reverse=True):
                active[j] = active[-1]
                active.pop()
    return arr[: len(pts)].copy()


def scatter(env: Environment, m: int, separation: float, clearance: float, rng: np.random.Generator,
            *, region=None, field: str = "target", part=None, deadline: float = math.inf) -> np.ndarray:
    """``(m, 2)`` placements spread uniformly over the free part of ``region`` (default: all).

    Pairwise at least ``separation`` apart and ``clearance`` from walls and
    obstacles, both exact; with ``part`` (:func:`largest_part`) only inside
    that component of the free space.  Raises :class:`ProblemError` naming
    ``field`` (with the achievable maximum) when ``m`` robots do not fit.
    """
    region = (0.0, 0.0, env.width, env.height) if region is None else tuple(float(v) for v in region)
    x0, y0, x1, y1 = region
    where = "the workspace" if region == (0.0, 0.0, env.width, env.height) else f"region {list(region)}"
    if part is not None:
        where = f"the largest connected part of {where}"
    area = (x1 - x0) * (y1 - y0) * _free_fraction(env, region, clearance, rng, part=part)
    # a saturated sample holds about 0.64 of a hexagonal packing
    guess = math.sqrt(0.64 * area / (math.sqrt(3) / 2 * max(m, 1))) if area > 0 else separation
    d = max(separation, guess)
    lo = hi = None  # spacings known to give >= m (lo) and < m (hi) points
    best = None
    for _ in range(_RUNS):
        pts = poisson_disc(env, region, d, clearance, rng, part=part, deadline=deadline)
        n = len(pts)
        if n >= m:
            if best is None or n < len(best):
                best = pts
            lo = d if lo is None else max(lo, d)
            if n <= m + max(2, m // 20):
                break
        else:
            if d <= separation * (1 + 1e-12):
                raise ProblemError(
                    field,
                    f"scatter: {m} robots do not fit {where} at spacing {separation:g}; "
                    f"at most {n} fit; lower robots.count",
                )
            hi = d if hi is None else min(hi, d)
        # next spacing: the count goes about as 1 / d^2, kept inside the bracket
        step = d * math.sqrt(max(n, 1) / m)
        if lo is not None and hi is not None:
            step = min(max(step, lo + 0.1 * (hi - lo)), hi - 0.1 * (hi - lo))
        elif hi is not None:
            step = min(step, hi * 0.97)
        d = max(separation, step)
    if best is None:
        pts = poisson_disc(env, region, separation, clearance, rng, part=part, deadline=deadline)
        if len(pts) < m:
            raise ProblemError(
                field,
                f"scatter: {m} robots do not fit {where} at spacing {separation:g}; "
                f"at most {len(pts)} fit; lower robots.count",
            )
        best = pts
    keep = np.sort(rng.choice(len(best), size=m, replace=False))
    return best[keep]
