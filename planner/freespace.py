"""A roadmap of the free space and goal-swapping routing on it, every step tested exactly.

Where obstacles crowd the workspace, pebble graphs sampled at random rarely
line up through the gaps, and a regular lattice misses them.  This stage
builds one roadmap of the free space instead:

* its vertices are the starts, the targets, a square grid of clear points
  one separation apart, the chains of vertices lining every narrow passage
  (:func:`planner.passages.passage_points`) and points just outside every
  convex obstacle corner (:func:`planner.guide.corner_points`), the extra
  points thinned to keep ``0.7`` separations apart (a medial-axis flavour:
  passages and corners are where the free space is thinnest, as in Han and
  Yu's medial-axis pebble graphs for dense unlabeled discs);
* its edges join vertices less than ``2.2`` separations apart whose
  segment is clear of the obstacles and walls (exact);
* where the starts' and targets' vertices still fall into different
  components (a channel whose clear band is a few hundredths wide, or
  curved, has no straight clear edge between thinned vertices), the
  medial axis traced 0.1 apart is added with its Voronoi ridges as edges.

Vertices need not be separated from each other: which robots may stand or
move where is decided by exact tests, not by the graph.  Routing is TSWAP
(Okumura and Defago, AIJ 2023) with those tests in place of vertex
occupancy: targets are assigned by a minimum sum of squared roadmap
distances; at each time step robots, farthest from their target first,
take the next edge towards it (or another edge that still brings them
closer) when the straight move keeps the separation from every other
robot's move already decided in this step and from the robots not yet
decided, where they stand (every pair is therefore tested with both
actual motions by whichever decides second); a robot blocked by one
resting on its own target swaps targets with it, and a cycle of robots
each blocked by the next rotates its targets.  The other routing is PIBT
(:mod:`planner.pibt`, robots pushing each other aside); either one that
stalls is finished one robot at a time (:mod:`planner.endgame`).
"""

from __future__ import annotations

import time

import numpy as np
from scipy.spatial import cKDTree

from .geometry import closest_approach, greedy_separated, point_segment_distance
from .problem import Problem

__all__ = ["FreeRoadmap", "build_free_roadmap", "free_roadmap_setup", "free_roadmap_waypoints"]

_MAX_GRID = 250_000  # grid points of half a separation beyond which the stage does not run
_MEDIAL_SAMPLES = 60_000  # outline samples of the medial axis at most (the step grows beyond)


class FreeRoadmap:
    """Vertices ``points (V, 2)`` (the first ``m`` are the starts, the next ``m`` the
    targets), adjacency ``nbr`` (per vertex: neighbour ids, edge lengths)."""

    def __init__(self, points: np.ndarray, edges: np.ndarray, m: int):
        self.points = points
        self.m = m
        self.n = len(points)
        length = np.linalg.norm(points[edges[:, 0]] - points[edges[:, 1]], axis=1)
        self.edges, self.length = edges, length
        adj = [[] for _ in range(self.n)]
        for (u, v), d in zip(edges.tolist(), length.tolist()):
            adj[u].append((v, d))
            adj[v].append((u, d))
        self.nbr = adj

    def distances(self, sources: np.ndarray) -> np.ndarray:
        """``(len(sources), V)`` shortest roadmap lengths from each source (inf: unreachable)."""
        from scipy.sparse import coo_matrix
        from scipy.sparse.csgraph import shortest_path

        e = self.edges
        g = coo_matrix((np.r_[self.length, self.length] + 1e-12, (np.r_[e[:, 0], e[:, 1]], np.r_[e[:, 1], e[:, 0]])),
                       shape=(self.n, self.n)).tocsr()
        return shortest_path(g, method="D", directed=False, indices=sources)


def medial_points(problem: Problem, step: float = 0.25) -> np.ndarray:
    """Clear points on the free space's medial axis: the Voronoi vertices of points spaced
    ``step`` along every obstacle outline and wall that keep the clearance (each lies
    midway between two nearest outline points, along the middle of a channel)."""
    return medial_graph(problem, step, ridges=False)[0]


