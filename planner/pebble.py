"""Pebble graphs (the paper's Algorithms 2 and 3) and the unlabeled pebble solver.

A *pumped configuration* is a set of ``n >= m`` free, mutually separated
placements.  Its *pebble graph* has an edge ``(v, v')`` when a robot moving
on the segment ``v -> v'`` stays clear of the obstacles and walls and
separated from robots parked on every other vertex.  Because the edge test
treats every other vertex as occupied, any pebble move along an edge onto a
free vertex is a valid robot motion whatever the rest of the placement is.

The paper's EDGE_PLANNER discretises the segment; here the test is exact:
the distance from a vertex ``u`` to the segment is the closed-form
point-to-segment distance, and the segment's clearance to obstacles comes
from :meth:`planner.geometry.Environment.segment_clearance`.

Signatures (Section II.C): the number of pebbles in each connected
component.  Two placements are equivalent, i.e. one can reach the other by
pebble moves, exactly when their signatures are equal.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from .geometry import greedy_separated, point_segment_distance
from .problem import Problem

__all__ = [
    "PebbleGraph",
    "build_pebble_graph",
    "edge_mask",
    "sample_free_points",
    "solve_pebbles",
]


@dataclass(frozen=True, eq=False)
class PebbleGraph:
    """A pumped configuration with its edges and connected components.

    vertices: ``(n, 2)`` placements; neighbors: sorted neighbour index
    arrays; component: component label of each vertex (0..h-1, numbered in
    order of the lowest vertex index).
    """

    vertices: np.ndarray
    neighbors: tuple[np.ndarray, ...]
    component: np.ndarray
    n_components: int

    @property
    def n(self) -> int:
        return len(self.vertices)

    @property
    def n_edges(self) -> int:
        return sum(len(a) for a in self.neighbors) // 2

    @classmethod
    def from_edges(cls, vertices, edges) -> "PebbleGraph":
        """A pebble graph with the given ``(E, 2)`` edge list (no geometry checked)."""
        return _graph_from_edges(np.asarray(vertices, float).reshape(-1, 2), np.asarray(edges, int).reshape(-1, 2))

    def signature(self, occupied) -> tuple[int, ...]:
        """Pebbles per connected component for the occupied vertex indices."""
        counts = np.bincount(self.component[np.asarray(occupied, int)], minlength=self.n_components)
        return tuple(int(c) for c in counts)


def sample_free_points(
    problem: Problem,
    count: int,
    rng: np.random.Generator,
    *,
    existing: np.ndarray | None = None,
    low=(0.0, 0.0),
    high=None,
    bridge_fraction: float = 0.0,
    max_batches: int = 200,
) -> np.ndarray:
    """Up to ``count`` clear points, separated from each other and from ``existing``.

    Algorithm 2 (PUMPED_CONFIGURATION), batched: candidates are drawn
    uniformly in the box ``[low, high]`` (default the workspace), those not
    clear of obstacles and walls are dropped, and the rest are accepted in
    order when separated from every point accepted so far.  With
    ``bridge_fraction > 0`` that share of the candidates comes from the
    bridge test instead (midpoints of two blocked points a short distance
    apart whose midpoint is free), which finds narrow passages that uniform
    sampling rarely hits.  Returns fewer points when the space is full.
    """
    clr = problem.clearance
    env = problem.env
    lo = np.maximum(np.asarray(low, float), clr)
    hi = np.array([problem.width, problem.height]) if high is None else np.asarray(high, float)
    hi = np.minimum(hi, np.array([problem.width, problem.height]) - clr)
    if np.any(hi <= lo):
        return np.zeros((0, 2))
    pts = np.zeros((0, 2)) if existing is None else np.asarray(existing, float).reshape(-1, 2)
    sep = problem.separation
    n0 = len(pts)
    batch = max(64, 4 * count)
    for _ in range(max_batches):
        need = count - (len(pts) - n0)
        if need <= 0:
            break
        n_bridge = int(round(batch * bridge_fraction))
        cand = rng.uniform(lo, hi, size=(batch - n_bridge, 2))
        if n_bridge:
            cand = np.vstack([cand, _bridge_candidates(problem, n_bridge, rng, lo, hi)])
        cand = cand[env.points_clear(cand, clr)]
        pts = np.vstack([pts, cand[greedy_separated(cand, sep, pts, need)]])
    return pts[n0:]


def _bridge_candidates(problem: Problem, k: int, rng, lo, hi) -> np.ndarray:
    """Midpoints of blocked point pairs whose midpoint is free (the bridge test)."""
    env = problem.env
    clr = problem.clearance
    a = rng.uniform(lo - clr, hi + clr, size=(k, 2))
    ang = rng.uniform(0.0, 2 * np.pi, size=k)
    length = rng.uniform(1.0, 3.0, size=k) * problem.separation
    b = a + length[:, None] * np.stack([np.cos(ang), np.sin(ang)], axis=1)
    mid = 0.5 * (a + b)
    blocked = (env.point_clearance(a) < clr) & (env.point_clearance(b) < clr)
    mid = mid[blocked]
    inside = np.all((mid >= lo) & (mid <= hi), axis=1)
    return mid[inside]


def edge_mask(problem: Problem, vertices: np.ndarray, pairs: np.ndarray, chunk: int = 1 << 20) -> np.ndarray:
    """Exact EDGE_PLANNER for candidate ``pairs`` ``(E, 2)`` of vertex indices.

    True where the segment between the two vertices is clear of obstacles
    and walls and at least the separation away from every other vertex (the
    closed-form point-to-segment distance; nothing is discretised).  Most
    long segments in a crowded configuration pass right by another vertex:
    a vertex within the separation of the segment's midpoint or quarter
    points blocks it for certain, which a KD-tree finds at once; only the
    segments that survive get the full test.
    """
    v = np.asarray(vertices, float)
    pairs = np.asarray(pairs, int).reshape(-1, 2)
    if len(pairs) == 0:
        return np.zeros(0, bool)
    sep = problem.separation
    a, b = v[pairs[:, 0]], v[pairs[:, 1]]
    ok = np.ones(len(pairs), bool)
    if len(v) > 2:
        tree = cKDTree(v)
        k = min(3, len(v))
        for f in (0.5, 0.25, 0.75):
            live = np.flatnonzero(ok)
            if len(live) == 0:
                break
            probe = a[live] + f * (b[live] - a[live])
            d, j = tree.query(probe, k=k)
            d = np.asarray(d).reshape(len(live), k)
            j = np.asarray(j).reshape(len(live), k)
            other = (j != pairs[live, 0:1]) & (j != pairs[live, 1:2])
            ok[live[((d < sep) & other).any(axis=1)]] = False
    idx = np.flatnonzero(ok)
    ok[idx] = problem.env.segments_clear(a[idx], b[idx], problem.clearance)
    idx = np.flatnonzero(ok)
    if len(idx) == 0 or len(v) <= 2:
        return ok
    n = len(v)
    rows = max(1, chunk // n)
    for s in range(0, len(idx), rows):
        sel = idx[s : s + rows]
        d = point_segment_distance(v[None, :, :], a[sel, None, :], b[sel, None, :])  # (rows, n)
        r = np.arange(len(sel))
        d[r, pairs[sel, 0]] = np.inf
        d[r, pairs[sel, 1]] = np.inf
        ok[sel] = d.min(axis=1) >= sep
    return ok


def build_pebble_graph(problem: Problem, vertices: np.ndarray) -> PebbleGraph:
    """Algorithm 3 over every pair of vertices (no cap on edge length)."""
    v = np.asarray(vertices, float).reshape(-1, 2)
    n = len(v)
    iu, ju = np.triu_indices(n, k=1)
    pairs = np.stack([iu, ju], axis=1)
    ok = edge_mask(problem, v, pairs)
    e = pairs[ok]
    return PebbleGraph.from_edges(v, e)


def _graph_from_edges(v: np.ndarray, e: np.ndarray) -> PebbleGraph:
    n = len(v)
    adj = coo_matrix(
        (np.ones(2 * len(e), bool), (np.r_[e[:, 0], e[:, 1]], np.r_[e[:, 1], e[:, 0]])),
        shape=(n, n),
    ).tocsr()
    adj.sort_indices()
    h, labels = connected_components(adj, directed=False)
    # Renumber components by their lowest vertex so labels do not depend on
    # the library's traversal order.
    first = {}
    for c in labels:
        first.setdefault(int(c), len(first))
    comp = np.array([first[int(c)] for c in labels], int)
    neighbors = tuple(adj.indices[adj.indptr[i] : adj.indptr[i + 1]].copy() for i in range(n))
    v = v.copy()
    v.setflags(write=False)
    return PebbleGraph(v, neighbors, comp, int(h))


def solve_pebbles(graph: PebbleGraph, start, target) -> list[tuple[int, int]]:
    """Unlabeled pebble motion: moves ``(from, to)`` taking ``start`` to ``target``.

    ``start`` and ``target`` are collections of distinct vertex indices of
    equal size.  Every move goes along an edge onto a free vertex.  Complete:
    a solution exists exactly when the signatures agree, and then one is
    returned; otherwise ``ValueError``.  Polynomial: ``O(n^2)`` moves.

    First, while some pebble off the target set has an edge straight to a
    free target vertex, the shortest such move is made (this alone often
    finishes, with few and short moves).  The rest is solved on each
    component by peeling a spanning tree leaf by leaf (the unlabeled case of
    Kornhauser, Miller and Spirakis), which keeps the invariant "as many
    pebbles as targets in the remaining tree":
      * a leaf ``l`` that is a target and holds a pebble: fix it, remove ``l``;
      * a target leaf that is empty: the nearest pebble walks to ``l`` (every
        vertex between is empty because that pebble is the nearest);
      * a non-target leaf that is empty: remove it;
      * a non-target leaf that holds a pebble: the pebbles on the path to the
        nearest empty vertex each shift one step towards it, which empties
        ``l`` (an empty vertex exists: the tree has more vertices than targets).
    """
    start = [int(x) for x in start]
    target = [int(x) for x in target]
    if len(set(start)) != len(start) or len(set(target)) != len(target):
        raise ValueError("start and target must be sets of distinct vertices")
    if graph.signature(start) != graph.signature(target):
        raise ValueError("signatures differ: no pebble solution exists")
    occupied = np.zeros(graph.n, bool)
    occupied[start] = True
    is_target = np.zeros(graph.n, bool)
    is_target[target] = True
    moves = _direct_moves(graph, occupied, is_target)
    for comp in range(graph.n_components):
        verts = np.flatnonzero(graph.component == comp)
        if np.array_equal(occupied[verts], is_target[verts]):
            continue
        tree = _spanning_tree(graph, int(verts[0]))
        _peel(tree, occupied, is_target, moves)
    return moves


def _direct_moves(graph: PebbleGraph, occupied, is_target) -> list[tuple[int, int]]:
    """Greedy shortest edges from pebbles off target onto free targets (in place)."""
    v = graph.vertices
    moves = []
    while True:
        src = np.flatnonzero(occupied & ~is_target)
        best = None
        for u in src:
            nb = graph.neighbors[u]
            nb = nb[is_target[nb] & ~occupied[nb]]
            if len(nb) == 0:
                continue
            d = np.linalg.norm(v[nb] - v[u], axis=1)
            j = int(np.argmin(d))
            if best is None or d[j] < best[0]:
                best = (float(d[j]), int(u), int(nb[j]))
        if best is None:
            return moves
        _, u, w = best
        moves.append((u, w))
        occupied[u] = False
        occupied[w] = True


def _spanning_tree(graph: PebbleGraph, root: int) -> dict[int, set[int]]:
    """BFS spanning tree of root's component as an adjacency dict."""
    tree: dict[int, set[int]] = {root: set()}
    queue = deque([root])
    while queue:
        u = queue.popleft()
        for w in graph.neighbors[u]:
            w = int(w)
            if w not in tree:
                tree[w] = {u}
                tree[u].add(w)
                queue.append(w)
    return tree


