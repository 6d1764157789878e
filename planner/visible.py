"""Straight visibility between two placements: which robot-to-target segments are clear.

Shared by the sequenced moves (:mod:`planner.sequenced`) and the shortest paths
around obstacles (:mod:`planner.guide`), which start from it; tested in chunks,
so its memory stays bounded and a deadline can stop it.
"""

from __future__ import annotations

import time

import numpy as np

from .problem import Problem

__all__ = ["Late", "clear_by", "straight_lengths"]


class Late(RuntimeError):
    """The deadline passed before a visibility or shortest-path computation ended (nothing is cached)."""


#: Segments tested per call in :func:`_visible` (its memory grows with them; 810 000 at once,
#: 900 robots to 900 targets among a room's walls, took 2.7 GB and 14 s past any deadline)
_VISIBLE_CHUNK = 50_000


def _visible(problem: Problem, a: np.ndarray, b: np.ndarray, deadline: float | None = None) -> np.ndarray:
    """``(len(a), len(b))`` mask of clear straight segments, tested in chunks of rows;
    raises :class:`Late` when ``deadline`` passes between two chunks."""
    out = np.zeros((len(a), len(b)), bool)
    if len(a) == 0 or len(b) == 0:
        return out
    rows = max(1, _VISIBLE_CHUNK // len(b))
    for r in range(0, len(a), rows):
        if deadline is not None and time.perf_counter() > deadline:
            raise Late("straight segments: past the deadline")
        part = a[r : r + rows]
        aa = np.repeat(part, len(b), axis=0)
        bb = np.tile(b, (len(part), 1))
        out[r : r + rows] = problem.env.segments_clear(aa, bb, problem.clearance).reshape(len(part), len(b))
    return out


#: Segments per call in :func:`clear_by` (10 000 among the 2 000 shelves of a warehouse: 0.25 s)
_CLEAR_CHUNK = 10_000


def clear_by(problem: Problem, a: np.ndarray, b: np.ndarray, deadline: float) -> np.ndarray | None:
    """``problem.env.segments_clear(a, b, clearance)``, tested in chunks of
    :data:`_CLEAR_CHUNK` segments; ``None`` when ``deadline`` passes between two."""
    out = np.zeros(len(a), bool)
    for r in range(0, len(a), _CLEAR_CHUNK):
        if time.perf_counter() > deadline:
            return None
        out[r : r + _CLEAR_CHUNK] = problem.env.segments_clear(a[r : r + _CLEAR_CHUNK], b[r : r + _CLEAR_CHUNK],
                                                               problem.clearance)
    return out


def straight_lengths(problem: Problem, starts: np.ndarray, targets: np.ndarray,
                     deadline: float | None = None) -> np.ndarray:
    """``(len(starts), len(targets))`` straight distances, ``inf`` where the segment is not clear.

    Remembered per problem and pair of placements (the straight and the
    bent sequenced moves, and the shortest paths, all start from it).
    Raises :class:`Late` (nothing remembered) when ``deadline`` passes first.
    """
    starts = np.ascontiguousarray(starts, float)
    targets = np.ascontiguousarray(targets, float)
    key = (starts.tobytes(), targets.tobytes())
    memo = problem.__dict__.setdefault("_straight_lengths", {})
    if key not in memo:
        direct = np.linalg.norm(starts[:, None] - targets[None], axis=2)
        if problem.obstacles:
            direct = np.where(_visible(problem, starts, targets, deadline), direct, np.inf)
        memo[key] = direct
    return memo[key]
