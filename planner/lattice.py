"""Many robots at once: snap onto a square lattice, route with goal swapping, snap off.

For hundreds of robots the structured stages move robots one at a time
along dependency orders, and the plans get long.  This stage keeps every
robot moving:

1. **Lattice.**  A square lattice of spacing ``a >= sqrt(2) * separation``
   over the workspace; its vertices are the clear points, its edges the
   clear segments between 4-neighbours (both exact).  Robots on distinct
   vertices that each stay or move to a 4-neighbour, with no two swapping
   vertices, keep the separation at every common time parameter: the
   relative position of two robots moves on a segment between two
   non-zero integer vectors (times ``a``) whose difference is at most two
   unit steps, which stays at least ``a / sqrt(2)`` from the origin.  So a
   lattice step needs no pairwise test.
2. **Snapping.**  The start placement is assigned to distinct lattice
   vertices (a minimum sum of squared distances over each robot's nearest
   vertices reached by a clear straight move), and the robots move there
   in *rounds*: each round is one step in which a subset moves at once,
   the largest found greedily whose moves keep the separation from each
   other and from every robot that waits (exact closest approaches over
   the pairs whose swept boxes meet).  A formation spaced a little over
   the separation spreads onto a lattice of spacing ``a`` in one round
   when ``1 / d_s^2 + 1 / a^2 <= 1 / d^2`` (``d`` the separation,
   ``d_s`` the formation's spacing): the minimum-sum-of-squares
   assignment's straight moves then keep ``d`` (the CAPT argument of
   Turpin, Michael and Kumar 2014, with unequal spacings).  The target
   placement is snapped the same way and the result is played backwards.
3. **Routing.**  Between the two sets of lattice vertices, TSWAP (Okumura
   and Defago, "Solving simultaneous target assignment and path planning
   efficiently with time-independent execution", AIJ 2023): targets are
   assigned (minimum sum of squared lattice distances among the assignments
   whose longest distance is the least possible), every robot steps
   towards its target along the lattice distance field each time step
   when the next vertex is free, a robot blocked by one resting on its
   own target swaps targets with it, and a cycle of robots each waiting
   for the next rotates its targets.  Robots move into a vertex vacated in
   the same step (following), which the spacing makes safe.  On a
   connected lattice every robot reaches a target.

Every step this stage writes is exact by construction or by test; the
plan it feeds is still checked by the exact validator.
"""

from __future__ import annotations

import math
import time

import numpy as np
from scipy.spatial import cKDTree

from .geometry import closest_approach
from .grid import _SLACK, Lattice, build_lattice, lattice_spacing
from .problem import Problem
from .snappush import pocket_corners, push
from .tswap import tswap
from .visible import clear_by

__all__ = ["Lattice", "build_lattice", "lattice_candidates", "lattice_spacing", "lattice_waypoints", "snap", "tswap"]


# ----------------------------------------------------------------------------
# snapping

_PUSH_TRIES = 16  # robots still to snap tried for a push (planner.snappush) when a round moves nobody
_REACH = 8.0  # a robot snaps to lattice vertices at most this many spacings away


def _close_pairs(a: np.ndarray, b: np.ndarray, pts: np.ndarray, sep: float,
                 tree: cKDTree | None = None) -> tuple[np.ndarray, np.ndarray]:
    """``(segment, point)`` index pairs whose point of ``pts`` lies closer than ``sep`` to
    the segment ``a -> b`` (exact, over the KD-tree's candidates; ``tree`` is over ``pts``)."""
    from .geometry import point_segment_distance

    mid = 0.5 * (a + b)
    half = 0.5 * np.linalg.norm(b - a, axis=1)
    lists = (cKDTree(pts) if tree is None else tree).query_ball_point(mid, half + sep, return_sorted=False)
    counts = np.fromiter((len(x) for x in lists), int, len(lists))
    seg = np.repeat(np.arange(len(a)), counts)
    who = np.fromiter((j for x in lists for j in x), int, int(counts.sum()))
    if len(seg) == 0:
        return seg, who
    close = point_segment_distance(pts[who], a[seg], b[seg]) < sep
    return seg[close], who[close]


def _near_segments(problem: Problem, a: np.ndarray, b: np.ndarray, owner: np.ndarray,
                   pos: np.ndarray, tree: cKDTree, ids: np.ndarray | None = None) -> np.ndarray:
    """For each segment ``a -> b`` of robot ``owner``: whether another robot's position in
    ``pos`` lies closer than the separation to it (exact, over the KD-tree's candidates)."""
    seg, who = _close_pairs(a, b, pos, problem.separation, tree)
    out = np.zeros(len(a), bool)
    out[seg[(who if ids is None else ids[who]) != owner[seg]]] = True
    return out


