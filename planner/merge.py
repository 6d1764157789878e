"""Fewer, longer straight moves: merged moves, merged steps and split moves.

See :mod:`planner.schedule` for how these passes shorten a plan without
changing what any robot does.
"""

from __future__ import annotations

import numpy as np

from .geometry import point_segment_distance
from .problem import Problem
from .steps import _late, step_clear, steps_clear, steps_of

__all__ = ["merge_moves", "merge_steps", "split_moves"]


def merge_moves(problem: Problem, waypoints: np.ndarray, deadline: float | None = None) -> np.ndarray:
    """Join consecutive single-robot moves of one robot when the direct move is clear.

    Greedy along each run of steps that move the same robot alone: from the
    run's first position the move is extended step by step while the
    straight move stays clear of the world and of the parked robots; where
    it stops, a new extension starts.  The candidate extensions of every
    run are tested together, one round per restart.
    """
    w = np.asarray(waypoints, float)
    if len(w) <= 2:
        return w
    movers = steps_of(w)
    single = np.array([len(mv) == 1 for mv in movers])
    who = np.array([int(mv[0]) if len(mv) == 1 else -1 for mv in movers])
    # maximal runs of >= 2 steps moving the same robot alone: (first step, last step, robot)
    pending = []
    k = 0
    while k < len(movers):
        j = k
        if single[k]:
            while j + 1 < len(movers) and single[j + 1] and who[j + 1] == who[k]:
                j += 1
        if j > k:
            pending.append((k, j, int(who[k])))
        k = j + 1
    last_of = {}  # first step of a joined move -> its last step
    sep = problem.separation
    while pending and not _late(deadline):
        # step k0 extended to end at waypoint e (k0 + 2 <= e <= k1 + 1)
        cand = [(n, k0, e, r) for n, (k0, k1, r) in enumerate(pending) for e in range(k0 + 2, k1 + 2)]
        n_of, k_of, e_of, r_of = (np.array(c) for c in zip(*cand))
        a, b = w[k_of, r_of], w[e_of, r_of]
        ok = problem.env.segments_clear(a, b, problem.clearance)
        if w.shape[1] > 1:
            d = point_segment_distance(w[k_of], a[:, None], b[:, None])  # (n, m): the parked robots
            d[np.arange(len(d)), r_of] = np.inf
            ok &= d.min(axis=1) >= sep
        nxt = []
        for n, (k0, k1, r) in enumerate(pending):
            mine = ok[n_of == n]
            j = k0 + (len(mine) if mine.all() else int(np.argmin(mine)))  # leading successes
            if j > k0:
                last_of[k0] = j
            if k1 - (j + 1) >= 1:  # two or more steps left: extend again from there
                nxt.append((j + 1, k1, r))
        pending = nxt
    out = [w[0]]
    k = 0
    while k < len(movers):
        k = last_of.get(k, k)
        out.append(w[k + 1])
        k += 1
    return np.asarray(out)


def merge_steps(problem: Problem, waypoints: np.ndarray, deadline: float | None = None) -> np.ndarray:
    """Greedily join consecutive steps into straight ones where that is clear.

    Every join of two consecutive original steps is tested up front
    (:func:`steps_clear`); a join onto a step that is itself already joined
    is tested when the greedy pass reaches it.  Past ``deadline`` nothing
    more is joined.
    """
    w = np.asarray(waypoints, float)
    if len(w) <= 2:
        return w
    # two[k]: w[k] -> w[k + 2] straight is clear; a move straight on through w[k + 1] is the
    # union of its two pieces, so only the others are tested against the obstacles (a merged
    # step is then clear of them exactly when its pieces were)
    two = steps_clear(problem, w[:-2], w[2:], deadline, via=w[1:-1])
    out = [w[0], w[1]]
    first = 0  # index in w of out[-2]
    for i in range(2, len(w)):
        if i - first == 2:
            clear = two[first]
        else:
            clear = not _late(deadline) and step_clear(problem, w[first], w[i])
        if clear:
            out[-1] = w[i]  # the last step now runs straight to ``w[i]``
        else:
            out.append(w[i])
            first = i - 1
    return np.asarray(out)


def split_moves(problem: Problem, waypoints: np.ndarray, piece: float | None = None) -> np.ndarray:
    """Cut long single-robot moves into straight pieces, so moves can overlap.

    A robot that must wait for another to get out of its way can start as
    soon as the first piece of the other's move is done, instead of after
    the whole move (the scheduler then packs pieces of different moves into
    common steps, and :func:`merge_steps` rejoins pieces that end up
    consecutive and clear).  Pieces default to the length beyond which a
    move is speed-limited, so cutting costs no time.
    """
    w = np.asarray(waypoints, float)
    if piece is None:
        # speed-limited above d*: 15/8 d / v = sqrt(10/sqrt(3) d / a)
        piece = (10 / np.sqrt(3)) * problem.max_speed**2 / ((15 / 8) ** 2 * problem.max_accel)
        piece = max(piece, problem.separation)
    out = [w[0]]
    for k in range(len(w) - 1):
        a, b = w[k], w[k + 1]
        moving = np.flatnonzero(np.any(a != b, axis=1))
        if len(moving) != 1:
            out.append(b)
            continue
        r = int(moving[0])
        n = int(np.floor(np.linalg.norm(b[r] - a[r]) / piece))
        for j in range(1, n):
            mid = out[-1].copy()
            mid[r] = a[r] + (j / n) * (b[r] - a[r])
            out.append(mid)
        out.append(b)
    return np.asarray(out)
