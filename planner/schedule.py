"""Shorter plans from the same motions: merged moves and concurrent steps.

UPUMP moves one robot at a time inside a pebble graph.  Two exact
post-passes make the plan shorter without changing what any robot does:

* :func:`merge_moves` joins consecutive moves of the same robot (a pebble
  walking along a path) into one straight move when that segment is clear
  of the obstacles and of every other robot where it stands.
* :func:`merge_steps` joins two consecutive steps into one straight step
  (every robot goes directly from where the first starts to where the
  second ends) when the joined step is clear: the duration of a step is
  subadditive in its length, so a valid merge never lengthens the plan and
  removes a stop.
* :func:`shortcut` replaces a robot's moves over a window of steps by one
  straight line travelled across those steps, when that line is clear of
  the obstacles and of every other robot at every common time parameter
  (detours through far pebble-graph vertices disappear).
* :func:`schedule` runs steps at the same time.  Steps are taken in plan
  order and each goes into the earliest layer it can join: the robots it
  moves must not move in that layer or any later one (each robot keeps the
  order of its own moves), its motion must keep the separation from the
  layer's motion at every common time parameter and from the robots parked
  during the layer, and every later layer it jumps over must keep the
  separation from its robots parked at their new positions.  Order
  dependencies ("a robot must leave a vertex before another enters it") are
  exactly these geometric conditions.  Joining a layer never lengthens the
  plan: a layer lasts as long as its longest move, so the plan gains at
  most the joined step's own duration, which appending would have cost.

All checks are closed-form (:mod:`planner.geometry`); the result is a plan
in the same contract (straight moves, one shared time scaling per step).
"""

from __future__ import annotations

import time

import numpy as np

from .geometry import closest_approach, point_segment_distance
from .problem import Problem

__all__ = ["merge_moves", "merge_steps", "schedule", "shortcut", "split_moves", "step_clear", "steps_clear", "steps_of"]


def steps_of(waypoints: np.ndarray) -> list[np.ndarray]:
    """The moving robots of each step (index arrays)."""
    w = np.asarray(waypoints)
    if len(w) < 2:
        return []
    step, robot = np.nonzero(np.any(w[1:] != w[:-1], axis=2))
    return np.split(robot, np.searchsorted(step, np.arange(1, len(w) - 1)))


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


def _late(deadline: float | None) -> bool:
    """Whether ``deadline`` (a ``time.perf_counter()`` value, or ``None``: never) has passed."""
    return deadline is not None and time.perf_counter() > deadline


def _any_by_layer(flags: np.ndarray, layer: np.ndarray, n_layers: int) -> np.ndarray:
    """For each layer, whether any flagged item belongs to it."""
    return np.bincount(layer[flags], minlength=n_layers)[:n_layers] > 0


_PAIRS_LIMIT = 40_000_000
"""Largest table of pairwise tests :func:`schedule` computes up front; larger plans are
scheduled layer by layer (:func:`_schedule_by_layer`, the same answers)."""
_CHUNK = 250_000  # pairwise tests per closest-approach call
_DENSE = 1 << 18  # up to this many pairs the scheduler's table is computed whole


