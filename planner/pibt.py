"""Priority inheritance with goal swapping on the free-space roadmap, every move tested exactly.

Robots that wait for each other in a narrow corridor stall plain
goal-swapping routing: nobody can get closer, so nobody moves.  PIBT
(Okumura, Machida, Defago and Tamura, "Priority inheritance with
backtracking for iterative multi-agent path finding", Artificial
Intelligence 310, 2022) pushes them out of the way instead.  At every time
step the robots decide in order of priority (the steps since each last
stood on its target, ties broken by a random number drawn once); a robot
takes, of its roadmap neighbours, the one nearest its target along the
roadmap whose move is free, and when robots that have not decided yet
stand in the way it lends them its priority: each must move first, away
from the place it wants (recursively, a failed push falls back to the
next neighbour), and a robot that cannot stays put.

Because robots are unlabeled, targets are exchanged as in TSWAP (Okumura
and Defago, "Solving simultaneous target assignment and path planning
efficiently with time-independent execution", Artificial Intelligence
321, 2023): a robot whose next move is blocked by a robot resting on its
own target takes that target and gives it its own.

The roadmap's vertices need not be separated: instead of vertex
occupancy, a move is free when its straight segment keeps the separation,
exactly (:func:`planner.geometry.closest_approach` under the shared time
scaling), from every move already decided in this step, from the robots
not yet decided where they stand, and from the moves the robots pushing it
want to make (and from them standing: a push may fail).  Every pair of
robots is therefore tested with both actual motions by whichever decides
second, so each step is clear of the other robots; the roadmap's edges are
clear of the obstacles.
"""

from __future__ import annotations

import time

import numpy as np

from .endgame import sequential_finish
from .geometry import closest_approach

__all__ = ["pibt_route"]


def pibt_route(roadmap, field: np.ndarray, goal_of: list[int], sep: float, deadline: float,
               rng: np.random.Generator, max_steps: int, hop: float = np.inf, patience: int = 5) -> list[np.ndarray] | None:
    """Waypoints ``[(m, 2), ...]`` from the roadmap's first ``m`` vertices (the starts) to
    its next ``m`` (the targets), or ``None`` when ``max_steps`` or the deadline pass.

    ``field[g]`` is the roadmap length from every vertex to target ``g``
    (vertex ``m + g``); ``goal_of[i]`` the target first given to robot ``i``; robots
    move along roadmap edges at most ``hop`` separations long.  A time step in which
    nobody moves is allowed ``patience`` times in a row (the target swaps and the random
    ties change the next one).
    """
    pts = roadmap.points
    m = roadmap.m
    goal_of = list(goal_of)
    where = list(range(m))
    pos = pts[:m].copy()
    # Short edges only (a vertex without one keeps its shortest): a long hop sweeps the
    # places a pushed robot could step aside to; PIBT's moves are to adjacent vertices.
    nbrs = []
    for adj in roadmap.nbr:
        short = [u for u, d in adj if d <= hop * sep]
        if not short and adj:
            short = [min(adj, key=lambda x: x[1])[0]]
        nbrs.append(np.array(short, dtype=int))
    waiting = np.zeros(m)  # steps since each robot last stood on its target
    tie = rng.random(m)
    out = [pos.copy()]
    idle = since = 0
    best = np.inf
    stale = 100 + 2 * m  # steps without a new lowest sum of roadmap lengths left

    def at_goal(i: int) -> bool:  # a start may be a target's very point
        return where[i] == m + goal_of[i] or bool((pts[where[i]] == pts[m + goal_of[i]]).all())

    for _ in range(max_steps):
        if time.perf_counter() > deadline:
            return None
        done = [at_goal(i) for i in range(m)]
        if all(done):
            return out
        waiting = np.where(done, 0.0, waiting + 1.0)
        _swap_targets(pts, pos, where, nbrs, field, goal_of, sep, at_goal)
        step = _Step(pts, pos, where, nbrs, field, goal_of, sep, rng)
        for i in sorted(range(m), key=lambda i: -(waiting[i] + tie[i])):
            if not step.decided[i]:
                step.decide(i, [])
        if not step.moved:
            idle += 1
            if idle > patience:
                break  # nobody can move: the steps would repeat
            continue
        idle = 0
        left = sum(field[goal_of[i]][step.where[i]] for i in range(m))
        if left < best - 1e-9:
            best, since = left, 0
        else:
            since += 1
            if since > stale:
                break  # pushing about without getting anywhere
        pos = step.nxt
        where = step.where
        out.append(pos.copy())
    extra = sequential_finish(roadmap, pos, where, sep, deadline)  # the last few, one at a time
    return None if extra is None else out + extra


