"""Snapping onto a crowded lattice: make room for a robot the settled ones have fenced in.

When the robots still to snap (:func:`planner.lattice.snap`) cannot move, each
one's every clear straight move onto a free vertex passes a robot that has
already settled (on a lattice of spacing barely above the separation, about
seven in ten vertices taken, the robots settled around a late one leave it no
way through).  :func:`push` then moves one settled robot out of the way
along lattice edges: for a vertex ``v0`` the fenced robot reaches by a clear
straight move that passes exactly one settled robot ``q`` (or ``q`` stands on
``v0``), a shortest lattice path from ``q``'s vertex through settled robots
leads to a free vertex ``f``; the robot before ``f`` steps onto it, the one
before steps into the vertex vacated, and so on back to ``q``, and then the
fenced robot moves onto ``v0`` (straight, or in two axis-aligned legs when a
straight move would hit an obstacle).  Each of these single moves is one round,
tested exactly against every other robot where it stands (the path's edges
also keep the separation from the robots not yet on the lattice); a push is
given up, nothing changed, at the first that fails.

A robot that sees no vertex at all by a straight move (a pocket between desks)
gets the corners of a way out instead (:func:`pocket_corners`): a breadth-first
search over a fine grid around it, every edge and every pulled-taut leg tested
exactly against the obstacles.
"""

from __future__ import annotations

import time
from collections import deque

import numpy as np
from scipy.spatial import cKDTree

from .geometry import point_segment_distance
from .grid import Lattice
from .problem import Problem

__all__ = ["push"]

_CANDIDATES = 48  # nearest vertices tried as the fenced robot's entry
_MAX_PATH = 40  # lattice edges a push may shift robots along
_ENTRIES = 8  # entry vertices a push tries
_POCKET_NODES = 161  # nodes a side of the fine grid a robot in a pocket searches for a way out
_POCKET_ROBOTS = 64  # robots in pockets sought a way out at most (more: none is)


def _single_clear(problem: Problem, pos: np.ndarray, r: int, b: np.ndarray) -> bool:
    """Whether robot ``r`` alone moving ``pos[r] -> b`` keeps the separation from every other
    robot where it stands and is clear of the obstacles (both exact)."""
    a = pos[r]
    if not problem.env.segments_clear(a[None], b[None], problem.clearance)[0]:
        return False
    d = point_segment_distance(pos, a[None], b[None]).ravel()
    d[r] = np.inf
    return bool(d.min(initial=np.inf) >= problem.separation)


def push(problem: Problem, lat: Lattice, pos: np.ndarray, vert: np.ndarray, todo: np.ndarray, r: int,
         deadline: float) -> tuple[list[np.ndarray], np.ndarray, np.ndarray] | None:
    """``(rounds, positions after them, vertices)`` placing robot ``r`` (of ``todo``) on a
    vertex by shifting settled robots (see the module docstring), or ``None``."""
    sep = problem.separation
    settled = ~todo
    occ = np.full(lat.n, -1)
    occ[vert[settled]] = np.flatnonzero(settled)
    reserved = np.zeros(lat.n, bool)
    reserved[vert[todo]] = True  # the other robots still to come keep their vertices
    reserved[vert[r]] = False
    loose = np.flatnonzero(todo)
    loose = loose[loose != r]
    tree = cKDTree(lat.points)
    near_loose = np.zeros(lat.n, bool)  # vertices too close to a robot not yet on the lattice
    if len(loose):
        hits = tree.query_ball_point(pos[loose], sep)
        for h in hits:
            near_loose[h] = True
    k = min(_CANDIDATES, lat.n)
    _, cand = tree.query(pos[r], k=k)
    away = pos[np.append(loose, r)]
    tried = 0
    for v in np.atleast_1d(cand):
        v = int(v)
        if reserved[v] or near_loose[v]:
            continue
        for legs in _legs(problem, pos[r], lat.points[v]):
            close = set()
            a = pos[r]
            for b in legs:
                d = point_segment_distance(pos, a[None], b[None]).ravel()
                d[r] = np.inf
                close.update(np.flatnonzero(d < sep).tolist())
                a = b
            if occ[v] >= 0:
                close.add(int(occ[v]))
            if len(close) > 1 or (close and not settled[next(iter(close))]):
                continue  # more than one in the way, or one not yet on the lattice
            if close:
                got = _shift(problem, lat, pos, vert, occ, next(iter(close)), v, reserved | near_loose, away,
                             deadline)
            else:  # nobody in the way: the two legs of an L a straight round could not take
                got = pos.copy(), vert.copy(), []
            tried += 1
            if got is not None:
                pos2, vert2, rounds = got
                for b in legs:
                    if not _single_clear(problem, pos2, r, b):
                        break
                    pos2[r] = b
                    rounds.append(pos2.copy())
                else:
                    vert2[r] = v
                    return rounds, pos2, vert2
            if tried >= _ENTRIES or time.perf_counter() > deadline:
                return None
    return None