def schedule(problem: Problem, waypoints: np.ndarray, deadline: float | None = None) -> np.ndarray:
    """Earliest-layer scheduling of the steps (see the module docstring).

    Past ``deadline`` (a ``time.perf_counter()`` value) the steps not yet
    placed each get a layer of their own, after the others (still valid:
    that is the plan's own order).

    Every step is checked against all the layers it could join: its moves
    against each layer's moves (closest approach at a common parameter)
    and against the robots parked during that layer, and its robots' new
    positions against every later layer it would jump over.

    Every one of these tests pairs a move of the plan with another move or
    with a position some robot holds in the plan (its start or the end of
    one of its moves), so all of them are computed at once, before the
    layers are known; the layering then combines them as bit sets (Python
    integers), which keeps the per-step cost to a few integer operations.
    """
    w = np.asarray(waypoints, float)
    if len(w) <= 2:
        return w
    m = w.shape[1]
    steps = [(k, r) for k, r in enumerate(steps_of(w)) if len(r)]
    total = sum(len(r) for _, r in steps)
    if total == 0:  # nobody moves
        return w[:1].copy()
    if 2 * total * (2 * total + m) > _PAIRS_LIMIT:
        return _schedule_by_layer(problem, w, steps, deadline)
    sep = problem.separation
    step_of = np.concatenate([np.full(len(r), k) for k, r in steps])
    robot_of = np.concatenate([r for _, r in steps])
    a, b = w[step_of, robot_of], w[step_of + 1, robot_of]  # move i: a[i] -> b[i]
    held = np.concatenate([w[0], b])  # position ids: robot r's start is r, move i's end is m + i
    # Rows: each move (join tests), then its robot parked at its end (pass
    # tests); columns: every move, then every held position (a parked robot
    # is a zero-length move).  Same closed form and arguments as layer by layer.
    rows_a, rows_b = np.concatenate([a, b]), np.concatenate([b, b])
    cols_a, cols_b = np.concatenate([a, held]), np.concatenate([b, held])
    if len(rows_a) * len(cols_a) <= _DENSE:  # small: every pair at once
        close = closest_approach(rows_a[:, None], rows_b[:, None], cols_a[None], cols_b[None]) < sep
        mv, pos = _bit_rows(close[:, :total]), _bit_rows(close[:, total:])
        return _layers(w, steps, m, total, mv[:total], mv[total:], pos[:total], pos[total:], robot_of, b, deadline)
    # Only pairs whose swept boxes can meet are tested: a KD-tree of the
    # columns' midpoints, searched around each row's midpoint.
    ri, ci = _near_pairs(rows_a, rows_b, cols_a, cols_b, sep)
    if _late(deadline):
        return w  # the plan's own order
    close = np.zeros(len(ri), bool)
    for c0 in range(0, len(ri), _CHUNK):
        sl = slice(c0, c0 + _CHUNK)
        close[sl] = closest_approach(rows_a[ri[sl]], rows_b[ri[sl]], cols_a[ci[sl]], cols_b[ci[sl]]) < sep
    ri, ci = ri[close], ci[close]
    is_mv = ci < total
    mv = _bit_sets(ri[is_mv], ci[is_mv], len(rows_a))  # per row: bits of the close moves
    pos = _bit_sets(ri[~is_mv], ci[~is_mv] - total, len(rows_a))  # ... and of the close positions
    return _layers(w, steps, m, total, mv[:total], mv[total:], pos[:total], pos[total:], robot_of, b, deadline)


def _layers(w, steps, m, total, join_mv, pass_mv, join_pos, pass_pos, robot_of, b, deadline):
    """:func:`schedule`'s layering from its tables of close pairs (bit sets per move)."""
    cur = list(range(m))  # each robot's position id
    all_held = (1 << m) - 1  # bits of every robot's position id
    last = [-1] * m  # layer of each robot's latest move
    layer_of = [0] * total
    moves_in: list[int] = []  # per layer: bits of its moves
    start_held: list[int] = []  # per layer: bits of every robot's position at its start
    movers_held: list[int] = []  # per layer: bits of its moving robots' positions at its start
    i = 0
    for n_step, (_, robots) in enumerate(steps):
        rs = robots.tolist()
        ids = range(i, i + len(rs))  # this step's moves: consecutive ids
        bits = ((1 << len(rs)) - 1) << i
        new = bits << m  # the position ids of their ends
        i += len(rs)
        lo = max(last[r] for r in rs) + 1  # each robot keeps the order of its own moves
        if n_step % 32 == 31 and _late(deadline):
            lo = len(moves_in)  # out of time: a layer of its own
        ours = 0
        for r in rs:
            ours |= 1 << cur[r]
        jm = jp = pm = pp = 0
        for j in ids:
            jm |= join_mv[j]
            jp |= join_pos[j]
            pm |= pass_mv[j]
            pp |= pass_pos[j]
        best = None
        # From the last layer down: the earliest joinable layer such that
        # every later layer can be passed; a layer that cannot be passed
        # ends the search.
        for layer in range(len(moves_in) - 1, lo - 1, -1):
            parked = start_held[layer] & ~movers_held[layer] & ~ours
            if not (jm & moves_in[layer]) and not (jp & parked):
                best = layer
            if (pm & moves_in[layer]) or (pp & parked):
                break
        if best is None:
            best = len(moves_in)
            moves_in.append(0)
            start_held.append(all_held)
            movers_held.append(0)
        else:
            for later in range(best + 1, len(moves_in)):
                start_held[later] = (start_held[later] & ~ours) | new
        moves_in[best] |= bits
        movers_held[best] |= ours
        all_held = (all_held & ~ours) | new
        for r, j in zip(rs, ids):
            cur[r] = m + j
            last[r] = best
            layer_of[j] = best
    layer_of = np.asarray(layer_of)
    out = [w[0].copy()]
    for layer in range(len(moves_in)):
        nxt = out[-1].copy()
        sel = layer_of == layer
        nxt[robot_of[sel]] = b[sel]
        out.append(nxt)
    return np.asarray(out)


