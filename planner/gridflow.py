"""Makespan-optimal routing on the grid stage's graph: a time-expanded flow.

For unlabeled robots on a graph, Yu and LaValle ("Multi-agent path planning
and network flow", WAFR 2012) route by a flow in the time-expanded graph:
one layer of vertices per time step, an arc from ``(v, t)`` to ``(u, t + 1)``
for every edge ``v u`` and a waiting arc to ``(v, t + 1)``; unit vertex
capacities keep robots apart, and a gadget per edge and step forbids two
robots crossing it in opposite directions.  With a horizon of ``T`` steps a
flow of value ``m`` from the starts to the targets is a plan of ``T`` steps,
and the smallest ``T`` with such a flow is the shortest makespan in steps.

The grid stage's graph needs one more rule (:mod:`planner.gridstage`): on
a grid finer than ``sqrt(2)`` separations a robot may not enter a vertex
in the step its occupant leaves it in a perpendicular direction (following
with a turn brings them ``c / sqrt(2)`` apart).  That is a side constraint
per vertex, step and direction of entry::

    x[t, w -> v] + x[t, v -> left of that direction] + x[t, v -> right of it] <= 1

so the problem is a small integer program rather than a pure flow.  It is
solved with HiGHS (``scipy.optimize.milp``), the horizon ``T`` found by
bisection between the smallest at which the flow without the edge and turn
rules carries every robot (no plan is shorter) and one below a plan
already known, within a time budget (the program has no objective: any
routing of that horizon will do).  Vertices that no start reaches by
step ``t`` or that reach no target in the remaining ``T - t`` steps are left
out of layer ``t`` (they cannot carry a robot then).
"""

from __future__ import annotations

import time

import numpy as np

from .grid import Lattice

__all__ = ["FLOW_MAX_VARIABLES", "flow_route", "flow_rows", "grid_distances", "relaxed_horizon", "tail_route"]

#: Largest integer program tried (variables); above it the grid stage keeps TSWAP (HiGHS
#: overran a 0.5 s limit by 6 s at 68,000).
FLOW_MAX_VARIABLES = 50_000


def grid_distances(lat: Lattice, sources: np.ndarray) -> np.ndarray:
    """Steps from the nearest of ``sources`` to every vertex (``inf``: unreachable)."""
    n = lat.n
    dist = np.full(n, np.inf)
    frontier = np.unique(np.asarray(sources, int))
    dist[frontier] = 0
    d = 0
    while len(frontier):
        d += 1
        nxt = lat.nbr[frontier].ravel()
        nxt = np.unique(nxt[nxt >= 0])
        nxt = nxt[np.isinf(dist[nxt])]
        dist[nxt] = d
        frontier = nxt
    return dist


def _flow_value(lat: Lattice, sv, gv, horizon: int) -> int:
    """Maximum flow of the time-expanded graph without the edge and turn rules (a
    relaxation: below ``m`` no routing of ``horizon`` steps exists)."""
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import maximum_flow

    n = lat.n
    # nodes: source 0, sink 1, then (t, v, in) = 2 + 2 (t n + v), (t, v, out) = that + 1
    def node(t, v, out):
        return 2 + 2 * (t * n + v) + out

    v, k = np.nonzero(lat.nbr >= 0)
    u = lat.nbr[v, k]
    a, b = [np.zeros(len(sv), int)], [node(0, np.asarray(sv), 0)]
    every = np.arange(n)
    for t in range(horizon + 1):
        a.append(node(t, every, 0))
        b.append(node(t, every, 1))
        if t < horizon:
            a += [node(t, v, 1), node(t, every, 1)]
            b += [node(t + 1, u, 0), node(t + 1, every, 0)]
    a.append(node(horizon, np.asarray(gv), 1))
    b.append(np.ones(len(gv), int))
    a_, b_ = np.concatenate(a), np.concatenate(b)
    size = 2 + 2 * n * (horizon + 1)
    g = csr_matrix((np.ones(len(a_), np.int32), (a_, b_)), shape=(size, size))
    return int(maximum_flow(g, 0, 1).flow_value)


