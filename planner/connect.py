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
from .sequenced import Sequenced, sequenced_moves

__all__ = [
    "Connection",
    "Sequenced",
    "candidate_pairs",
    "connect",
    "connect_sequenced",
    "interference_graph",
    "sequenced_moves",
]


@dataclass(frozen=True, eq=False)
class Connection:
    """A motion from an ``m``-placement of graph ``a`` to one of graph ``b``.

    The robot on vertex ``src[k]`` of graph ``a`` moves straight to vertex
    ``dst[k]`` of graph ``b``.  With ``order=None`` all move at once (the
    paper's connections); otherwise one at a time in the order
    ``order`` (indices into ``src``), which keeps every move clear of the
    robots still on their sources and of those already on their
    destinations.  ``via``, for an ordered connection, holds each robot's
    corner points between its source and destination (empty for a
    straight move; ``None`` when every move is straight).  ``duration``
    estimates the motion's time [s] (for an ordered one, its longest chain
    of dependent moves); ``sig_a`` and ``sig_b`` are the signatures of
    ``src`` and ``dst``.
    """

    a: int
    b: int
    src: np.ndarray
    dst: np.ndarray
    duration: float
    sig_a: tuple[int, ...]
    sig_b: tuple[int, ...]
    order: np.ndarray | None = None
    via: tuple[np.ndarray, ...] | None = None

    def reversed(self) -> "Connection":
        order = None if self.order is None else self.order[::-1].copy()
        via = None if self.via is None else tuple(v[::-1].copy() for v in self.via)
        return Connection(self.b, self.a, self.dst, self.src, self.duration, self.sig_b, self.sig_a, order, via)


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
    clear = problem.env.segments_clear(va[pairs[:, 0]], vb[pairs[:, 1]], problem.clearance)
    return pairs[clear]


def interference_graph(problem: Problem, va, vb, pairs) -> tuple[np.ndarray, np.ndarray]:
    """The interference graph over ``pairs`` as CSR ``(indptr, indices)``.

    Two pairs interfere when they share a source or a destination, or when
    robots moving along both at once come closer than the separation
    (closed-form closest approach; only pairs whose midpoints are near
    enough are tested, found with a KD-tree).  Every pair interferes with
    itself, so a chosen pair blocks itself too.
    """
    from scipy.sparse import coo_matrix

    n = len(pairs)
    rows, cols = [], []
    for col in (0, 1):
        key = pairs[:, col]
        order = np.argsort(key, kind="stable")
        sk = key[order]
        starts = np.flatnonzero(np.r_[True, sk[1:] != sk[:-1]])
        sizes = np.diff(np.r_[starts, n])
        size_of = np.repeat(sizes, sizes)  # group size of each sorted member
        start_of = np.repeat(starts, sizes)
        r = np.repeat(order, size_of)
        # member k of a group of size g at start s pairs with s .. s + g - 1
        first = np.repeat(np.cumsum(size_of) - size_of, size_of)
        c = order[np.repeat(start_of, size_of) + (np.arange(len(r)) - first)]
        rows.append(r)
        cols.append(c)
    a = va[pairs[:, 0]]
    b = vb[pairs[:, 1]]
    mid = 0.5 * (a + b)
    half = 0.5 * np.linalg.norm(b - a, axis=1)
    reach = 2 * float(half.max(initial=0.0)) + problem.separation
    cand = cKDTree(mid).query_pairs(reach, output_type="ndarray")
    if len(cand):
        i, j = cand[:, 0], cand[:, 1]
        hit = closest_approach(a[i], b[i], a[j], b[j]) < problem.separation
        rows += [i[hit], j[hit]]
        cols += [j[hit], i[hit]]
    r = np.concatenate(rows)
    c = np.concatenate(cols)
    m = coo_matrix((np.ones(len(r), np.int8), (r, c)), shape=(n, n)).tocsr()
    return m.indptr, m.indices


def _greedy_sets(graph, keys, m, comp_a=None, quota_a=None, comp_b=None, quota_b=None):
    """Greedy independent sets, one per row of ``keys`` (scan order = argsort).

    A pair is taken when it interferes with none taken before and, where
    quotas are given, its endpoints' components still have room (so a set
    of size ``m`` has exactly the signature ``quota``).  Returns a boolean
    ``(attempts, P)`` matrix of the chosen pairs; rows stop at ``m`` pairs.
    The scan is plain Python over a byte array (numpy marks a chosen
    pair's neighbours in one go through a shared view).
    """
    indptr, indices = graph
    q, p = keys.shape
    orders = np.argsort(keys, axis=1, kind="stable").tolist()
    ptr = indptr.tolist()
    ca = comp_a.tolist() if quota_a is not None else None
    cb = comp_b.tolist() if quota_b is not None else None
    chosen = np.zeros((q, p), bool)
    for row, order in enumerate(orders):
        blocked = bytearray(p)
        view = np.frombuffer(blocked, dtype=np.uint8)
        taken = []
        left_a = list(quota_a) if quota_a is not None else None
        left_b = list(quota_b) if quota_b is not None else None
        for c in order:
            if blocked[c]:
                continue
            if left_a is not None and left_a[ca[c]] == 0:
                continue
            if left_b is not None and left_b[cb[c]] == 0:
                continue
            taken.append(c)
            if len(taken) == m:
                break
            view[indices[ptr[c] : ptr[c + 1]]] = 1
            if left_a is not None:
                left_a[ca[c]] -= 1
            if left_b is not None:
                left_b[cb[c]] -= 1
        chosen[row, taken] = True
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
    inter = interference_graph(problem, va, vb, pairs)
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


def connect_sequenced(
    problem: Problem,
    ga: PebbleGraph,
    gb: PebbleGraph,
    a: int,
    b: int,
    src: np.ndarray,
    dst: np.ndarray,
    bent: bool = False,
) -> Connection | None:
    """A connection from vertices ``src`` of ``ga`` to ``dst`` of ``gb`` by :func:`sequenced_moves`."""
    seq = sequenced_moves(problem, ga.vertices[np.asarray(src, int)], gb.vertices[np.asarray(dst, int)], bent)
    if seq is None:
        return None
    src_sorted = np.asarray(src, int)[seq.rows]
    dst_sorted = np.asarray(dst, int)[seq.cols]
    has_via = any(len(p) > 2 for p in seq.paths)
    return Connection(
        a, b, src_sorted, dst_sorted, seq.duration,
        ga.signature(src_sorted), gb.signature(dst_sorted), seq.order,
        tuple(p[1:-1] for p in seq.paths) if has_via else None,
    )