def _near_pairs(ra: np.ndarray, rb: np.ndarray, ca: np.ndarray, cb: np.ndarray, sep: float):
    """``(row, column)`` pairs of moves ``ra -> rb`` and ``ca -> cb`` that can come closer than
    ``sep``: their midpoints are within half of each one's length plus ``sep``."""
    from scipy.spatial import cKDTree

    half_c = 0.5 * np.linalg.norm(cb - ca, axis=1)
    mid_r = 0.5 * (ra + rb)
    reach = 0.5 * np.linalg.norm(rb - ra, axis=1) + float(half_c.max(initial=0.0)) + sep
    lists = cKDTree(0.5 * (ca + cb)).query_ball_point(mid_r, reach, return_sorted=False)
    counts = np.fromiter((len(x) for x in lists), int, len(lists))
    rows = np.repeat(np.arange(len(ra)), counts)
    cols = np.fromiter((j for x in lists for j in x), int, int(counts.sum()))
    return rows, cols


def _bit_sets(rows: np.ndarray, cols: np.ndarray, n: int) -> list[int]:
    """Per row ``0..n-1``, the Python integer with bit ``c`` set for each of its columns."""
    out = [0] * n
    for r, c in zip(rows.tolist(), cols.tolist()):
        out[r] |= 1 << c
    return out


def _bit_rows(mask: np.ndarray) -> list[int]:
    """Each row of a boolean matrix as a Python integer (bit ``j`` = column ``j``)."""
    packed = np.packbits(mask, axis=1, bitorder="little")
    return [int.from_bytes(row.tobytes(), "little") for row in packed]