def flow_rows(n: int, t_: np.ndarray, v_: np.ndarray, h_: np.ndarray, steps: int, sv, gv):
    """``(rows, cols, vals, lo, hi, count)`` of the rows every time-expanded routing
    program shares (this module's and :mod:`planner.superflow`'s): the arc ``i`` leaves
    vertex ``v_[i]`` at step ``t_[i]`` for ``h_[i]``; flow is conserved, every robot
    leaves its start and ends on a target, and at most one robot is on a vertex between
    steps."""
    rows, cols, vals, lo, hi = [], [], [], [], []
    r = 0
    start, goal = np.zeros(n), np.zeros(n)
    start[sv], goal[gv] = 1.0, 1.0
    # out(t, v) - in(t - 1 -> v) = [t == 0 and v a start]; in(last -> v) = [v a target]
    for t in range(steps + 1):
        rid = r + np.arange(n)
        for sel, sign, at in ((t_ == t, 1.0, v_), (t_ == t - 1, -1.0, h_)):
            rows.append(rid[at[sel]])
            cols.append(np.nonzero(sel)[0])
            vals.append(np.full(int(sel.sum()), sign))
        b = start if t == 0 else (-goal if t == steps else np.zeros(n))
        lo.append(b)
        hi.append(b)
        r += n
    # at most one robot on a vertex: out(t, v) <= 1 (t >= 1; t = 0 is fixed above)
    sel = t_ >= 1
    rows.append(r + (t_[sel] - 1) * n + v_[sel])
    cols.append(np.nonzero(sel)[0])
    vals.append(np.ones(int(sel.sum())))
    lo.append(np.full((steps - 1) * n, -np.inf))
    hi.append(np.ones((steps - 1) * n))
    r += (steps - 1) * n
    return rows, cols, vals, lo, hi, r


def _program(lat: Lattice, sv, gv, horizon: int, turns: bool):
    """Arrays of the integer program of ``horizon`` steps, or ``None`` when too big."""
    from scipy.sparse import coo_matrix

    n = lat.n
    ds, dg = grid_distances(lat, sv), grid_distances(lat, gv)
    # arcs (t, v, slot) whose tail and head can carry a robot at t and t + 1
    head_of = np.concatenate([lat.nbr, np.arange(n)[:, None]], axis=1)  # (n, 5)
    tt, vv, kk = [], [], []
    for t in range(horizon):
        tail_ok = (ds <= t) & (dg <= horizon - t)
        head = head_of
        ok = (head >= 0) & tail_ok[:, None]
        hv = np.where(head >= 0, head, 0)
        ok &= (ds[hv] <= t + 1) & (dg[hv] <= horizon - t - 1)
        v, k = np.nonzero(ok)
        tt.append(np.full(len(v), t))
        vv.append(v)
        kk.append(k)
    t_, v_, k_ = np.concatenate(tt), np.concatenate(vv), np.concatenate(kk)
    nvar = len(t_)
    if nvar > FLOW_MAX_VARIABLES:
        return None
    h_ = head_of[v_, k_]
    index = np.full((horizon, n, 5), -1)
    index[t_, v_, k_] = np.arange(nvar)
    rows, cols, vals, lo, hi, r = flow_rows(n, t_, v_, h_, horizon, sv, gv)
    # no swap: x[t, u -> w] + x[t, w -> u] <= 1, and (grids finer than sqrt(2) separations)
    # no following with a turn: x[t, w -> v] + x[t, v -> both perpendicular slots] <= 1
    groups = []
    mv = k_ < 4
    a_idx = np.nonzero(mv & ((k_ == 0) | (k_ == 1)))[0]
    back = index[t_[a_idx], h_[a_idx], k_[a_idx] + 2]
    keep = back >= 0
    groups.append(np.stack([a_idx[keep], back[keep]], axis=1))
    if not turns:
        m_idx = np.nonzero(mv)[0]
        p1 = index[t_[m_idx], h_[m_idx], (k_[m_idx] + 1) % 4]
        p3 = index[t_[m_idx], h_[m_idx], (k_[m_idx] + 3) % 4]
        groups.append(np.stack([m_idx, p1, p3], axis=1))
    for grp in groups:
        used = grp >= 0
        keep = used.sum(axis=1) >= 2
        grp, used = grp[keep], used[keep]
        k = len(grp)
        rr = np.repeat(r + np.arange(k), grp.shape[1])
        rows.append(rr[used.ravel()])
        cols.append(grp.ravel()[used.ravel()])
        vals.append(np.ones(int(used.sum())))
        lo.append(np.full(k, -np.inf))
        hi.append(np.ones(k))
        r += k
    a = coo_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(r, nvar)).tocsr()
    cost = np.zeros(nvar)  # feasibility: a count of moves as objective makes HiGHS slower to a first routing
    return a, np.concatenate(lo), np.concatenate(hi), cost, (t_, v_, k_, h_)


