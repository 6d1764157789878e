"""Routing with steps of two cells: a time-expanded program whose steps differ in length.

A plan's step is a straight move of every robot from rest to rest, as long as
its longest move: one cell of ``c`` takes ``t1 = step_duration(c)``, two cells
in a straight line ``t2 = step_duration(2 c)`` (4.5 s against 2 x 2.63 s at
cells of 2.4, speed 2 and acceleration 2: the second cell is travelled at
speed instead of stopping).  :mod:`planner.gridflow` routes in steps of one
cell; here a routing is a sequence of *kinds*, each step either of kind 1
(every robot waits or moves to a neighbour) or of kind 2 (every robot waits,
moves one cell, or two cells straight on along two clear edges), and a
routing of ``n1`` steps of kind 1 and ``n2`` of kind 2 lasts
``n1 t1 + n2 t2``.

The program is the flow of :mod:`planner.gridflow` on the moves of each
step's kind (unit vertex capacities at the step ends), with one rule for
robots close together, derived from the geometry instead of listed by hand:
within a step every robot goes straight at one shared time scaling, so the
difference of two robots' positions moves on the segment from ``r0 = pa -
pb`` to ``r0 + da - db`` (grid units), and two moves ``(va, da)``, ``(vb,
db)`` are exclusive (``x_a + x_b <= 1``) exactly when that segment comes
within ``separation / c`` of the origin without ending there (ending there
is the vertex capacity).  For steps of kind 1 on a grid finer than
``sqrt(2)`` separations this is :mod:`planner.gridflow`'s pair of rules (no
swap, no following with a turn); coarser, following with a turn is allowed.
A move of two cells that passes a standing robot, or meets one coming the
other way, is excluded the same way.  Every step of the result is checked
again exactly by the grid stage.

The kinds tried (:func:`super_route`): every ``(n1, n2)`` whose duration is
below the routing to beat and whose reach ``n1 + 2 n2`` is at least the
relaxed flow's horizon (:func:`planner.gridflow.relaxed_horizon`; no routing
reaches farther in fewer cells), with the steps of kind 1 split between the
two ends (robots start and end packed, where long moves conflict most),
searched by bisection over the durations; a program that runs out of time
counts as infeasible, as in :func:`planner.gridflow.flow_route`.
"""

from __future__ import annotations

import math
import time
from functools import lru_cache

import numpy as np

from .grid import Lattice
from .gridflow import FLOW_MAX_VARIABLES, flow_rows, grid_distances, relaxed_horizon

__all__ = ["MOVES", "conflict_offsets", "kinds_of", "super_route"]

#: Moves in grid units: the four neighbour slots of :class:`planner.grid.Lattice`
#: (right, up, left, down), waiting, then two cells along each slot.
MOVES = np.array([(1, 0), (0, 1), (-1, 0), (0, -1), (0, 0), (2, 0), (0, 2), (-2, 0), (0, -2)])
_WAIT = 4
_TWO = 5  # moves from this index on are two cells long


def _heads(lat: Lattice) -> np.ndarray:
    """Vertex reached by every move from every vertex ``(n, 9)`` (-1: none): two-cell
    moves need both edges."""
    n = lat.n
    head = np.full((n, len(MOVES)), -1)
    head[:, :4] = lat.nbr
    head[:, _WAIT] = np.arange(n)
    for k in range(4):
        mid = lat.nbr[:, k]
        ok = mid >= 0
        head[ok, _TWO + k] = lat.nbr[mid[ok], k]
    return head


@lru_cache(maxsize=8)
def conflict_offsets(sep_c: float) -> dict[tuple[int, int], list[tuple[int, int]]]:
    """For every pair of moves ``(a, b)``, the grid offsets ``r0 = pa - pb`` (non-zero)
    at which the two moves, made at one time scaling, come closer than ``sep_c`` grid
    units (a hair more, to stay on the safe side) without ending on one vertex."""
    out: dict[tuple[int, int], list[tuple[int, int]]] = {}
    span = 4 + math.ceil(sep_c)
    for a in range(len(MOVES)):
        for b in range(len(MOVES)):
            d = (MOVES[a] - MOVES[b]).astype(float)
            dd = float(d @ d)
            offs = []
            for x in range(-span, span + 1):
                for y in range(-span, span + 1):
                    r0 = np.array([x, y], float)
                    if (x, y) == (0, 0) or not (r0 + d).any():
                        continue
                    s = 0.0 if dd == 0 else min(1.0, max(0.0, -float(r0 @ d) / dd))
                    if math.hypot(*(r0 + s * d)) < sep_c * (1 + 1e-9):
                        offs.append((x, y))
            out[(a, b)] = offs
    return out