def _schedule_by_layer(problem: Problem, w: np.ndarray, steps, deadline: float | None = None) -> np.ndarray:
    """:func:`schedule` for plans too long for its table of pairwise tests.

    ``steps`` are the plan's non-empty steps as ``(index, moving robots)``.
    Every step is checked against all the layers it could join at once, in
    one closest-approach call over the candidate layers' moves and parked
    robots.
    """
    m = w.shape[1]
    total = sum(len(r) for _, r in steps)
    sep = problem.separation
    mv_layer = np.zeros(total, int)  # every scheduled move: its layer, robot and segment
    mv_robot = np.zeros(total, int)
    mv_a = np.zeros((total, 2))
    mv_b = np.zeros((total, 2))
    n_mv = 0
    before = np.zeros((len(steps) + 1, m, 2))  # positions at the start of each layer
    moves_in = np.zeros((len(steps) + 1, m), bool)  # robot moves in layer
    n_layers = 0
    pos = w[0].copy()
    last_move = np.full(m, -1)
    for n_step, (k, robots) in enumerate(steps):
        a, b = w[k][robots], w[k + 1][robots]
        floor = int(last_move[robots].max())  # cannot go at or before this layer
        best = None
        lo = floor + 1
        if n_step % 16 == 15 and _late(deadline):
            lo = n_layers  # out of time: a layer of its own
        if lo < n_layers:
            L = n_layers - lo  # candidate layers lo .. n_layers - 1
            sel = mv_layer[:n_mv] >= lo
            ll = mv_layer[:n_mv][sel] - lo
            n_k, n_lm = len(robots), mv_a[:n_mv][sel].shape[0]
            # One closest-approach call for the four tests.  Rows: our moves
            # (join) and our robots parked at b (pass); columns: the
            # candidate layers' moves, then every robot parked at the start
            # of each candidate layer (a parked robot is a zero-length move).
            bef = before[lo:n_layers].reshape(-1, 2)  # (L * m, 2)
            ours_a = np.concatenate([a, b])
            ours_b = np.concatenate([b, b])
            them_a = np.concatenate([mv_a[:n_mv][sel], bef])
            them_b = np.concatenate([mv_b[:n_mv][sel], bef])
            close = closest_approach(ours_a[:, None], ours_b[:, None], them_a[None], them_b[None]) < sep
            # robots parked during each candidate layer (not moving in it, not ours)
            parked = ~moves_in[lo:n_layers]  # (L, m)
            parked[:, robots] = False
            near = close[:, n_lm:].reshape(2 * n_k, L, m)
            join_bad = _any_by_layer(close[:n_k, :n_lm].any(axis=0), ll, L)
            join_bad |= (near[:n_k].any(axis=0) & parked).any(axis=1)
            pass_bad = _any_by_layer(close[n_k:, :n_lm].any(axis=0), ll, L)
            pass_bad |= (near[n_k:].any(axis=0) & parked).any(axis=1)
            # the latest layer j such that every later layer can be passed
            ok_after = np.ones(L, bool)  # all of layers j+1 .. end passable
            if L > 1:
                ok_after[:-1] = np.cumsum(pass_bad[::-1])[::-1][1:] == 0
            cand = np.flatnonzero(~join_bad & ok_after)
            if len(cand):
                best = lo + int(cand[0])
        if best is None:
            best = n_layers
            before[best] = pos
            n_layers += 1
        else:
            before[best + 1 : n_layers, robots] = b
        moves_in[best, robots] = True
        j = slice(n_mv, n_mv + len(robots))
        mv_layer[j], mv_robot[j], mv_a[j], mv_b[j] = best, robots, a, b
        n_mv += len(robots)
        pos[robots] = b
        last_move[robots] = best
    out = [w[0].copy()]
    for layer in range(n_layers):
        nxt = out[-1].copy()
        sel = mv_layer[:n_mv] == layer
        nxt[mv_robot[:n_mv][sel]] = mv_b[:n_mv][sel]
        out.append(nxt)
    return np.asarray(out)


def _durations(problem: Problem, lengths: np.ndarray) -> np.ndarray:
    from .plan import step_duration

    return np.where(lengths > 0, step_duration(lengths, problem.max_speed, problem.max_accel), 0.0)


def _shortcut_tables(problem: Problem, w: np.ndarray, r: int):
    """Per step of ``w``: robot ``r``'s move length, the longest move of the others,
    and the step's duration (what :func:`_try_shortcut` reads for every window)."""
    length = np.linalg.norm(w[1:] - w[:-1], axis=2)  # (L, m)
    own = length[:, r].copy()
    others = np.delete(length, r, axis=1).max(axis=1, initial=0.0)  # (L,)
    return own, others, _durations(problem, np.maximum(others, own))


def _try_shortcut(problem: Problem, w: np.ndarray, r: int, j1: int, j2: int, tables=None) -> bool:
    """Straighten robot ``r`` between waypoints ``j1`` and ``j2`` if clear and faster.

    The straight displacement is shared among the steps in proportion to
    the longest move of the *other* robots in each, so no step gets longer
    when it fits; steps where only ``r`` moved lose that move.  Checked
    exactly: obstacles, and the closest approach to every other robot in
    every step of the window.  Edits ``w`` in place when accepted.
    ``tables`` are :func:`_shortcut_tables` of ``w`` and ``r`` (computed
    when not given).
    """
    if j2 - j1 < 1:
        return False
    own_all, others_all, dur_all = tables if tables is not None else _shortcut_tables(problem, w, r)
    own = own_all[j1:j2]
    own_sum = own.sum()
    if own_sum <= 1e-12:
        return False
    d = w[j2, r] - w[j1, r]
    dist = float(np.linalg.norm(d))
    if dist >= own_sum - 1e-9:
        return False  # already straight
    others = others_all[j1:j2]
    old_cost = dur_all[j1:j2].sum()
    cap = others.sum()
    if cap > 1e-12:
        frac = others / cap
    else:
        frac = np.zeros(len(others))
        frac[0] = 1.0
    new_own = dist * frac
    new_cost = _durations(problem, np.maximum(others, new_own)).sum()
    if new_cost > old_cost - 1e-9:
        return False
    cum = np.concatenate([[0.0], np.cumsum(frac)])
    ys = w[j1, r] + cum[:, None] * d  # (L + 1, 2)
    ys[-1] = w[j2, r]  # exactly where the window ends
    a, b = ys[:-1], ys[1:]
    if not problem.env.segments_clear(a, b, problem.clearance).all():
        return False
    oa = np.delete(w[j1:j2], r, axis=1)  # (L, m - 1, 2)
    ob = np.delete(w[j1 + 1 : j2 + 1], r, axis=1)
    if oa.shape[1]:
        dmin = closest_approach(a[:, None], b[:, None], oa, ob)
        if dmin.min() < problem.separation:
            return False
    w[j1 : j2 + 1, r] = ys
    return True