#: HiGHS's presolve on the programs of :func:`flow_route`.  Off: on the programs captured
#: from room-32-32-4 (200 and 400 robots), random-32-32-20 (400) and maze-32-32-2 (200)
#: a routing that exists is found in 0.6-2.3 s instead of 1.0-3.1 s, which the search's
#: budget (a quarter per program) then fits; what the presolve gains is proofs of
#: infeasibility, which take longer than that budget either way (room at 200 robots and 11
#: steps: 5.8 s).  The programs of steps of two cells (:mod:`planner.superflow`) keep it:
#: there it was faster on some and slower on others.
PRESOLVE = False


def _solve(lat: Lattice, sv, gv, horizon: int, turns: bool, budget: float):
    """Vertex of every robot at every step ``(horizon + 1, m)`` for ``horizon`` steps,
    ``None`` when there is none, ``"unknown"`` when the budget ran out first, or
    ``"too big"`` above :data:`FLOW_MAX_VARIABLES`."""
    from scipy.optimize import LinearConstraint, milp

    prog = _program(lat, sv, gv, horizon, turns)
    if prog is None:
        return "too big"
    a, lo, hi, cost, (t_, v_, k_, h_) = prog
    if len(cost) == 0:
        return None  # no move can be made at all: no routing
    res = milp(cost, integrality=np.ones(len(cost)), bounds=(0, 1), constraints=LinearConstraint(a, lo, hi),
               options={"time_limit": max(budget, 0.05), "disp": False, "presolve": PRESOLVE})
    if res.status == 2:  # infeasible
        return None
    if res.x is None or res.status != 0:
        return "unknown"
    x = res.x > 0.5
    nxt = {}
    for t, v, h in zip(t_[x], v_[x], h_[x]):
        nxt[(int(t), int(v))] = int(h)
    where = [np.asarray(sv, int)]
    for t in range(horizon):
        where.append(np.array([nxt[(t, int(v))] for v in where[-1]]))
    return np.stack(where)


def relaxed_horizon(lat: Lattice, sv: np.ndarray, gv: np.ndarray, top: int, deadline: float) -> int | None:
    """The fewest steps at which the relaxed flow (:func:`_flow_value`) carries every
    robot, at most ``top`` (``None`` above it or at the deadline): no routing is shorter."""
    m = len(sv)
    if time.perf_counter() > deadline or _flow_value(lat, sv, gv, top) < m:
        return None
    lo, hi = 1, top
    while lo < hi:
        if time.perf_counter() > deadline:
            return None
        mid = (lo + hi) // 2
        if _flow_value(lat, sv, gv, mid) >= m:
            hi = mid
        else:
            lo = mid + 1
    return hi


def flow_route(lat: Lattice, sv: np.ndarray, gv: np.ndarray, deadline: float, turns: bool = False,
               below: int = 64, budget: float = 8.0) -> list[np.ndarray] | None:
    """Vertices of every robot after each step of a short routing (as
    :func:`planner.tswap.tswap` returns them), or ``None`` when none shorter than
    ``below`` steps (a known routing's) is found within ``budget`` seconds.

    The horizon is searched by bisection between the relaxed bound
    (:func:`relaxed_horizon`) and ``below - 1``; each integer program gets a
    quarter of the budget.  A routing, when there is one, is found fast; proving
    a horizon infeasible can take far longer, so a horizon whose program runs out
    of time counts as infeasible (the result is the shortest found, not proven
    shortest)."""
    t0 = time.perf_counter()
    end = min(deadline, t0 + budget)
    if len(sv) == 0 or np.array_equal(np.sort(sv), np.sort(gv)):
        return []
    hi = below - 1
    # the programs grow as vertices x horizon: past the cap even the first would be too big
    if hi < 1 or lat.n * hi > 2 * FLOW_MAX_VARIABLES or end - time.perf_counter() < 0.2:
        return None
    lo = relaxed_horizon(lat, sv, gv, hi, end)
    if lo is None:
        return None
    best = None
    failed = 0.0  # how long the last program without a routing took (HiGHS overruns short limits)
    while lo <= hi:
        left = end - time.perf_counter()
        if left <= 0.05 or left < failed:
            break  # one more such program would not finish within the budget
        mid = (lo + hi) // 2
        began = time.perf_counter()
        got = _solve(lat, sv, gv, mid, turns, min(left, max(0.1, budget / 4)))
        if isinstance(got, np.ndarray):
            best = got
            hi = mid - 1
        elif got == "too big":
            hi = mid - 1  # a shorter horizon is a smaller program
        else:
            lo = mid + 1
            failed = time.perf_counter() - began
    return None if best is None else list(_park(best)[1:])


