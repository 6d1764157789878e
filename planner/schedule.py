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

import numpy as np

from .geometry import closest_approach
from .merge import merge_moves, merge_steps, split_moves
from .problem import Problem
from .shortcut import shortcut
from .steps import _CHUNK, _late, step_clear, steps_clear, steps_of

__all__ = ["merge_moves", "merge_steps", "schedule", "shortcut", "split_moves", "step_clear", "steps_clear", "steps_of"]


def _any_by_layer(flags: np.ndarray, layer: np.ndarray, n_layers: int) -> np.ndarray:
    """For each layer, whether any flagged item belongs to it."""
    return np.bincount(layer[flags], minlength=n_layers)[:n_layers] > 0


_PAIRS_LIMIT = 40_000_000
"""Largest table of pairwise tests :func:`schedule` computes up front; larger plans are
scheduled layer by layer (:func:`_schedule_by_layer`, the same answers)."""
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