def medial_graph(problem: Problem, step: float, ridges: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """``(points, edges)``: the clear Voronoi vertices of :func:`medial_points` and the
    Voronoi ridges between two of them whose segment is clear (exact; with ``ridges``)."""
    from scipy.spatial import Voronoi

    w, h = problem.width, problem.height
    rings = [np.array([[0, 0], [w, 0], [w, h], [0, h]], float)]
    env = problem.env
    rings += list(env.polygons)
    for cc, r in zip(env.circle_centers, env.circle_radii):
        k = max(8, int(np.ceil(2 * np.pi * r / step)))
        ang = 2 * np.pi * np.arange(k) / k
        rings.append(cc + r * np.stack([np.cos(ang), np.sin(ang)], axis=1))
    a = np.vstack(rings)
    b = np.vstack([np.roll(r, -1, axis=0) for r in rings])
    length = np.linalg.norm(b - a, axis=1)
    # a coarser step where the outlines are long (Voronoi of 200 000 samples takes 7 s)
    step = max(step, float(length.sum()) / _MEDIAL_SAMPLES)
    n = np.maximum(1, np.ceil(length / step).astype(int))
    seg = np.repeat(np.arange(len(a)), n)
    f = ((np.arange(len(seg)) - np.repeat(np.cumsum(n) - n, n)) / n[seg])[:, None]
    pts = np.unique(np.round(a[seg] + f * (b[seg] - a[seg]), 12), axis=0)
    none = (np.zeros((0, 2)), np.zeros((0, 2), int))
    if len(pts) < 4:
        return none
    vor = Voronoi(pts)
    v = vor.vertices
    ok = (v[:, 0] > 0) & (v[:, 0] < w) & (v[:, 1] > 0) & (v[:, 1] < h)
    ok[ok] = env.points_clear(v[ok], problem.clearance)
    new_id = np.cumsum(ok) - 1
    if not ridges:
        return v[ok], none[1]
    rv = np.array([r for r in vor.ridge_vertices if r[0] >= 0 and r[1] >= 0], int).reshape(-1, 2)
    rv = rv[ok[rv[:, 0]] & ok[rv[:, 1]]]
    rv = rv[env.segments_clear(v[rv[:, 0]], v[rv[:, 1]], problem.clearance)] if len(rv) else rv
    return v[ok], new_id[rv].reshape(-1, 2)


def build_free_roadmap(problem: Problem, reach: float = 2.2, spacing: float = 0.9,
                       deadline: float = float("inf")) -> FreeRoadmap:
    """The roadmap of the module docstring (starts, targets, grid, passages, corners);
    where the starts' and targets' vertices fall apart, the traced medial axis is added
    (:func:`_bridge`; not after ``deadline``)."""
    from .guide import corner_points
    from .passages import passage_points

    c, sep = problem.clearance, problem.separation
    step = 0.5 * sep
    xs = np.arange(c, problem.width - c + 1e-9, step)
    ys = np.arange(c, problem.height - c + 1e-9, step)
    gx, gy = np.meshgrid(xs, ys, indexing="ij")
    grid = np.stack([gx.ravel(), gy.ravel()], axis=1)
    grid = grid[problem.env.points_clear(grid, c)]
    fixed = np.vstack([problem.start, problem.target])
    pieces = [grid]
    for part in (passage_points, medial_points, corner_points):  # seconds each on a large map
        if time.perf_counter() > deadline:
            return FreeRoadmap(fixed, np.zeros((0, 2), int), problem.m)  # the caller sees the deadline
        pieces.insert(len(pieces) - 1, part(problem))
    extra = np.vstack(pieces)
    keep = greedy_separated(extra, spacing * step, fixed)
    pts = np.vstack([fixed, extra[keep]])
    pairs = _clear_pairs(problem, pts, reach * sep)
    if time.perf_counter() < deadline and not _joined(len(pts), pairs, 2 * problem.m):
        pts, pairs = _bridge(problem, pts, pairs, 0.1)
    return FreeRoadmap(pts, pairs, problem.m)


def _clear_pairs(problem: Problem, pts: np.ndarray, reach: float, first: int = 0) -> np.ndarray:
    """``(E, 2)`` pairs of points less than ``reach`` apart whose segment is clear
    (exact), at least one of them from index ``first`` on."""
    pairs = cKDTree(pts).query_pairs(reach, output_type="ndarray").reshape(-1, 2)
    pairs = pairs[pairs.max(axis=1) >= first]
    if len(pairs):
        pairs = pairs[problem.env.segments_clear(pts[pairs[:, 0]], pts[pairs[:, 1]], problem.clearance)]
    return pairs.reshape(-1, 2)


def _joined(n: int, pairs: np.ndarray, k: int) -> bool:
    """Whether the first ``k`` of ``n`` vertices are in one component of the graph."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    g = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    _, label = connected_components(g, directed=False)
    return len(np.unique(label[:k])) == 1


def _bridge(problem: Problem, pts: np.ndarray, pairs: np.ndarray, fine: float) -> tuple:
    """The roadmap with the medial axis traced ``fine`` apart added (its Voronoi ridges as
    edges, every roadmap vertex joined to the axis points within a separation): a channel
    whose clear band is a few hundredths wide, or curved, has no straight clear edges
    between the thinned vertices, and this joins what the free space joins (used where the
    start's and the target's vertices fell apart)."""
    extra, ridges = medial_graph(problem, fine)
    n = len(pts)
    both = np.vstack([pts, extra])
    near = cKDTree(extra).query_ball_point(pts, problem.separation, return_sorted=False) if len(extra) else []
    link = np.array([(i, n + j) for i, js in enumerate(near) for j in js], int).reshape(-1, 2)
    if len(link):
        link = link[problem.env.segments_clear(both[link[:, 0]], both[link[:, 1]], problem.clearance)]
    return both, np.vstack([pairs, ridges + n, link]).astype(int)


def free_roadmap_setup(problem: Problem, deadline: float) -> tuple | None:
    """``(roadmap, field, goal_of)``: the roadmap, every vertex's roadmap length to each
    target (``field[g]``), and the minimum sum of squared roadmap lengths assignment of
    robots to targets; ``None`` when the workspace is too large for the roadmap's grid,
    a robot cannot reach the target it must take, or the deadline passes.  Remembered
    on the problem (routing tries with other random draws reuse it)."""
    from scipy.optimize import linear_sum_assignment

    memo = problem.__dict__.setdefault("_free_setup", {})
    if "setup" in memo:
        return memo["setup"]
    m = problem.m
    step = 0.5 * problem.separation
    if problem.width * problem.height / step**2 > _MAX_GRID:
        return None  # a workspace this large is the lattice stage's
    rm = build_free_roadmap(problem, deadline=deadline)
    if time.perf_counter() > deadline:
        return None
    goals = np.arange(m, 2 * m)
    field = rm.distances(goals)  # (goal, vertex)
    cost = field[:, :m].T  # (robot, goal)
    out = None
    if np.isfinite(cost).any(axis=1).all():
        _, goal_of = linear_sum_assignment(np.where(np.isfinite(cost), cost**2, 1e12))
        if np.isfinite(cost[np.arange(m), goal_of]).all():  # else a robot cannot reach its target
            out = (rm, field, goal_of.tolist())
    memo["setup"] = out
    return out


def free_roadmap_waypoints(problem: Problem, deadline: float, rng: np.random.Generator | None = None,
                           max_steps: int | None = None, escapes: int = 60,
                           router: str = "tswap") -> np.ndarray | None:
    """Raw waypoints ``(K + 1, m, 2)`` from the start to the target along the free-space
    roadmap, or ``None`` when routing stalls, a target is out of reach or the deadline passes.

    ``router`` ``"tswap"``: the goal-swapping routing of the module docstring; a time step
    in which nobody can move closer to a target becomes an *escape* step (with ``rng``; at
    most ``escapes`` of them): robots, in random order, take a random clear edge, wherever
    it leads, which unjams crowds that wait on each other.  ``"pibt"``: priority
    inheritance, robots pushing each other out of the way (:mod:`planner.pibt`).  Either
    routing that stalls, or goes ``100 + 2 m`` steps without bringing the robots closer to
    their targets, is finished one robot at a time (:mod:`planner.endgame`) when it can."""
    setup = free_roadmap_setup(problem, deadline)
    if setup is None or time.perf_counter() > deadline:
        return None
    rm, field, goal_of = setup
    m = problem.m
    if max_steps is None:
        max_steps = 40 * m + 400
    if router == "pibt":
        from .pibt import pibt_route

        if rng is None:
            raise ValueError("rng: PIBT draws its tie-breaks from the run's generator; pass it")

        out = pibt_route(rm, field, goal_of, problem.separation, deadline,
                         rng, max_steps)
        return None if out is None else np.asarray(out)
    goal_of = list(goal_of)
    goals = np.arange(m, 2 * m)
    pts = rm.points
    sep = problem.separation
    where = list(range(m))  # vertex of each robot
    pos = pts[:m].copy()
    frows = [field[g] for g in range(m)]
    goal_vert = goals.tolist()

    def at_goal(i: int) -> bool:
        return where[i] == goal_vert[goal_of[i]]

    def options(i: int) -> list[int]:
        """Neighbours closer to robot i's target, on the shortest path first."""
        row = frows[goal_of[i]]
        here = row[where[i]]
        cand = [(d + row[u], u) for u, d in rm.nbr[where[i]] if row[u] < here - 1e-9]
        cand.sort()
        return [u for _, u in cand]

    def blocker(i: int, v: int) -> int:
        """A robot (not i) standing closer than the separation to robot i's move onto vertex v,
        nearest to v first; -1: none."""
        d = point_segment_distance(pos, pos[i], pts[v])
        d[i] = np.inf
        if d.min() >= sep:
            return -1
        d = np.where(d < sep, np.hypot(*(pos - pts[v]).T), np.inf)
        j = int(np.argmin(d))
        return j if d[j] < sep else -1

    out = [pos.copy()]
    stall = since = 0
    best = np.inf
    stale = 100 + 2 * m  # steps without a new lowest sum of roadmap lengths left
    for _ in range(max_steps):
        if time.perf_counter() > deadline:
            return None
        if all(at_goal(i) for i in range(m)):
            return np.asarray(out)
        order = sorted((i for i in range(m) if not at_goal(i)), key=lambda i: -frows[goal_of[i]][where[i]])
        # target swaps with robots resting on their targets, rotations along blocking cycles
        for i in order:
            if at_goal(i):
                continue
            opts = options(i)
            if not opts:
                continue
            j = blocker(i, opts[0])
            if j < 0:
                continue
            if at_goal(j):
                goal_of[i], goal_of[j] = goal_of[j], goal_of[i]
                continue
            chain, seen, k = [i], {i}, j
            while k >= 0 and k not in seen and not at_goal(k):
                chain.append(k)
                seen.add(k)
                ok = options(k)
                k = blocker(k, ok[0]) if ok else -1
            if k == i and len(chain) > 1:
                first = goal_of[chain[0]]
                for x in range(len(chain) - 1):
                    goal_of[chain[x]] = goal_of[chain[x + 1]]
                goal_of[chain[-1]] = first
        # moves, each tested against the moves decided so far and everybody else where they stand
        nxt = pos.copy()
        moved = False
        order = sorted((i for i in range(m) if not at_goal(i)), key=lambda i: -frows[goal_of[i]][where[i]])
        for i in order:
            for v in options(i):
                b = pts[v]
                d = closest_approach(pos[i], b, pos, nxt)
                d[i] = np.inf
                if d.min() >= sep:
                    nxt[i] = b
                    where[i] = v
                    moved = True
                    break
        if not moved and rng is not None and escapes > 0:
            escapes -= 1
            for i in rng.permutation(m).tolist():
                nb = [u for u, _ in rm.nbr[where[i]]]
                for v in rng.permutation(nb).tolist() if nb else []:
                    d = closest_approach(pos[i], pts[v], pos, nxt)
                    d[i] = np.inf
                    if d.min() >= sep:
                        nxt[i] = pts[v]
                        where[i] = v
                        moved = True
                        break
        if moved:
            pos = nxt
            out.append(pos.copy())
            stall = 0
            left = sum(frows[goal_of[i]][where[i]] for i in range(m))
            if left < best - 1e-9:
                best, since = left, 0
            else:
                since += 1
                if since > stale:
                    break  # stepping around each other without getting anywhere
        else:
            stall += 1
            if stall > 3:
                break
    return _finish(rm, out, pos, where, sep, deadline)


def _finish(rm: FreeRoadmap, out: list, pos: np.ndarray, where: list, sep: float, deadline: float):
    """``out`` completed one robot at a time (:func:`planner.endgame.sequential_finish`)."""
    from .endgame import sequential_finish

    extra = sequential_finish(rm, pos, where, sep, deadline)
    return None if extra is None else np.asarray(out + extra)