def _bfs_path(tree, src: int, goal) -> list[int]:
    """Shortest tree path from ``src`` to the nearest vertex with ``goal(v)``."""
    parent = {src: -1}
    queue = deque([src])
    while queue:
        u = queue.popleft()
        if u != src and goal(u):
            path = [u]
            while parent[path[-1]] != -1:
                path.append(parent[path[-1]])
            return path[::-1]
        for w in sorted(tree[u]):
            if w not in parent:
                parent[w] = u
                queue.append(w)
    raise RuntimeError("pebble solver invariant broken: no vertex found")


def _peel(tree, occupied, is_target, moves):
    leaves = sorted(v for v, nb in tree.items() if len(nb) <= 1)
    while tree:
        leaf = leaves.pop(0) if leaves else min(tree)
        if leaf not in tree:
            continue
        if is_target[leaf] and not occupied[leaf]:
            path = _bfs_path(tree, leaf, lambda v: occupied[v])
            # path runs leaf -> ... -> pebble; walk the pebble back along it.
            for k in range(len(path) - 1, 0, -1):
                moves.append((path[k], path[k - 1]))
                occupied[path[k]] = False
                occupied[path[k - 1]] = True
        elif not is_target[leaf] and occupied[leaf]:
            path = _bfs_path(tree, leaf, lambda v: not occupied[v])
            # path runs leaf -> ... -> hole; shift pebbles one step towards it.
            for k in range(len(path) - 1, 0, -1):
                moves.append((path[k - 1], path[k]))
                occupied[path[k - 1]] = False
                occupied[path[k]] = True
        for w in tree.pop(leaf):
            tree[w].discard(leaf)
            if len(tree[w]) <= 1:
                leaves.append(w)
        leaves.sort()