def _assign(problem: Problem, lat: Lattice, pos: np.ndarray, robots: np.ndarray, taken: np.ndarray,
            hard: np.ndarray | None = None, k: int = 16, deadline: float = math.inf) -> np.ndarray | None:
    """Distinct free lattice vertices for ``robots`` (rows of ``pos``): minimum sum of squared
    distances over each robot's ``k`` nearest vertices that are not ``taken`` and are
    reached by a clear straight move.  A move passing closer than the separation to
    another robot's position is charged a large penalty, and excluded where that
    robot is marked in ``hard``.  ``None`` also when ``deadline`` passes."""
    n = len(robots)
    if n == 0:
        return np.zeros(0, int)
    k = min(k, lat.n)
    # vertices within _REACH spacings only: in a maze the nearest ones can lie far away,
    # and long moves are costly to test (and rarely clear)
    d, j = cKDTree(lat.points).query(pos[robots], k=k, distance_upper_bound=_REACH * lat.spacing)
    d, j = np.asarray(d).reshape(n, k), np.asarray(j).reshape(n, k)
    rows = np.repeat(np.arange(n), k)
    found = j.ravel() < lat.n
    cols = np.where(found, j.ravel(), 0)
    d = np.where(np.isfinite(d), d, 0.0)
    a = np.repeat(pos[robots], k, axis=0)
    b = lat.points[cols]
    ok = found & ~taken[cols]
    clear = clear_by(problem, a[ok], b[ok], deadline)
    if clear is None:
        return None
    ok[ok] = clear
    blocked = np.zeros(len(cols), bool)
    blocked[ok] = _near_segments(problem, a[ok], b[ok], np.repeat(robots, k)[ok], pos, cKDTree(pos))
    if hard is not None and hard.any():
        firm = np.zeros(len(cols), bool)
        idx = np.flatnonzero(ok)
        firm[idx] = _near_segments(problem, a[idx], b[idx], np.repeat(robots, k)[idx], pos[hard],
                                   cKDTree(pos[hard]), np.flatnonzero(hard))
        ok &= ~firm
    # a zero weight would read as no edge; a blocked move costs as much as one a few cells longer
    # (a huge penalty makes the sparse assignment solver crawl)
    w = d.ravel() ** 2 + 1e-9 + np.where(blocked, 16 * lat.spacing**2, 0.0)
    # Dense over the candidate vertices only (the sparse solver can crawl when the
    # candidates barely hold a full matching); absent pairs cost a prohibitive amount.
    from scipy.optimize import linear_sum_assignment

    used, col_of = np.unique(cols[ok], return_inverse=True)
    if len(used) < n:
        return None
    big = 1e18
    cost = np.full((n, len(used)), big)
    cost[rows[ok], col_of] = w[ok]
    r, c = linear_sum_assignment(cost)
    if (cost[r, c] >= big).any():
        return None  # no full matching among the candidates
    out = np.empty(n, int)
    out[r] = used[c]
    return out


def _conflicts(problem: Problem, a: np.ndarray, b: np.ndarray, moving: np.ndarray) -> np.ndarray:
    """``(P, 2)`` pairs of robots, at least one moving, that come closer than the
    separation when every robot goes ``a -> b`` at once (exact, over the pairs
    whose swept boxes can meet)."""
    sep = problem.separation
    mid = 0.5 * (a + b)
    half = 0.5 * np.linalg.norm(b - a, axis=1)
    reach = 2 * float(half.max(initial=0.0)) + sep
    pairs = cKDTree(mid).query_pairs(reach, output_type="ndarray")
    if len(pairs) == 0:
        return pairs.reshape(0, 2)
    i, j = pairs[:, 0], pairs[:, 1]
    keep = moving[i] | moving[j]
    i, j = i[keep], j[keep]
    close = closest_approach(a[i], b[i], a[j], b[j]) < sep
    return np.stack([i[close], j[close]], axis=1)


def _round(problem: Problem, pos: np.ndarray, dest: np.ndarray, todo: np.ndarray,
           hold_back: bool = False) -> np.ndarray:
    """The robots that move in one round: all of ``todo`` at first; while some pair
    conflicts, a mover conflicting with a waiting robot waits, else the mover of a
    conflicting pair with more conflicts waits (with ``hold_back``, first without the
    robots whose destination lies in another's way).  When that leaves nobody moving, the
    first robot of ``todo`` that can move alone does (two robots whose moves cross,
    one passing where the other stands: the greedy choice may stop the wrong one)."""
    later = _in_the_way(problem, pos, dest, todo) if hold_back else np.zeros_like(todo)
    movers = _greedy_round(problem, pos, dest, todo & ~later) if (todo & ~later).any() else np.zeros_like(todo)
    if not movers.any():
        movers = _greedy_round(problem, pos, dest, todo)
    if movers.any() or not todo.any():
        return movers
    for i in np.flatnonzero(todo)[:_ALONE_TRIES]:
        alone = np.zeros_like(todo)
        alone[i] = True
        if len(_conflicts(problem, pos, np.where(alone[:, None], dest, pos), alone)) == 0:
            return alone
    return movers