def shortcut(problem: Problem, waypoints: np.ndarray, passes: int = 3, deadline: float | None = None) -> np.ndarray:
    """Straighten detours robot by robot (see :func:`_try_shortcut`).

    For each robot the whole plan is tried first, then its halves, quarters
    and so on down to windows of two steps; a few passes run until nothing
    improves or ``deadline`` passes (every accepted change is checked, so
    the plan is valid whenever it stops).  Steps in which nobody moves any
    more are dropped.
    """
    w = np.array(waypoints, float)
    if len(w) <= 2:
        return w
    for _ in range(passes):
        improved = False
        for r in range(w.shape[1]):
            if _late(deadline):
                break
            tables = None  # of the current w, for robot r
            stack = [(0, len(w) - 1)]
            while stack:
                j1, j2 = stack.pop()
                if j2 - j1 < 2:
                    continue
                if tables is None:
                    tables = _shortcut_tables(problem, w, r)
                if _try_shortcut(problem, w, r, j1, j2, tables):
                    improved = True
                    tables = None
                    continue
                mid = (j1 + j2) // 2
                stack.append((mid, j2))
                stack.append((j1, mid))
        if not improved or _late(deadline):
            break
    keep = [0] + [k + 1 for k in range(len(w) - 1) if np.any(w[k + 1] != w[k])]
    return w[keep]


def step_clear(problem: Problem, a: np.ndarray, b: np.ndarray) -> bool:
    """Exact check of one step in which every robot goes straight ``a -> b``
    (:func:`steps_clear` of that one step)."""
    return bool(steps_clear(problem, np.asarray(a)[None], np.asarray(b)[None])[0])


def steps_clear(problem: Problem, a: np.ndarray, b: np.ndarray, deadline: float | None = None) -> np.ndarray:
    """:func:`step_clear` of ``K`` steps at once: step ``k`` moves every robot ``a[k] -> b[k]``.

    ``a`` and ``b`` are ``(K, m, 2)``; the same exact tests, in one
    clearance call and chunked closest-approach calls.  Steps not tested
    by ``deadline`` count as not clear.
    """
    n_steps, m = a.shape[:2]
    kk, rr = np.nonzero(np.any(a != b, axis=2))  # every moving robot of every step
    bad = np.zeros(n_steps, bool)
    if len(kk) == 0:
        return ~bad
    sa, sb = a[kk, rr], b[kk, rr]
    bad[kk[~problem.env.segments_clear(sa, sb, problem.clearance)]] = True
    if m > 1:
        chunk = max(1, _CHUNK // m)
        for c0 in range(0, len(kk), chunk):
            if _late(deadline):
                bad[kk[c0:]] = True
                break
            sl = slice(c0, c0 + chunk)
            d = closest_approach(sa[sl, None], sb[sl, None], a[kk[sl]], b[kk[sl]])  # (rows, m)
            d[np.arange(len(d)), rr[sl]] = np.inf  # a robot and itself
            bad[kk[sl][(d < problem.separation).any(axis=1)]] = True
    return ~bad


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
    two = steps_clear(problem, w[:-2], w[2:], deadline)  # two[k]: w[k] -> w[k + 2] straight is clear
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