def _program(lat: Lattice, ij: np.ndarray, vid: np.ndarray, sv, gv, kinds: list[int], sep_c: float):
    """Arrays of the integer program for the step ``kinds``, or ``None`` when too big."""
    from scipy.sparse import coo_matrix

    n, steps = lat.n, len(kinds)
    head = _heads(lat)
    cum = np.concatenate([[0], np.cumsum(kinds)])
    ds, dg = grid_distances(lat, sv), grid_distances(lat, gv)
    hv = np.where(head >= 0, head, 0)
    tt, vv, kk = [], [], []
    for t in range(steps):
        ok = (head >= 0) & ((ds <= cum[t]) & (dg <= cum[-1] - cum[t]))[:, None]
        ok &= (ds[hv] <= cum[t + 1]) & (dg[hv] <= cum[-1] - cum[t + 1])
        if kinds[t] == 1:
            ok[:, _TWO:] = False
        v, k = np.nonzero(ok)
        tt.append(np.full(len(v), t))
        vv.append(v)
        kk.append(k)
    t_, v_, k_ = np.concatenate(tt), np.concatenate(vv), np.concatenate(kk)
    nvar = len(t_)
    if nvar > FLOW_MAX_VARIABLES:
        return None
    h_ = head[v_, k_]
    index = np.full((steps, n, len(MOVES)), -1)
    index[t_, v_, k_] = np.arange(nvar)
    rows, cols, vals, lo, hi, r = flow_rows(n, t_, v_, h_, steps, sv, gv)
    # pairs of moves that come too close (module docstring)
    nx, ny = vid.shape
    pa, pb = [], []
    for a, b in ((i, j) for i in range(len(MOVES)) for j in range(i, len(MOVES))):
        ia = np.nonzero(k_ == a)[0]
        for x, y in conflict_offsets(sep_c)[(a, b)] if len(ia) else ():
            u = ij[v_[ia]] - np.array([x, y])
            inside = (u[:, 0] >= 0) & (u[:, 0] < nx) & (u[:, 1] >= 0) & (u[:, 1] < ny)
            jb = np.full(len(ia), -1)
            ub = vid[u[inside, 0], u[inside, 1]]
            jb[inside] = np.where(ub >= 0, index[t_[ia[inside]], np.maximum(ub, 0), b], -1)
            good = (jb >= 0) & ((jb > ia) if a == b else True)
            pa.append(ia[good])
            pb.append(jb[good])
    if pa:
        p, q = np.concatenate(pa), np.concatenate(pb)
        rows += [r + np.arange(len(p))] * 2
        cols += [p, q]
        vals += [np.ones(len(p))] * 2
        lo.append(np.full(len(p), -np.inf))
        hi.append(np.ones(len(p)))
        r += len(p)
    a_ = coo_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(r, nvar)).tocsr()
    return a_, np.concatenate(lo), np.concatenate(hi), (t_, v_, h_)


def _solve(lat, ij, vid, sv, gv, kinds, sep_c, budget):
    """Vertex of every robot after every step ``(len(kinds) + 1, m)``, ``None`` when there
    is none, ``"unknown"`` when the budget ran out first, ``"too big"`` past the cap."""
    from scipy.optimize import LinearConstraint, milp

    prog = _program(lat, ij, vid, sv, gv, kinds, sep_c)
    if prog is None:
        return "too big"
    a, lo, hi, (t_, v_, h_) = prog
    if len(t_) == 0:
        return None  # no move can be made at all: no routing
    res = milp(np.zeros(len(t_)), integrality=np.ones(len(t_)), bounds=(0, 1),
               constraints=LinearConstraint(a, lo, hi), options={"time_limit": max(budget, 0.05), "disp": False})
    if res.status == 2:
        return None
    if res.x is None:
        return "unknown"
    x = res.x > 0.5
    nxt = {(int(t), int(v)): int(h) for t, v, h in zip(t_[x], v_[x], h_[x])}
    where = [np.asarray(sv, int)]
    for t in range(len(kinds)):
        where.append(np.array([nxt[(t, int(v))] for v in where[-1]]))
    return np.stack(where)


def kinds_of(n1: int, n2: int) -> list[int]:
    """Step kinds of a routing of ``n1`` one-cell and ``n2`` two-cell steps: the one-cell
    steps split between the two ends (the later end takes the odd one)."""
    first = n1 // 2
    return [1] * first + [2] * n2 + [1] * (n1 - first)


def super_route(lat: Lattice, ij: np.ndarray, vid: np.ndarray, sv: np.ndarray, gv: np.ndarray, sep_c: float,
                t1: float, t2: float, beat: float, deadline: float, budget: float
                ) -> tuple[list[int], list[np.ndarray]] | None:
    """``(kinds, vertices of every robot after each step)`` of the shortest routing found
    that lasts less than ``beat`` seconds (steps of kind 1 ``t1``, of kind 2 ``t2``),
    or ``None``.  See the module docstring."""
    t0 = time.perf_counter()
    end = min(deadline, t0 + budget)
    if len(sv) == 0 or np.array_equal(np.sort(sv), np.sort(gv)):
        return None
    top = int(beat // t1) + 1
    if lat.n * top > 4 * FLOW_MAX_VARIABLES or end - t0 < 0.2:
        return None
    reach = relaxed_horizon(lat, sv, gv, top, end)
    if reach is None:
        return None
    # routings of steps of one cell only are planner.gridflow's
    cands = sorted((n1 * t1 + n2 * t2, n1 + n2, n1, n2) for n2 in range(1, top + 1) for n1 in range(top + 1)
                   if n1 + 2 * n2 >= reach and n1 * t1 + n2 * t2 < beat * (1 - 1e-9))
    lo, hi, best = 0, len(cands) - 1, None
    failed = 0.0  # how long the last program without a routing took (HiGHS overruns short limits)
    while lo <= hi:
        left = end - time.perf_counter()
        if left <= 0.05 or left < failed:
            break  # one more such program would not finish within the budget
        mid = (lo + hi) // 2
        kinds = kinds_of(cands[mid][2], cands[mid][3])
        began = time.perf_counter()
        got = _solve(lat, ij, vid, sv, gv, kinds, sep_c, min(left, max(0.1, budget / 4)))
        if isinstance(got, np.ndarray):
            best = (kinds, got)
            hi = mid - 1
        elif got == "too big":
            hi = mid - 1
        else:
            lo = mid + 1
            failed = time.perf_counter() - began
    if best is None:
        return None
    kinds, where = best
    return kinds, list(where[1:])
