"""The geometric contact witness: the exact smallest gap of every sample, robot pairs through Verlet lists.

Between samples it sweeps (:mod:`sim.execute.swept`): a contact that begins
and ends inside one step, so that both samples are clear, is still seen.
"""

from __future__ import annotations

import math

import numpy as np

from .contacts import ROBOT_OBSTACLE, ROBOT_ROBOT, ROBOT_WALL, Contact, _contacts, static_clearances
from .kernels import circle_clearance, wall_clearance

__all__ = ["SERIES_CAP", "GapMonitor"]




# Samples that share one Verlet list of candidate robot pairs, and the
# candidates per robot above which the monitor switches to per-sample
# nearest neighbours.
_VERLET_SPAN = 16
_PAIRS_PER_ROBOT = 40

SWEEP_FRACTION = 0.1
"""Between two samples in which some robot moves more than ``SWEEP_FRACTION``
radii, :meth:`GapMonitor.observe` sweeps the straight moves.  Slower moves
are not swept: two discs (or a disc and an obstacle) clear at both ends of a
move of relative length ``D`` overlap in between by at most ``D^2 / (16 r)``
(``r / 400`` at this fraction), while a straight chord is only an
approximation of the true, curved path."""

SERIES_CAP = 2.0
"""Per-sample smallest gaps above ``SERIES_CAP * radius`` (one robot diameter) are
recorded as that cap: nothing that far apart is near a contact, and the cap
bounds the pairs the monitor measures."""