def _legs(problem: Problem, a: np.ndarray, b: np.ndarray) -> list[list[np.ndarray]]:
    """Ways from ``a`` to the vertex ``b`` clear of the obstacles (exact): straight, else
    along the two axis-aligned L-shapes (a robot in a pocket between desks may see no
    vertex but reach a grid line across it)."""
    env, cl = problem.env, problem.clearance
    if env.segments_clear(a[None], b[None], cl)[0]:
        return [[b]]
    out = []
    for w in (np.array([b[0], a[1]]), np.array([a[0], b[1]])):
        if env.segments_clear(np.stack([a, w]), np.stack([w, b]), cl).all():
            out.append([w, b])
    return out


def _shift(problem: Problem, lat: Lattice, pos: np.ndarray, vert: np.ndarray, occ: np.ndarray, q: int,
           keep: int, barred: np.ndarray, away: np.ndarray, deadline: float):
    """Rounds moving settled robot ``q`` off its vertex along a shortest lattice path through
    settled robots to a free vertex (each robot on it one vertex on), the vertex ``keep``
    and the ``barred`` ones left alone and every move clear of the positions ``away``:
    ``(positions, vertices, rounds)`` or ``None``."""
    sep = problem.separation
    start = int(vert[q])
    parent = {start: -1, keep: -2}
    queue = deque([(start, 0)])
    free = -1
    while queue:
        if time.perf_counter() > deadline:
            return None
        v, depth = queue.popleft()
        if v != start and occ[v] < 0:
            free = v
            break
        if depth >= _MAX_PATH:
            continue
        for u in lat.nbr[v]:
            u = int(u)
            if u >= 0 and u not in parent and not barred[u] \
                    and point_segment_distance(away, lat.points[u], lat.points[v]).min() >= sep:
                parent[u] = v  # the robot on v can step onto u past the robots not yet on the lattice
                queue.append((u, depth + 1))
    if free < 0:
        return None
    path = [free]
    while parent[path[-1]] >= 0:
        path.append(parent[path[-1]])
    path = path[::-1]  # start ... free
    pos, vert = pos.copy(), vert.copy()
    rounds = []
    for i in range(len(path) - 2, -1, -1):  # the robot on path[i] steps onto path[i + 1]
        who = int(occ[path[i]])
        b = lat.points[path[i + 1]]
        if not _single_clear(problem, pos, who, b):
            return None
        pos[who] = b
        vert[who] = path[i + 1]
        rounds.append(pos.copy())
    return pos, vert, rounds