_ALONE_TRIES = 64  # robots tried one at a time when the greedy round moves nobody


def _in_the_way(problem: Problem, pos: np.ndarray, dest: np.ndarray, todo: np.ndarray) -> np.ndarray:
    """Robots of ``todo`` whose destination lies closer than the separation to the move
    of another robot of ``todo`` (exact): on a dense lattice, a robot that settles there
    first would stop the other for good."""
    out = np.zeros(len(pos), bool)
    idx = np.flatnonzero(todo)
    if len(idx) >= 2:
        seg, who = _close_pairs(pos[idx], dest[idx], dest[idx], problem.separation)
        out[idx[who[who != seg]]] = True
    return out


def _greedy_round(problem: Problem, pos: np.ndarray, dest: np.ndarray, todo: np.ndarray) -> np.ndarray:
    movers = todo.copy()
    while movers.any():
        b = np.where(movers[:, None], dest, pos)
        bad = _conflicts(problem, pos, b, movers)
        if len(bad) == 0:
            break
        both = movers[bad[:, 0]] & movers[bad[:, 1]]
        lone = np.concatenate([bad[~both & movers[bad[:, 0]], 0], bad[~both & movers[bad[:, 1]], 1]])
        movers[lone] = False
        if len(lone) == 0:
            count = np.bincount(bad[both].ravel(), minlength=len(pos))
            for i, j in bad[both]:
                if movers[i] and movers[j]:
                    movers[i if (count[i], i) > (count[j], j) else j] = False
    return movers


def snap(problem: Problem, lat: Lattice, placement: np.ndarray, deadline: float,
         max_rounds: int = 400) -> tuple[list[np.ndarray], np.ndarray] | None:
    """Steps moving the robots of ``placement`` onto distinct lattice vertices, in rounds.

    Returns ``(steps, vertex of each robot)``.  Each round is one step moving
    the robots :func:`_round` lets go at once (exact).  When a round can move
    nobody, settled robots make room for one still to move
    (:func:`planner.snappush.push`), or failing that the robots still to move get
    new vertices whose straight moves pass no other robot where it stands, so
    that the next round moves some.  A try that fails is made again with the
    robots whose destination lies in another's way held back a round.  When the
    first assignment fails because a robot sees no vertex (a pocket between
    obstacles), that robot first passes the corners of a way out
    (:func:`planner.snappush.pocket_corners`), one round each.
    ``None`` when no such vertices exist or the deadline passes.
    """
    got = _snap(problem, lat, placement, deadline, max_rounds, False)
    if got is None and time.perf_counter() < deadline:  # a crowd: robots that would fence others in wait
        got = _snap(problem, lat, placement, deadline, max_rounds, True)
    return got


def _snap(problem: Problem, lat: Lattice, placement: np.ndarray, deadline: float, max_rounds: int,
          hold_back: bool) -> tuple[list[np.ndarray], np.ndarray] | None:
    m = len(placement)
    pos = np.array(placement, float)
    everyone = np.arange(m)
    vert = None
    for k in (16, 48, 144):  # more candidates where the lattice is coarse next to the formation
        if time.perf_counter() > deadline:
            return None
        vert = _assign(problem, lat, pos, everyone, np.zeros(lat.n, bool), k=k, deadline=deadline)
        if vert is not None:
            break
    via: dict[int, list[np.ndarray]] = {}  # corners a robot in a pocket passes on its way to its vertex
    if vert is None and time.perf_counter() < deadline:
        via = pocket_corners(problem, lat, pos, _REACH * lat.spacing, deadline)
        if via:
            vert = _assign(problem, lat, _through_corners(pos, via), everyone, np.zeros(lat.n, bool), k=144, deadline=deadline)
    if vert is None:
        return None
    steps: list[np.ndarray] = []
    stuck = 0
    for _ in range(max_rounds):
        dest = lat.points[vert].copy()
        for r in list(via):
            while via[r] and np.array_equal(pos[r], via[r][0]):
                via[r].pop(0)
            if not via[r] or np.array_equal(pos[r], dest[r]):
                del via[r]
            else:
                dest[r] = via[r][0]
        todo = np.any(pos != dest, axis=1)
        if not todo.any():
            return steps, vert
        if time.perf_counter() > deadline:
            return None
        movers = _round(problem, pos, dest, todo, hold_back)
        if movers.any():
            pos = np.where(movers[:, None], dest, pos)
            steps.append(pos.copy())
            stuck = 0
            continue
        pushed = None
        for r in np.flatnonzero(todo)[:_PUSH_TRIES]:  # make room among the settled robots
            pushed = push(problem, lat, pos, vert, todo, int(r), deadline)
            if pushed is not None:
                break
        if pushed is not None:
            steps += pushed[0]
            pos, vert = pushed[1], pushed[2]
            continue
        stuck += 1
        if stuck > 3:
            return None
        left = np.flatnonzero(todo)
        taken = np.zeros(lat.n, bool)
        taken[vert[~todo]] = True
        new = _assign(problem, lat, _through_corners(pos, via), left, taken, hard=~todo,
                      k=48 if stuck < 2 else 144, deadline=deadline)
        if new is None:
            return None
        vert = vert.copy()
        vert[left] = new
    return None


