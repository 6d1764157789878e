"""Connections between pebble graphs (the paper's Algorithm 4, CONNECT / CON_GEN).

For two pumped configurations ``V`` and ``V'`` the candidate pairs are
``D = {(v, v') : the segment v -> v' is clear of the obstacles and walls}``.
Robots moving along several pairs do so simultaneously, with one shared
time parameter, so two pairs *interfere* when they share an endpoint or
when two robots moving along them come closer than the separation at some
common parameter (closed form: :func:`planner.geometry.closest_approach`).
An independent set of size ``m`` in the interference graph ``I`` is a
collision-free simultaneous motion from an ``m``-placement of ``V`` to an
``m``-placement of ``V'``: a *connection*.

Filled gaps, following Solovey and Halperin's KPUMP/UPUMP:

* ``D`` is limited to nearby pairs (each vertex's ``k`` nearest vertices of
  the other graph, both ways, found with a KD-tree): ``I`` grows with the
  square of ``|D|`` and long pairs rarely survive in an independent set.
* The paper's randomised greedy heuristic scans ``D`` in a random order and
  keeps a pair when it interferes with none kept so far.  The order here is
  a *weighted* random permutation (key ``U(0, 1) * (length + separation)``):
  still random, but short pairs tend to come first, which yields shorter,
  less crossing connections and more successes.
* All ``q`` attempts between two graphs run together, vectorised over the
  attempts, and successes are kept once per pair of signatures (the
  roadmap only needs one connection per pair of its nodes), the shortest.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from .geometry import closest_approach
from .pebble import PebbleGraph
from .plan import step_duration
from .problem import Problem

__all__ = ["Connection", "candidate_pairs", "connect", "interference_matrix"]


@dataclass(frozen=True, eq=False)
class Connection:
    """A simultaneous motion from graph ``a`` to graph ``b``.

    The robot on vertex ``src[k]`` of graph ``a`` moves straight to vertex
    ``dst[k]`` of graph ``b``.  ``duration`` is the step's shortest duration
    [s]; ``sig_a`` and ``sig_b`` are the signatures of ``src`` and ``dst``.
    """

    a: int
    b: int
    src: np.ndarray
    dst: np.ndarray
    duration: float
    sig_a: tuple[int, ...]
    sig_b: tuple[int, ...]

    def reversed(self) -> "Connection":
        return Connection(self.b, self.a, self.dst, self.src, self.duration, self.sig_b, self.sig_a)


def candidate_pairs(problem: Problem, va: np.ndarray, vb: np.ndarray, k: int = 8) -> np.ndarray:
    """The pairs ``D`` ``(P, 2)`` (index in ``va``, index in ``vb``), nearest first."""
    if len(va) == 0 or len(vb) == 0:
        return np.zeros((0, 2), int)
    ka = min(k, len(vb))
    kb = min(k, len(va))
    _, jb = cKDTree(vb).query(va, k=ka)
    _, ja = cKDTree(va).query(vb, k=kb)
    jb = np.asarray(jb).reshape(len(va), ka)
    ja = np.asarray(ja).reshape(len(vb), kb)
    pairs = np.concatenate(
        [
            np.stack([np.repeat(np.arange(len(va)), ka), jb.ravel()], axis=1),
            np.stack([ja.ravel(), np.repeat(np.arange(len(vb)), kb)], axis=1),
        ]
    )
    pairs = np.unique(pairs, axis=0)
    clear = problem.env.segment_clearance(va[pairs[:, 0]], vb[pairs[:, 1]]) >= problem.clearance
    return pairs[clear]


def interference_matrix(problem: Problem, va, vb, pairs) -> np.ndarray:
    """Dense boolean interference graph over ``pairs`` (a pair interferes with itself)."""
    a = va[pairs[:, 0]]
    b = vb[pairs[:, 1]]
    n = len(pairs)
    inter = (pairs[:, None, 0] == pairs[None, :, 0]) | (pairs[:, None, 1] == pairs[None, :, 1])
    # Only pairs whose segments pass near each other can interfere.
    mid = 0.5 * (a + b)
    half = 0.5 * np.linalg.norm(b - a, axis=1)
    reach = 2 * float(half.max(initial=0.0)) + problem.separation
    cand = cKDTree(mid).query_pairs(reach, output_type="ndarray")
    if len(cand):
        i, j = cand[:, 0], cand[:, 1]
        d = closest_approach(a[i], b[i], a[j], b[j])
        hit = d < problem.separation
        inter[i[hit], j[hit]] = True
        inter[j[hit], i[hit]] = True
    inter[np.arange(n), np.arange(n)] = True
    return inter


def _greedy_sets(inter, keys, m, comp_a=None, quota_a=None, comp_b=None, quota_b=None):
    """Greedy independent sets, one per row of ``keys`` (scan order = argsort).

    A pair is taken when it interferes with none taken before and, where
    quotas are given, its endpoints' components still have room (so a set
    of size ``m`` has exactly the signature ``quota``).  Returns a boolean
    ``(attempts, P)`` matrix of the chosen pairs; rows stop at ``m`` pairs.
    """
    q, p = keys.shape
    order = np.argsort(keys, axis=1, kind="stable")
    blocked = np.zeros((q, p), bool)
    chosen = np.zeros((q, p), bool)
    size = np.zeros(q, int)
    rows = np.arange(q)
    cnt_a = None if quota_a is None else np.zeros((q, len(quota_a)), int)
    cnt_b = None if quota_b is None else np.zeros((q, len(quota_b)), int)
    for t in range(p):
        c = order[:, t]
        take = ~blocked[rows, c] & (size < m)
        if cnt_a is not None:
            take &= cnt_a[rows, comp_a[c]] < quota_a[comp_a[c]]
        if cnt_b is not None:
            take &= cnt_b[rows, comp_b[c]] < quota_b[comp_b[c]]
        if not take.any():
            if (size >= m).all():
                break
            continue
        r = rows[take]
        ct = c[take]
        chosen[r, ct] = True
        size[r] += 1
        blocked[r] |= inter[ct]
        if cnt_a is not None:
            cnt_a[r, comp_a[ct]] += 1
        if cnt_b is not None:
            cnt_b[r, comp_b[ct]] += 1
    return chosen


def _assignment_keys(pairs, length, n_a, n_b, pref_a, pref_b) -> np.ndarray:
    """Keys putting a minimum-sum-of-squares assignment first (then the rest).

    The assignment runs between the preferred vertices of each side (all of
    them where none are preferred).  Synchronised straight lines along such
    an assignment often do not collide (the CAPT observation), so this one
    deterministic attempt frequently connects two placements directly.
    """
    from scipy.optimize import linear_sum_assignment

    rows = np.arange(n_a) if pref_a is None else np.asarray(pref_a)
    cols = np.arange(n_b) if pref_b is None else np.asarray(pref_b)
    ra = np.full(n_a, -1)
    ra[rows] = np.arange(len(rows))
    cb = np.full(n_b, -1)
    cb[cols] = np.arange(len(cols))
    big = 1e12
    cost = np.full((len(rows), len(cols)), big)
    ok = (ra[pairs[:, 0]] >= 0) & (cb[pairs[:, 1]] >= 0)
    cost[ra[pairs[ok, 0]], cb[pairs[ok, 1]]] = length[ok] ** 2
    ri, ci = linear_sum_assignment(cost)
    good = cost[ri, ci] < big
    chosen = set(zip(rows[ri[good]].tolist(), cols[ci[good]].tolist()))
    in_assignment = np.fromiter(((int(i), int(j)) in chosen for i, j in pairs), bool, len(pairs))
    return np.where(in_assignment, length, 1e6 + length)


def connect(
    problem: Problem,
    ga: PebbleGraph,
    gb: PebbleGraph,
    a: int,
    b: int,
    attempts: int,
    rng: np.random.Generator,
    *,
    need_a: tuple[int, ...] | None = None,
    need_b: tuple[int, ...] | None = None,
    prefer_a: np.ndarray | None = None,
    prefer_b: np.ndarray | None = None,
    k: int = 8,
) -> list[Connection]:
    """CON_GEN: up to ``attempts`` greedy independent sets of size ``m``.

    ``need_a``/``need_b``: the only signature wanted on that side (per
    component quotas), e.g. the start's signature in the start graph.
    ``prefer_a``/``prefer_b``: vertices whose pairs are scanned first (the
    start or target placement itself, which saves pebble moves).  The first
    attempt follows a minimum-sum-of-squares assignment; the others are the
    paper's randomised greedy.  Returns the distinct connections found, one
    per pair of signatures (the one with the shortest duration).
    """
    m = problem.m
    va, vb = ga.vertices, gb.vertices
    pairs = candidate_pairs(problem, va, vb, k=k)
    if len(pairs) < m:
        return []
    # A connection needs m distinct sources and m distinct destinations.
    if len(np.unique(pairs[:, 0])) < m or len(np.unique(pairs[:, 1])) < m:
        return []
    inter = interference_matrix(problem, va, vb, pairs)
    length = np.linalg.norm(vb[pairs[:, 1]] - va[pairs[:, 0]], axis=1)
    tier = np.zeros(len(pairs))
    for pref, col in ((prefer_a, 0), (prefer_b, 1)):
        if pref is not None:
            mask = np.zeros(len(va) if col == 0 else len(vb), bool)
            mask[np.asarray(pref, int)] = True
            tier += ~mask[pairs[:, col]]
    keys = tier[None] * 1e6 + rng.random((attempts, len(pairs))) * (length + problem.separation)[None]
    if attempts > 0:
        keys[0] = _assignment_keys(pairs, length, len(va), len(vb), prefer_a, prefer_b)
    chosen = _greedy_sets(
        inter,
        keys,
        m,
        ga.component[pairs[:, 0]] if need_a is not None else None,
        np.asarray(need_a) if need_a is not None else None,
        gb.component[pairs[:, 1]] if need_b is not None else None,
        np.asarray(need_b) if need_b is not None else None,
    )
    ok = chosen.sum(axis=1) == m
    best: dict[tuple, Connection] = {}
    for row in np.flatnonzero(ok):
        sel = pairs[chosen[row]]
        src, dst = sel[:, 0], sel[:, 1]
        dur = float(step_duration(float(length[chosen[row]].max()), problem.max_speed, problem.max_accel))
        key = (ga.signature(src), gb.signature(dst))
        if key not in best or dur < best[key].duration:
            best[key] = Connection(a, b, src, dst, dur, key[0], key[1])
    return [best[key] for key in sorted(best)]
