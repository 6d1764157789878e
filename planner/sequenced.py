"""Sequenced moves: robots moved one at a time (or, in dependency cycles, in
groups) from one placement to another, ordered so that every move is clear
of the robots parked on their sources and destinations.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .geometry import closest_approach, point_segment_distance
from .plan import step_duration
from .problem import Problem

__all__ = ["Sequenced", "sequenced_moves"]


@dataclass(frozen=True, eq=False)
class Sequenced:
    """Robots moved one at a time from placement ``va`` to placement ``vb``.

    Robot on ``va[rows[k]]`` goes to ``vb[cols[k]]`` along ``paths[k]`` (a
    polyline from source to destination); ``order`` lists ``k`` in the
    order the moves run; ``duration`` is the longest chain of dependent
    moves (what the moves take when independent ones overlap).  With
    ``groups`` (consecutive runs of ``order``), the robots of a group move
    together, leg by leg.
    """

    rows: np.ndarray
    cols: np.ndarray
    paths: tuple
    order: np.ndarray
    duration: float
    groups: tuple | None = None

    def waypoints(self, positions: np.ndarray, robots) -> list[np.ndarray]:
        """The steps, leg by leg, that move ``robots[k]`` (rows of ``positions``) in order."""
        pos = np.array(positions, float)
        robots = np.asarray(robots)
        out = []
        groups = self.groups if self.groups is not None else [[k] for k in self.order]
        for group in groups:
            legs = max(len(self.paths[k]) for k in group) - 1
            for s in range(1, legs + 1):
                pos = pos.copy()
                for k in group:
                    pos[robots[k]] = self.paths[k][min(s, len(self.paths[k]) - 1)]
                out.append(pos)
        return out


def sequenced_moves(problem: Problem, va: np.ndarray, vb: np.ndarray, bent: bool = False,
                    groups: bool = False, deadline: float | None = None) -> Sequenced | None:
    """Move the robots on ``va`` to ``vb`` one at a time, ordered by their conflicts.

    Robots go along a minimum-sum-of-squares assignment: of the straight
    segments clear of the obstacles, or with ``bent``, of shortest paths
    (the straight segment where it is clear, else the shortest polyline
    around the obstacles through a visibility graph of their corners,
    every leg checked exactly).  Robot ``i``'s path passing within
    the separation of robot ``j``'s source means ``j`` must leave first;
    passing near ``j``'s destination means ``i`` must pass before ``j``
    arrives.  When these dependencies have no cycle, moving robots in a
    topological order, each along its whole path, is collision-free by
    construction: while ``i`` moves, every other robot is parked on its
    source or its destination, and both are clear of ``i``'s path.
    Returns ``None`` when some robot has no path or the dependencies have a
    cycle.

    With ``groups``, a cycle does not end it: the robots of each strongly
    connected component of the dependencies move together (leg by leg,
    one shared time parameter per leg), components in a topological
    order.  Robots outside a component stay clear of its paths by the
    same argument (a robot parked on its source is in a later component,
    one on its destination in an earlier one, and the dependencies keep
    the paths clear of both); inside a component every pair of
    simultaneous legs is checked exactly (closest approach).  ``None``
    when such a check fails.
    """
    from scipy.optimize import linear_sum_assignment

    from .guide import shortest_paths, straight_lengths

    va = np.asarray(va, float)
    vb = np.asarray(vb, float)
    m = len(va)
    path_of = None
    if bent and problem.obstacles:
        length, path_of = shortest_paths(problem, va, vb, deadline)
    else:
        length = straight_lengths(problem, va, vb, deadline)
    big = 1e18
    cost = np.where(np.isfinite(length), length**2, big)
    rows, cols = linear_sum_assignment(cost)
    if not np.all(np.isfinite(length[rows, cols])):
        return None
    if path_of is None:
        paths = [np.stack([va[i], vb[j]]) for i, j in zip(rows, cols)]
    else:
        paths = [path_of(int(i), int(j)) for i, j in zip(rows, cols)]
    # Pad the polylines to one length (repeating the last point adds
    # zero-length legs) so that distances to them are computed at once.
    legs = max(len(p) for p in paths) - 1
    pad = np.stack([np.vstack([p, np.repeat(p[-1:], legs + 1 - len(p), axis=0)]) for p in paths])
    pa, pb = pad[:, :-1], pad[:, 1:]  # (m, legs, 2)
    sep = problem.separation
    b_of = vb[cols]
    moving = np.linalg.norm(pb - pa, axis=2).sum(axis=1) > 0

    def to_paths(points):  # (m points) -> (m paths, m points) distance
        return point_segment_distance(points[None, None], pa[:, :, None], pb[:, :, None]).min(axis=1)

    # first[j, i]: robot j must move before robot i.
    #   i's path passes j's source      -> j first
    #   i's path passes j's destination -> i first
    path_to_src = to_paths(va)
    path_to_dst = to_paths(b_of)
    np.fill_diagonal(path_to_src, np.inf)
    np.fill_diagonal(path_to_dst, np.inf)
    first = (path_to_src < sep).T | (path_to_dst < sep)
    first &= moving[None, :] | moving[:, None]
    order = _topological(first)
    if order is None and not groups:
        return None
    dur = step_duration(np.linalg.norm(pb - pa, axis=2), problem.max_speed, problem.max_accel).sum(axis=1)
    if order is None:
        return _grouped(rows, cols, paths, pa, pb, first, dur, sep)
    finish = np.zeros(m)
    for i in order:  # longest chain of dependent moves
        preds = np.flatnonzero(first[:, i])
        finish[i] = (finish[preds].max() if len(preds) else 0.0) + dur[i]
    return Sequenced(rows, cols, tuple(paths), np.asarray(order, int), float(finish.max(initial=0.0)))


def _grouped(rows, cols, paths, pa, pb, first, dur, sep) -> Sequenced | None:
    """:class:`Sequenced` moving each strongly connected component of ``first`` together."""
    from scipy.sparse.csgraph import connected_components

    n_comp, comp = connected_components(first, directed=True, connection="strong")
    cfirst = np.zeros((n_comp, n_comp), bool)  # component j before component i
    j, i = np.nonzero(first)
    cfirst[comp[j], comp[i]] = True
    np.fill_diagonal(cfirst, False)
    corder = _topological(cfirst)  # a condensation has no cycle
    members = [np.flatnonzero(comp == c) for c in range(n_comp)]
    for c in corder:
        g = members[c]
        if len(g) > 1:  # simultaneous legs: one shared parameter per leg
            d = closest_approach(pa[g][:, None], pb[g][:, None], pa[g][None], pb[g][None])  # (g, g, legs)
            d[np.arange(len(g)), np.arange(len(g))] = np.inf
            if d.min() < sep:
                return None
    groups = tuple(members[c].tolist() for c in corder)
    finish = np.zeros(n_comp)
    for c in corder:  # longest chain of dependent groups
        preds = np.flatnonzero(cfirst[:, c])
        finish[c] = (finish[preds].max() if len(preds) else 0.0) + dur[members[c]].max()
    order = np.concatenate([members[c] for c in corder])
    return Sequenced(rows, cols, tuple(paths), order, float(finish.max(initial=0.0)), groups)


def _topological(first: np.ndarray) -> list[int] | None:
    """Kahn's order of ``first[j, i]`` (j before i); ``None`` on a cycle.

    Among the robots free to go, the lowest index goes first, so the order
    is deterministic.
    """
    import heapq

    n = len(first)
    indeg = first.sum(axis=0).astype(int).tolist()
    succ = [np.flatnonzero(first[j]).tolist() for j in range(n)]
    ready = [i for i in range(n) if indeg[i] == 0]
    heapq.heapify(ready)
    out = []
    while ready:
        j = heapq.heappop(ready)
        out.append(j)
        for i in succ[j]:
            indeg[i] -= 1
            if indeg[i] == 0:
                heapq.heappush(ready, i)
    return out if len(out) == n else None