def _through_corners(pos: np.ndarray, via: dict[int, list[np.ndarray]]) -> np.ndarray:
    """Positions with each robot still to pass corners (``via``) at its last corner: the
    place its straight move onto a vertex starts from."""
    out = pos.copy()
    for r, corners in via.items():
        if corners:
            out[r] = corners[-1]
    return out


# ----------------------------------------------------------------------------
# the stage (routing: :func:`planner.tswap.tswap`)


def lattice_waypoints(problem: Problem, deadline: float, spacing: float | None = None) -> np.ndarray | None:
    """Raw waypoints ``(K + 1, m, 2)`` from the start to the target through the lattice,
    or ``None`` when every try fails or the deadline passes.

    Tries the spacings of :func:`_spacings`, each at four shifts of the lattice.
    """
    return next(lattice_candidates(problem, deadline, spacing), None)


def lattice_candidates(problem: Problem, deadline: float, spacing: float | None = None):
    """Raw waypoints of every lattice that works, in the order of
    :func:`lattice_waypoints` (a generator: the caller stops when one is short enough;
    plans through different shifts of the lattice differ by up to 1.4x in makespan)."""
    tries = [spacing] if spacing is not None else _spacings(problem)
    for a in tries:
        for shift in ((0.0, 0.0), (0.5, 0.5), (0.5, 0.0), (0.0, 0.5)):
            if time.perf_counter() > deadline:
                return
            out = _through(problem, build_lattice(problem, a, shift), deadline)
            if out is not None:
                yield out


def _spacings(problem: Problem) -> list[float]:
    """Lattice spacings to try: the CAPT spacing first when both placements are spaced a
    little over the separation (one round onto the lattice then suffices in theory) and
    the lattice keeps room for the robots, then the default."""
    base = lattice_spacing(problem)
    d = problem.separation
    ds = min(_min_spacing(problem.start), _min_spacing(problem.target))
    out = []
    if ds > d * 1.002:
        capt = d / math.sqrt(1.0 - (d / ds) ** 2) * _SLACK
        room = (problem.width - 2 * problem.clearance) * (problem.height - 2 * problem.clearance)
        if capt > base and room / capt**2 >= 4 * problem.m:
            out.append(capt)
    out.append(base)
    return out


def _min_spacing(pts: np.ndarray) -> float:
    if len(pts) < 2:
        return math.inf
    return float(cKDTree(pts).query(pts, k=2)[0][:, 1].min())


def _through(problem: Problem, lat: Lattice, deadline: float) -> np.ndarray | None:
    if lat.n < problem.m:
        return None
    got = snap(problem, lat, problem.start, deadline)
    if got is None:
        return None
    entry, sv = got
    got = snap(problem, lat, problem.target, deadline)
    if got is None:
        return None
    leave, tv = got
    route = tswap(lat, sv, tv, deadline)
    if route is None:
        return None
    where = route[-1] if route else sv
    # the robot on vertex tv[j] ends on target j, along the target's rounds played backwards
    at = np.full(lat.n, -1)
    at[where] = np.arange(problem.m)
    robot_of_target = at[tv]
    if (robot_of_target < 0).any():
        return None
    inv = np.empty(problem.m, int)
    inv[robot_of_target] = np.arange(problem.m)
    steps = [problem.start.copy(), *entry]
    steps += [lat.points[r] for r in route]
    back = [problem.target, *leave][::-1]  # target j's robot in row j
    steps += [cfg[inv] for cfg in back[1:]]
    return np.asarray(steps)