def _swap_targets(pts, pos, where, nbrs, field, goal_of, sep, at_goal) -> None:
    """TSWAP's rule: a robot whose best next move is blocked by a robot resting on
    its own target exchanges targets with it."""
    for i in range(len(pos)):
        if at_goal(i) or not len(nbrs[where[i]]):
            continue
        row = field[goal_of[i]]
        nb = nbrs[where[i]]
        v = nb[np.argmin(row[nb])]
        if row[v] >= row[where[i]]:
            continue
        d = closest_approach(pos[i], pts[v], pos, pos)
        d[i] = np.inf
        close = np.flatnonzero(d < sep)
        if not len(close):
            continue
        j = int(close[np.argmin(np.hypot(*(pos[close] - pts[v]).T))])
        if at_goal(j):
            goal_of[i], goal_of[j] = goal_of[j], goal_of[i]


class _Step:
    """One PIBT time step: ``nxt`` the positions reached, ``decided`` per robot."""

    def __init__(self, pts, pos, where, nbrs, field, goal_of, sep, rng):
        self.pts, self.pos, self.nbrs, self.field, self.goal_of, self.sep = pts, pos, nbrs, field, goal_of, sep
        self.rng = rng
        self.where = list(where)
        self.nxt = pos.copy()
        self.decided = np.zeros(len(pos), bool)
        self.moved = False

    def _candidates(self, i: int, pushed: bool) -> list[int]:
        """Neighbours nearest robot i's target first (random ties); staying (-1) ranked
        among them unless pushed."""
        here = self.where[i]
        nb = self.nbrs[here]
        row = self.field[self.goal_of[i]]
        order = nb[np.lexsort((self.rng.random(len(nb)), row[nb]))].tolist()
        if pushed:
            return order
        k = int((row[nb] < row[here]).sum())
        return order[:k] + [-1]

    def decide(self, i: int, pushers: list[tuple[int, np.ndarray]]) -> bool:
        """Robot i's move this step; ``pushers`` are the robots (with the places they
        want) whose priority it inherited.  False when it stays (so failed its pushers)."""
        pos, sep = self.pos, self.sep
        self.decided[i] = True  # no robot pushes one that is already deciding
        ancestors = {a for a, _ in pushers}
        for v in self._candidates(i, bool(pushers)):
            if v < 0:
                break
            b = self.pts[v]
            d = closest_approach(pos[i], b, pos, self.nxt)
            d[i] = np.inf
            hit = d < sep
            if not hit.any() and not self._hits_pushers(pos[i], b, pushers):
                self._commit(i, v)
                return True
            blockers = np.flatnonzero(hit).tolist()
            if self._hits_pushers(pos[i], b, pushers) or any(
                    self.decided[j] or j in ancestors for j in blockers):
                continue
            chain = pushers + [(i, b)]
            if not all(self.decided[j] or self.decide(j, chain) for j in blockers):
                continue
            d = closest_approach(pos[i], b, pos, self.nxt)
            d[i] = np.inf
            if d.min() >= sep:
                self._commit(i, v)
                return True
        self.nxt[i] = pos[i]
        return False

    def _hits_pushers(self, a: np.ndarray, b: np.ndarray, pushers) -> bool:
        """Whether a -> b comes closer than the separation to a pusher, where it stands
        or on the move it wants."""
        if not pushers:
            return False
        idx = [p for p, _ in pushers]
        want = np.array([w for _, w in pushers])
        here = self.pos[idx]
        return bool((closest_approach(a, b, here, want) < self.sep).any()
                    or (closest_approach(a, b, here, here) < self.sep).any())

    def _commit(self, i: int, v: int) -> None:
        self.nxt[i] = self.pts[v]
        self.where[i] = v
        self.moved = True