class GapMonitor:
    """Exact gaps at the recorded samples, the smallest one, and touching episodes.

    Feed it samples in time order with :meth:`observe`.  ``min_gap`` is the
    smallest gap seen [units], ``min_time`` its time [s], ``min_kind`` and
    ``min_pair`` what attained it (robot pair; or robot and obstacle index,
    ``-1`` for the wall).  These are of the samples; contacts found
    between samples (:meth:`sweep`) are contacts with their own depth, and
    the least gap among them is ``swept_min_gap`` at ``swept_min_time``.
    """

    swept = True
    """Sweep between samples (switch off only to show what the sampled check alone misses)."""

    def __init__(self, problem):
        self.radius = float(problem.radius)
        self.cap = SERIES_CAP * self.radius
        self.env = problem.env
        self.n_obstacles = len(problem.obstacles)
        self.min_gap = float("inf")
        self.min_time = float("nan")
        self.min_kind = ""
        self.min_pair = (-1, -1)
        self._records: list[list] = []
        self._active: dict[tuple, list] = {}
        self._series: list[np.ndarray] = []
        self.swept_min_gap = float("inf")
        self.swept_min_time = float("nan")
        self._last: tuple[float, np.ndarray] | None = None  # the last sample observed
        self._covered: set[float] = set()  # starts of steps swept along their substeps

    def contacts(self) -> list[Contact]:
        return _contacts(self._records, "monitor")

    @property
    def series(self) -> np.ndarray:
        """``(T,)`` smallest gap of every sample observed so far [units], capped at :attr:`cap`."""
        return np.concatenate(self._series) if self._series else np.zeros(0)

    # -- robot pairs --------------------------------------------------------------
    def _robot_pairs(self, pos: np.ndarray, bound: float):
        """Robot-robot gaps of the samples ``pos`` ``(C, m, 2)``.

        Returns the smallest gap with its ``(sample, i, j)``, the touching
        ``(sample, i, j, gap)`` rows and the ``(C,)`` smallest gap of each
        sample.  The smallest gap is exact whenever it is below ``bound``
        (otherwise it is only known to be at least ``bound``, and ``inf``
        may be returned); a sample's smallest gap is exact whenever it is
        below :attr:`cap` (otherwise it is at least the cap).
        """
        best, where, touching = np.inf, None, []
        per_sample = np.full(len(pos), np.inf)
        if pos.shape[1] < 2:
            return best, where, touching, per_sample
        for s0 in range(0, len(pos), _VERLET_SPAN):
            g, w, t, ps = self._pairs_block(pos[s0 : s0 + _VERLET_SPAN], min(bound, best))
            if g < best:
                best, where = g, (s0 + w[0], w[1], w[2])
            touching.extend((s0 + s, i, j, gap) for s, i, j, gap in t)
            per_sample[s0 : s0 + len(ps)] = ps
        return best, where, touching, per_sample

    def _pairs_block(self, pos: np.ndarray, bound: float):
        """:meth:`_robot_pairs` for a few consecutive samples.

        Candidate pairs (a Verlet list): no robot moves more than ``D``
        from its position in the first sample, so a pair farther apart than
        ``2 r + 2 D + max(bound, cap, 0)`` there keeps a gap above
        ``max(bound, cap, 0)`` in every sample: it neither touches nor
        lowers the minimum nor any sample's minimum below the cap.  Only the
        closer pairs are measured, all samples at once.
        """
        from scipy.spatial import cKDTree

        c, m = pos.shape[:2]
        two_r = 2.0 * self.radius
        touching: list[tuple[int, int, int, float]] = []
        best, where = np.inf, None
        per_sample = np.full(c, np.inf)
        move = pos - pos[:1]
        reach = float(np.sqrt(np.einsum("cmk,cmk->cm", move, move).max()))
        cutoff = two_r + 2.0 * reach + max(bound, self.cap, 0.0) + 1e-9
        pairs = cKDTree(pos[0]).query_pairs(cutoff, output_type="ndarray")
        if len(pairs) > _PAIRS_PER_ROBOT * m:
            # Too many candidates (sparse robots, large bound): exact nearest
            # neighbours per sample instead.
            for s in range(c):
                tree = cKDTree(pos[s])
                dd, jj = tree.query(pos[s], k=2)
                i = int(np.argmin(dd[:, 1]))
                g = float(dd[i, 1]) - two_r
                per_sample[s] = g
                if g < best:
                    j = int(jj[i, 1])
                    best, where = g, (s, min(i, j), max(i, j))
                if g < 0.0:
                    for i, j in tree.query_pairs(two_r, output_type="ndarray"):
                        gap = float(np.linalg.norm(pos[s, i] - pos[s, j])) - two_r
                        if gap < 0.0:
                            touching.append((s, int(i), int(j), gap))
            return best, where, touching, per_sample
        if len(pairs) == 0:
            return best, where, touching, per_sample
        pi, pj = pairs[:, 0], pairs[:, 1]
        diff = pos[:, pi] - pos[:, pj]
        d2 = np.einsum("cpk,cpk->cp", diff, diff)
        per_sample = np.sqrt(d2.min(axis=1)) - two_r
        s, q = divmod(int(np.argmin(d2)), d2.shape[1])
        g = math.sqrt(d2[s, q]) - two_r
        i, j = int(pi[q]), int(pj[q])
        best, where = g, (s, min(i, j), max(i, j))
        if g < 0.0:
            for s, q in zip(*np.nonzero(d2 < two_r * two_r)):
                gap = math.sqrt(d2[s, q]) - two_r
                if gap < 0.0:
                    i, j = int(pi[q]), int(pj[q])
                    touching.append((int(s), min(i, j), max(i, j), gap))
        return best, where, touching, per_sample

    # -- samples --------------------------------------------------------------------
    def observe(self, times: np.ndarray, positions: np.ndarray) -> None:
        """Take samples ``positions`` ``(C, m, 2)`` at ``times`` ``(C,)`` (after earlier ones)."""
        times = np.asarray(times, float).reshape(-1)
        pos = np.asarray(positions, float)
        c, m = pos.shape[:2]
        if c == 0:
            return
        r = self.radius
        events: list[tuple[int, str, int, int, float]] = []

        pts = pos.reshape(-1, 2)
        # Polygon entries need to be exact only where they could be the
        # smallest gap of the chunk, or of their sample up to the cap, or an
        # overlap: below what the walls and circles already give (never
        # below the radius, i.e. a zero gap).
        env = self.env
        cheap_pt = wall_clearance(pts, env.width, env.height)
        if len(env.circle_radii):
            cheap_pt = np.minimum(cheap_pt, circle_clearance(pts, env.circle_centers, env.circle_radii).min(axis=1))
        cheap_s = cheap_pt.reshape(c, m).min(axis=1)
        cheap = float(cheap_s.min())
        below_s = np.maximum(max(cheap, r), np.minimum(cheap_s, self.cap + r)) + 1e-9
        gaps = static_clearances(env, pts, self.n_obstacles, below=np.repeat(below_s, m)) - r
        sample_min = np.minimum(gaps.reshape(c, -1).min(axis=1), self.cap)
        flat = int(np.argmin(gaps))
        row, col = divmod(flat, gaps.shape[1])
        g = float(gaps[row, col])
        if g < self.min_gap:
            s, i = divmod(row, m)
            ob = col if col < self.n_obstacles else -1
            kind = ROBOT_OBSTACLE if ob >= 0 else ROBOT_WALL
            self._set_min(g, times[s], kind, (i, ob))
        if g < 0.0:
            for row, col in zip(*np.nonzero(gaps < 0.0)):
                s, i = divmod(int(row), m)
                ob = int(col) if col < self.n_obstacles else -1
                kind = ROBOT_OBSTACLE if ob >= 0 else ROBOT_WALL
                events.append((s, kind, i, ob, float(gaps[row, col])))

        best, where, touching, pair_min = self._robot_pairs(pos, self.min_gap)
        if best < self.min_gap:
            s, i, j = where
            self._set_min(best, times[s], ROBOT_ROBOT, (i, j))
        events.extend((s, ROBOT_ROBOT, i, j, g) for s, i, j, g in touching)
        self._series.append(np.minimum(sample_min, pair_min))

        if events or self._active:
            self._episodes(times, events)
        if self.swept:
            self._sweep_samples(times, pos)
        self._last = (float(times[-1]), pos[-1].copy())

    def _set_min(self, gap: float, time: float, kind: str, pair: tuple[int, int]) -> None:
        self.min_gap = float(gap)
        self.min_time = float(time)
        self.min_kind = kind
        self.min_pair = (int(pair[0]), int(pair[1]))

    def _episodes(self, times: np.ndarray, events) -> None:
        by_sample: dict[int, dict[tuple, float]] = {}
        for s, kind, a, b, gap in events:
            by_sample.setdefault(s, {})[(kind, a, b)] = gap
        for s in range(len(times)):
            now = by_sample.get(s, {})
            for key in [k for k in self._active if k not in now]:
                del self._active[key]
            for key, gap in now.items():
                record = self._active.get(key)
                if record is None:
                    record = [float(times[s]), key[0], key[1], key[2], -gap]
                    self._records.append(record)
                    self._active[key] = record
                else:
                    record[4] = max(record[4], -gap)

    # -- between samples ----------------------------------------------------------------
    def _sweep_samples(self, times: np.ndarray, pos: np.ndarray) -> None:
        """Sweep the straight moves between consecutive observed samples where some robot moves fast."""
        if self._last is not None:
            times = np.concatenate([[self._last[0]], times])
            pos = np.concatenate([self._last[1][None], pos])
        if len(pos) < 2:
            return
        move = pos[1:] - pos[:-1]
        fast = np.einsum("kmx,kmx->km", move, move).max(axis=1) > (SWEEP_FRACTION * self.radius) ** 2
        if self._covered:
            fast &= ~np.isin(times[:-1], list(self._covered))
        k = np.flatnonzero(fast)
        if len(k):
            self._sweep_moves(times[k], times[k + 1], pos[k], pos[k + 1], pos[k], pos[k + 1], k)

    def sweep(self, times: np.ndarray, positions: np.ndarray) -> None:
        """Sweep the path ``positions`` ``(S + 1, m, 2)`` at ``times`` ``(S + 1,)`` between two samples.

        The first and last rows are the samples at the ends of one step
        (given to :meth:`observe` too); the rows between are positions
        within the step (physics substeps).  The path is straight between
        rows.  Each pair (two robots, or a robot and an obstacle) whose
        least gap along the path is below 0 while it is clear at both ends
        opens one contact (``witness`` ``monitor``, ``swept`` true), timed
        at the closest approach, with that gap's depth.
        """
        times = np.asarray(times, float).reshape(-1)
        pos = np.asarray(positions, float)
        if len(pos) < 2:
            return
        self._covered.add(float(times[0]))
        if self.swept:
            self._sweep_path(times, pos)

    def _sweep_path(self, times: np.ndarray, pos: np.ndarray) -> None:
        n = len(pos) - 1
        first, last = np.broadcast_to(pos[0], pos[1:].shape), np.broadcast_to(pos[-1], pos[1:].shape)
        self._sweep_moves(times[:-1], times[1:], pos[:-1], pos[1:], first, last, np.zeros(n, int))

    def _sweep_moves(self, t0, t1, p0, p1, end0, end1, step) -> None:
        """Sweep the straight moves ``p0 -> p1`` ``(K, m, 2)`` over ``[t0, t1]`` ``(K,)``.

        Move ``k`` belongs to the step ``step[k]`` between the samples
        ``end0[k]`` and ``end1[k]``; each pair touching within a step whose
        samples are both clear opens one contact, at its closest approach.
        """
        from .swept import swept_hits

        hits = swept_hits(self.radius, self.env, p0, p1)
        if not hits:
            return
        best: dict[tuple, tuple[float, float, int]] = {}
        for k, kind, a, b, gap, s in hits:
            key = (int(step[k]), kind, a, b)
            if key not in best or gap < best[key][0]:
                best[key] = (gap, float(t0[k] + s * (t1[k] - t0[k])), k)
        for (_, kind, a, b), (gap, t, k) in sorted(best.items(), key=lambda kv: kv[1][1]):
            if self._end_gap(np.stack([end0[k], end1[k]]), kind, a, b) < 0.0:
                continue  # touching at a sample: the sampled check has it
            self._records.append([t, kind, a, b, -gap, True])
            if gap < self.swept_min_gap:
                self.swept_min_gap, self.swept_min_time = gap, t

    def _end_gap(self, ends: np.ndarray, kind: str, a: int, b: int) -> float:
        """The smaller gap of the pair at the two samples ``ends`` ``(2, m, 2)``."""
        if kind == ROBOT_ROBOT:
            d = ends[:, a] - ends[:, b]
            return float(np.sqrt(np.einsum("kx,kx->k", d, d)).min()) - 2.0 * self.radius
        col = b if b >= 0 else self.n_obstacles
        return float(static_clearances(self.env, ends[:, a], self.n_obstacles)[:, col].min()) - self.radius