def _park(where: np.ndarray) -> np.ndarray:
    """Loops cut out of a routing ``(T + 1, m)``: a robot that is back at ``v`` at step
    ``t2`` after being there at ``t1`` waits at ``v`` instead when no other robot is on
    ``v`` in between.  Waiting on a vertex nobody else uses breaks none of the step
    rules (it only removes moves, so no swap or following is added), and the program's
    routings, having no objective, wander."""
    w = np.array(where)
    steps, m = w.shape
    changed = True
    while changed:
        changed = False
        occ: dict[tuple[int, int], int] = {(t, int(v)): i for t in range(steps) for i, v in enumerate(w[t])}
        for i in range(m):
            col = w[:, i]
            for t1 in range(steps - 2):
                v = int(col[t1])
                later = np.nonzero(col[t1 + 2 :] == v)[0]
                if not len(later):
                    continue
                t2 = t1 + 2 + int(later[-1])
                if all(occ.get((t, v), i) == i for t in range(t1 + 1, t2)) and (col[t1:t2] != v).any():
                    for t in range(t1 + 1, t2):
                        occ.pop((t, int(col[t])), None)
                        occ[(t, v)] = i
                    col[t1:t2] = v
                    changed = True
    return w


#: :func:`tail_route` stops after this many tails in a row (each with more robots) found no
#: shorter routing.
TAIL_MISSES = 3


def tail_route(lat: Lattice, where: np.ndarray, deadline: float, turns: bool = False, budget: float = 4.0,
               first_cap: int = 40) -> list[np.ndarray] | None:
    """A routing shorter than ``where`` (``(T + 1, m)`` vertices, a known routing) that keeps
    its first steps and routes only the robots still moving after them anew, or ``None``.

    Near its end a routing moves few robots (TSWAP's last steps on a sparse map: 52 of 400
    robots move in the last 11 of 25 steps on room-64-64-8), where :func:`flow_route`
    solves a small program even when the whole one is far too big.  From the latest step
    ``t0`` after which at most ``cap`` robots move (``first_cap`` robots, then 1.5 times
    as many after each try), those robots are routed by :func:`flow_route` from where they
    are at ``t0`` to where they end, in fewer than ``T - t0`` steps, on the graph without
    the vertices of the robots that stay (they stand still meanwhile, so the one-cell
    rules hold between them and the movers: a move along an axis never passes within a
    cell of a robot standing on another vertex).  A shorter tail replaces the old one and
    the search goes on from it, within ``budget`` seconds and until :data:`TAIL_MISSES`
    tries in a row find nothing."""
    t_end = min(deadline, time.perf_counter() + budget)
    w = np.asarray(where, int)
    improved = False
    cap = first_cap
    m = w.shape[1]
    misses = 0
    while time.perf_counter() < t_end - 0.2 and misses < TAIL_MISSES:
        steps = len(w) - 1
        mv = w[1:] != w[:-1]
        last = np.where(mv.any(axis=0), steps - 1 - np.argmax(mv[::-1], axis=0), -1)  # each robot's last move
        count = np.cumsum(np.bincount(last[last >= 0], minlength=steps)[::-1])[::-1]  # robots moving from t on
        fits = np.nonzero(count <= cap)[0]
        t0 = int(fits[0]) if len(fits) else steps
        if steps - t0 < 2:
            if cap >= m:
                break
            cap = int(cap * 1.5) + 1
            continue
        movers = np.nonzero(last >= t0)[0]
        stay = w[t0, np.setdiff1d(np.arange(m), movers)]
        nbr = lat.nbr.copy()
        nbr[stay] = -1
        nbr[np.isin(nbr, stay)] = -1
        sub = Lattice(lat.points, nbr, lat.spacing, lat.component)
        left = t_end - time.perf_counter()
        got = flow_route(sub, w[t0, movers], w[-1, movers], t_end, turns=turns, below=steps - t0, budget=left)
        if got is not None and len(got) < steps - t0:
            tail = np.repeat(w[t0][None], len(got), axis=0)  # none: the movers already fill their ends
            if len(got):
                tail[:, movers] = np.stack(got)
            w = np.concatenate([w[: t0 + 1], tail])
            improved, misses = True, 0
        elif cap >= m:
            break
        else:
            cap, misses = int(cap * 1.5) + 1, misses + 1
    return list(w[1:]) if improved else None
