"""Routing on the lattice with goal swapping: TSWAP (Okumura and Defago, AIJ
2023) between two sets of lattice vertices (see :mod:`planner.lattice`)."""

from __future__ import annotations

import time

import numpy as np

from .grid import Lattice

__all__ = ["tswap"]


#: From this many lattice vertices on, :func:`_fields` searches breadth first.
_BFS_FROM = 1500


def _fields(lat: Lattice, sources: np.ndarray, deadline: float) -> np.ndarray | None:
    """``(len(sources), V)`` lattice distances (steps) from each source; -1 unreachable.

    One breadth-first search per source (:func:`scipy.sparse.csgraph.breadth_first_order`,
    in C), then the depths from its order: the vertices come level by level and the
    position of a vertex's predecessor never decreases along the order, so level
    ``L + 1`` ends after the last vertex whose predecessor lies within the first ``L``
    levels, found for a chunk of sources at once by one :func:`numpy.searchsorted` per
    level.  (Dijkstra's method in :func:`scipy.sparse.csgraph.shortest_path` takes 14 ms
    per source on the 96,603 vertices of orz900d, this 4; below :data:`_BFS_FROM`
    vertices Dijkstra's, all sources in one call, is the faster: 0.7 ms against 1.8 ms
    for 20 sources on 225 vertices.)"""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import breadth_first_order, shortest_path

    n = lat.n
    v = np.repeat(np.arange(n), 4)
    w = lat.nbr.ravel()
    ok = w >= 0
    g = coo_matrix((np.ones(int(ok.sum())), (v[ok], w[ok])), shape=(n, n)).tocsr()
    g = g.maximum(g.T).tocsr()  # undirected, once (not in every search)
    dtype = np.int16 if n < 30_000 else np.int32
    sources = np.asarray(sources, int)
    out = np.full((len(sources), n), -1, dtype)
    if not len(sources):
        return out
    if n < _BFS_FROM:
        chunk = max(1, min(128, 1_000_000 // max(n, 1)))  # the deadline is checked between chunks
        for s in range(0, len(sources), chunk):
            if time.perf_counter() > deadline:
                return None
            d = shortest_path(g, method="D", directed=True, unweighted=True, indices=sources[s : s + chunk])
            d[~np.isfinite(d)] = -1
            out[s : s + chunk] = d
        return out
    chunk = max(1, min(128, 4_000_000 // max(n, 1)))
    pos = np.empty(n, np.int64)
    for c0 in range(0, len(sources), chunk):
        if time.perf_counter() > deadline:
            return None
        orders, preds, sizes = [], [], []
        for r, s in enumerate(sources[c0 : c0 + chunk]):
            order, pred = breadth_first_order(g, int(s), directed=True, return_predecessors=True)
            pos[order] = np.arange(len(order))
            # predecessor positions of the non-source vertices, offset so that every
            # source's run sorts after the previous one's
            preds.append(pos[pred[order[1:]]] + r * (n + 1))
            orders.append(order)
            sizes.append(len(order))
        k = len(orders)
        size = np.asarray(sizes, np.int64)
        flat = np.concatenate(preds)
        offset = np.arange(k, dtype=np.int64) * (n + 1)
        begin = np.concatenate([[0], np.cumsum(size - 1)[:-1]])  # each run's start in flat
        end = np.ones(k, np.int64)  # level 0: the source alone
        ends = [end]
        while (end < size).any():
            end = np.minimum(np.searchsorted(flat, end + offset) - begin + 1, size)
            ends.append(end)
        table = np.stack(ends)  # (levels, k): where each level ends in each order
        for r in range(k):
            e = table[:, r]
            e = e[: int(np.searchsorted(e, size[r])) + 1]
            out[c0 + r, orders[r]] = np.repeat(np.arange(len(e), dtype=dtype), np.diff(e, prepend=0))
    return out


def _assign(cost: np.ndarray, bottleneck: bool, memo: dict) -> np.ndarray:
    """Goal of each robot: the fewest summed squared distances, among the assignments of
    the least longest distance when ``bottleneck`` (see :func:`tswap`); both kept in
    ``memo``, the second starting from the first."""
    from scipy.optimize import linear_sum_assignment

    if ("assign", False) not in memo:
        memo[("assign", False)] = linear_sum_assignment(cost**2)[1]
    goal_of = memo[("assign", False)]
    m = len(cost)
    if not bottleneck or m <= 1:
        return goal_of
    if ("assign", True) not in memo:
        # the sum of squares can leave a robot far longer than needed (random-64-64-10, 200
        # robots: 18 steps where the bottleneck is 12): the fewest squares among the
        # assignments of the least longest distance (rows with pairs over it barred)
        from .bounds import _bottleneck

        top = float(cost[np.arange(m), goal_of].max())
        least = _bottleneck(cost, top)
        if least < top:
            goal_of = linear_sum_assignment(np.where(cost <= least, cost**2, 1e12))[1]
        memo[("assign", True)] = goal_of
    return memo[("assign", True)]


def tswap(lat: Lattice, start_v: np.ndarray, goal_v: np.ndarray, deadline: float,
          max_steps: int | None = None, turns: bool = True, rng=None,
          bottleneck: bool = True, memo: dict | None = None) -> list[np.ndarray] | None:
    """Time steps (vertex of every robot after each) from ``start_v`` to the set ``goal_v``.

    TSWAP (see :mod:`planner.lattice`), synchronous: per time step, first
    target swaps (a robot whose next vertex holds a robot resting on its
    own target takes that target, and gives its own) and rotations of
    targets along waiting cycles, then every robot not on its target moves
    to its next vertex when that is free at that moment.  With ``turns``
    false, a robot enters a vertex vacated in the same step only when the
    robot that left it moves in the same direction, and prefers going straight
    on among its shortest moves (on a grid finer than
    ``sqrt(2)`` separations, following with a turn brings two robots to
    ``spacing / sqrt(2)``; see :mod:`planner.gridstage`).  ``None`` when
    the deadline or the step cap comes first, or a target is unreachable.
    Targets are first assigned by the fewest summed squared lattice distances
    among the assignments of the least longest one (``bottleneck``; false: the
    fewest squares alone, which can leave one robot far longer on its way).
    ``memo``: a dict kept between calls on the same lattice; the distance fields and
    both assignments are computed once in it (they depend on nothing else).
    """
    m = len(start_v)
    goals = np.asarray(goal_v, int)
    key = (id(lat), np.asarray(start_v, int).tobytes(), goals.tobytes())
    memo = {} if memo is None else memo
    if memo.get("key") != key:
        memo.clear()
        memo["key"] = key
    if "cost" not in memo:
        field = _fields(lat, goals, deadline)
        if field is None:
            return None
        cost = field[:, start_v].T.astype(float)  # (robot, goal)
        if (cost < 0).any():
            # robots and targets in different lattice components: only matching counts can work
            if np.any(np.bincount(lat.component[start_v], minlength=lat.n)
                      != np.bincount(lat.component[goals], minlength=lat.n)):
                return None
            cost[cost < 0] = 1e9
        memo.update(field=field, cost=cost)
    field, cost = memo["field"], memo["cost"]
    goal_of = _assign(cost, bottleneck, memo).tolist()  # robot -> goal index
    pts = lat.points
    nbr = lat.nbr.tolist()
    gpts = pts[goals]
    where = [int(v) for v in start_v]
    occ = np.full(lat.n, -1)
    occ[start_v] = np.arange(m)
    occ = occ.tolist()
    goal_vert = goals.tolist()
    frows = [field[g] for g in range(m)]
    heading = [-1] * m  # neighbour slot of each robot's last move

    def nexts(i: int) -> list[int]:
        """Neighbours one step closer to robot i's target, the most direct first."""
        g = goal_of[i]
        row = frows[g]
        v = where[i]
        dv = row[v]
        cand = [u for u in nbr[v] if u >= 0 and row[u] == dv - 1]
        if len(cand) > 1:
            gx, gy = gpts[g]
            cand.sort(key=lambda u: (pts[u][0] - gx) ** 2 + (pts[u][1] - gy) ** 2)
            if not turns and heading[i] >= 0:  # straight on first: fewer turns to wait for
                ahead = nbr[v][heading[i]]
                if ahead in cand:
                    cand.remove(ahead)
                    cand.insert(0, ahead)
        return cand

    if max_steps is None:
        max_steps = int(field.max(initial=0)) * 4 + 4 * m + 100
    order = sorted(range(m), key=lambda i: -float(cost[i, goal_of[i]]))
    if rng is not None:  # another try: ties among equally far robots broken at random
        noise = rng.random(m)
        order = sorted(range(m), key=lambda i: (-float(cost[i, goal_of[i]]), noise[i]))
    out = []
    for _ in range(max_steps):
        if time.perf_counter() > deadline:
            return None
        done = True
        # target swaps and rotations
        for i in order:
            if where[i] == goal_vert[goal_of[i]]:
                continue
            done = False
            c = nexts(i)
            if not c:
                continue
            j = occ[c[0]]
            if j < 0:
                continue
            if where[j] == goal_vert[goal_of[j]]:
                goal_of[i], goal_of[j] = goal_of[j], goal_of[i]
                continue
            chain = [i]
            seen = {i}
            k = j
            while k >= 0 and k not in seen and where[k] != goal_vert[goal_of[k]]:
                chain.append(k)
                seen.add(k)
                ck = nexts(k)
                k = occ[ck[0]] if ck else -1
            if k == i and len(chain) > 1:
                first = goal_of[chain[0]]
                for x in range(len(chain) - 1):
                    goal_of[chain[x]] = goal_of[chain[x + 1]]
                goal_of[chain[-1]] = first
        if done:
            return out
        moved = False
        left = {}  # vertex vacated this step -> direction (neighbour slot) of the robot that left
        for i in order:
            if where[i] == goal_vert[goal_of[i]]:
                continue
            for u in nexts(i):
                if occ[u] < 0:
                    k = nbr[where[i]].index(u)
                    if not turns and left.get(u, k) != k:
                        continue  # following with a turn: not on this grid
                    left[where[i]] = k
                    heading[i] = k
                    occ[where[i]] = -1
                    occ[u] = i
                    where[i] = u
                    moved = True
                    break
        if moved:
            out.append(np.array(where))
    return None