def pocket_corners(problem: Problem, lat: Lattice, pos: np.ndarray, reach: float, deadline: float,
                   k: int = 144) -> dict[int, list[np.ndarray]]:
    """Corners by which each robot that no straight move clear of the obstacles brings onto
    one of its ``k`` nearest vertices within ``reach`` (a pocket between desks) gets out:
    ``{robot: [corner, ...]}``, the last corner seeing a vertex.  The robot snaps through
    them, one straight round each (:func:`pocket_path`).  Robots with no way out found are
    left out; more than :data:`_POCKET_ROBOTS` in pockets, none is sought (``{}``)."""
    env, cl = problem.env, problem.clearance
    k = min(k, lat.n)
    tree = cKDTree(lat.points)
    _, j = tree.query(pos, k=k, distance_upper_bound=reach)
    j = np.asarray(j).reshape(len(pos), k)
    out: dict[int, list[np.ndarray]] = {}
    tried = 0
    for r in range(len(pos)):
        cand = j[r][j[r] < lat.n]
        if time.perf_counter() > deadline:
            break
        if len(cand) and env.segments_clear(np.repeat(pos[[r]], len(cand), axis=0), lat.points[cand], cl).any():
            continue
        if tried >= _POCKET_ROBOTS:
            return {}  # that many pockets: the grid does not suit the placement (each try ~0.05 s)
        tried += 1
        way = pocket_path(problem, lat, tree, pos[r], reach)
        if way:
            out[r] = way
    return out


def pocket_path(problem: Problem, lat: Lattice, tree: cKDTree, a: np.ndarray, reach: float) -> list[np.ndarray]:
    """Corners of a way from ``a`` out of a pocket, clear of the obstacles (every leg exact),
    to a point that sees a lattice vertex, or ``[]``.  Breadth-first search over a fine
    square grid centred on ``a`` (4-neighbour edges tested exactly; the spacing
    ``min(clearance, lattice spacing) / 8`` finds gaps at least that wide), the
    nearest reached node that sees one of its four nearest vertices kept, and the
    path pulled taut: from each corner the farthest later node it sees."""
    env, cl = problem.env, problem.clearance
    h = min(cl, lat.spacing) / 8
    half = min(_POCKET_NODES // 2, int(np.ceil(reach / h)))
    side = 2 * half + 1
    ii, jj = np.meshgrid(np.arange(side), np.arange(side), indexing="ij")
    pts = a + h * np.stack([ii.ravel() - half, jj.ravel() - half], axis=1)
    free = env.points_clear(pts, cl)
    centre = half * side + half
    free[centre] = True
    # edges right (i + 1) and up (j + 1) between free nodes, each tested exactly
    edge_ok = np.zeros((2, side * side), bool)
    for axis, step in ((0, side), (1, 1)):
        inside = (ii.ravel() < side - 1) if axis == 0 else (jj.ravel() < side - 1)
        u = np.flatnonzero(inside & free)
        u = u[free[u + step]]
        edge_ok[axis, u] = env.segments_clear(pts[u], pts[u + step], cl)
    parent = np.full(side * side, -1)
    parent[centre] = centre
    order = [centre]
    queue = deque([centre])
    while queue:
        u = queue.popleft()
        for w, ok in ((u + side, edge_ok[0, u]), (u - side, u >= side and edge_ok[0, u - side]),
                      (u + 1, edge_ok[1, u]), (u - 1, u % side > 0 and edge_ok[1, u - 1])):
            if ok and parent[w] < 0:
                parent[w] = u
                order.append(w)
                queue.append(w)
    order_a = np.asarray(order)
    _, near = tree.query(pts[order_a], k=min(4, lat.n))
    near = np.asarray(near).reshape(len(order_a), -1)
    goal = -1
    for lo in range(0, len(order_a), 512):
        blk = order_a[lo:lo + 512]
        v = near[lo:lo + 512]
        sees = env.segments_clear(np.repeat(pts[blk], v.shape[1], axis=0), lat.points[v.ravel()], cl)
        hit = np.flatnonzero(sees.reshape(len(blk), -1).any(axis=1))
        if len(hit):
            goal = int(blk[hit[0]])
            break
    if goal < 0 or goal == centre:
        return []
    path = [goal]
    while path[-1] != centre:
        path.append(int(parent[path[-1]]))
    path = path[::-1]
    corners: list[np.ndarray] = []
    at = 0
    while at < len(path) - 1:
        later = np.asarray(path[at + 1:])
        seen = env.segments_clear(np.repeat(pts[[path[at]]], len(later), axis=0), pts[later], cl)
        # the farthest node seen (the next one always is: its edge is clear)
        nxt = at + 1 + int(np.flatnonzero(seen)[-1])
        corners.append(pts[path[nxt]])
        at = nxt
    return corners
