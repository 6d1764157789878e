"""UPUMP: the roadmap of pebble graphs, the query and path retrieval (Algorithms 5, 6).

Roadmap nodes are ``(pebble graph, signature)`` pairs; its edges are
connections (:mod:`planner.connect`).  The start and the target each live in
a pumped configuration of their own (the placement plus a few free
vertices), graphs 0 and 1.  A route from ``(0, sig(S))`` to ``(1, sig(T))``
becomes a plan: inside each graph the pebble solver moves robots one at a
time onto the next connection's sources (same signature, so it always
succeeds), then the connection moves them all at once into the next graph.

Filled gaps, following Solovey and Halperin's KPUMP/UPUMP:

* The paper's CONNECTIVITY_MATRIX / WAY_FINDER / FIND_PATH are a shortest
  path search over the roadmap (Dijkstra, weighted by step durations and an
  estimate of the pebble moves between connections).
* ``g`` and ``q`` may be ``auto``: an anytime loop that first tries the
  start and target graphs directly, then keeps adding one sampled pebble
  graph at a time, connecting it to every graph so far, doubling the
  attempts per pair every few graphs, until the start and target nodes are
  connected or the time limit passes (the paper's open problem, Sec. VI).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import networkx as nx
import numpy as np

from .connect import Connection, connect
from .params import PlannerParams
from .pebble import PebbleGraph, build_pebble_graph, sample_free_points, solve_pebbles
from .plan import Plan, PlanStats, step_duration
from .problem import Problem

__all__ = ["NoPlanFound", "Roadmap", "plan_sequential", "pump"]


class NoPlanFound(RuntimeError):
    """No plan within the limits; ``stats`` tells what was tried."""

    def __init__(self, message: str, stats: PlanStats):
        super().__init__(message)
        self.stats = stats


def pump(problem: Problem, placement: np.ndarray, extra: int, rng: np.random.Generator) -> PebbleGraph:
    """The pebble graph of ``placement`` plus ``extra`` free vertices near it.

    The free vertices are drawn in the placement's bounding box grown by two
    separations (so they are near enough to give the robots room to move),
    then anywhere in the workspace if that box is full.
    """
    pts = np.asarray(placement, float)
    grow = 2.0 * problem.separation
    near = sample_free_points(
        problem, extra, rng, existing=pts, low=pts.min(axis=0) - grow, high=pts.max(axis=0) + grow
    )
    if len(near) < extra:
        more = sample_free_points(problem, extra - len(near), rng, existing=np.vstack([pts, near]))
        near = np.vstack([near, more])
    return build_pebble_graph(problem, np.vstack([pts, near]))


@dataclass
class Roadmap:
    """Pebble graphs and the connections found between them.

    ``graph`` is a networkx graph over nodes ``(graph index, signature)``;
    each edge keeps its best connection (oriented from the smaller node).
    """

    problem: Problem
    graphs: list[PebbleGraph] = field(default_factory=list)
    graph: nx.Graph = field(default_factory=nx.Graph)
    attempts: int = 0
    found: int = 0

    def add_graph(self, g: PebbleGraph) -> int:
        self.graphs.append(g)
        return len(self.graphs) - 1

    def add_connections(self, conns: list[Connection]):
        for c in conns:
            u, v = (c.a, c.sig_a), (c.b, c.sig_b)
            self.found += 1
            weight = c.duration + self._pebble_estimate(c)
            old = self.graph.get_edge_data(u, v)
            if old is None or weight < old["weight"]:
                self.graph.add_edge(u, v, weight=weight, conn=c)

    def _pebble_estimate(self, c: Connection) -> float:
        """A rough time for the pebble moves around a connection (for routing).

        Each end of a connection that does not coincide with the graph's own
        start/target placement costs about one short pebble move per robot
        that is off it; this prefers routes with fewer pebble moves.
        """
        p = self.problem
        step = step_duration(p.separation, p.max_speed, p.max_accel)
        cost = 0.0
        for gid, verts in ((c.a, c.src), (c.b, c.dst)):
            if gid in (0, 1):
                cost += step * int(np.count_nonzero(np.asarray(verts) >= p.m))
        return cost

    def connect_pair(self, a: int, b: int, attempts: int, rng) -> int:
        """Run CON_GEN between graphs ``a`` and ``b`` and add what it finds.

        On the start graph (0) and the target graph (1) only the start's and
        the target's signatures are useful, and their own placements (the
        first ``m`` vertices) are preferred.
        """
        m = self.problem.m
        own = np.arange(m)
        need = {0: self.graphs[0].signature(own), 1: self.graphs[1].signature(own)}
        conns = connect(
            self.problem,
            self.graphs[a],
            self.graphs[b],
            a,
            b,
            attempts,
            rng,
            need_a=need.get(a),
            need_b=need.get(b),
            prefer_a=own if a in need else None,
            prefer_b=own if b in need else None,
        )
        self.attempts += attempts
        self.add_connections(conns)
        return len(conns)

    def route(self, source, goal) -> list | None:
        if source not in self.graph or goal not in self.graph:
            return None
        try:
            return nx.dijkstra_path(self.graph, source, goal, weight="weight")
        except nx.NetworkXNoPath:
            return None


def _retrieve(problem: Problem, roadmap: Roadmap, route: list) -> list[np.ndarray]:
    """RETRIEVE_PATH: waypoints along a roadmap route (pebble moves and connections)."""
    m = problem.m
    pos = problem.start.copy()
    waypoints = [pos.copy()]
    gid = 0
    occ = {v: v for v in range(m)}  # vertex of the current graph -> robot

    def pebble_moves(graph: PebbleGraph, goal):
        nonlocal pos
        for u, w in solve_pebbles(graph, sorted(occ), goal):
            r = occ.pop(u)
            occ[w] = r
            pos = pos.copy()
            pos[r] = graph.vertices[w]
            waypoints.append(pos)

    for u, v in zip(route[:-1], route[1:]):
        conn: Connection = roadmap.graph.edges[u, v]["conn"]
        if conn.a != u[0]:
            conn = conn.reversed()
        assert conn.a == gid
        pebble_moves(roadmap.graphs[gid], conn.src)
        nb = roadmap.graphs[conn.b]
        robots = [occ[int(s)] for s in conn.src]
        pos = pos.copy()
        pos[robots] = nb.vertices[conn.dst]
        waypoints.append(pos)
        occ = {int(d): r for d, r in zip(conn.dst, robots)}
        gid = conn.b
    assert gid == 1
    pebble_moves(roadmap.graphs[1], range(m))
    return waypoints


def _graph_size(problem: Problem, params: PlannerParams) -> int:
    if params.n is not None:
        return max(params.n, problem.m)
    return int(math.ceil(1.5 * problem.m)) + 2


def plan_sequential(problem: Problem, params: PlannerParams, rng: np.random.Generator, deadline: float):
    """Build the roadmap and retrieve a route; returns ``(waypoints, stats)``.

    Raises :class:`NoPlanFound` when the start and target stay unconnected.
    """
    t0 = time.perf_counter()
    m = problem.m
    stats = PlanStats()
    extra = params.extra if params.extra is not None else max(2, math.ceil(m / 4))
    rm = Roadmap(problem)
    rm.add_graph(pump(problem, problem.start, extra, rng))
    rm.add_graph(pump(problem, problem.target, extra, rng))
    source = (0, rm.graphs[0].signature(range(m)))
    goal = (1, rm.graphs[1].signature(range(m)))
    n = _graph_size(problem, params)
    bridge = 0.2 if problem.obstacles else 0.0

    if _same_placement(problem.start, problem.target):
        stats.found = True
        return [problem.start.copy()], _finish(stats, rm, 0, 0, t0)

    def sample_graph():
        v = sample_free_points(problem, n, rng, bridge_fraction=bridge)
        if len(v) < m:
            return None
        return build_pebble_graph(problem, v)

    route = None
    if params.auto:
        q = params.q if params.q is not None else 16
        g_cap = params.g  # None: unlimited
        rm.connect_pair(0, 1, q, rng)
        route = rm.route(source, goal)
        sampled = 0
        while route is None and time.perf_counter() < deadline and (g_cap is None or sampled < g_cap):
            g = sample_graph()
            sampled += 1
            if g is None:
                continue
            gid = rm.add_graph(g)
            for other in range(gid):
                rm.connect_pair(other, gid, q, rng)
                if time.perf_counter() > deadline:
                    break
            route = rm.route(source, goal)
            if route is None and params.q is None and sampled % 3 == 0:
                q = min(2 * q, 512)
        q_used, g_used = q, sampled
    else:
        for _ in range(params.g):
            g = sample_graph()
            if g is not None:
                rm.add_graph(g)
        for a in range(len(rm.graphs)):
            for b in range(a + 1, len(rm.graphs)):
                rm.connect_pair(a, b, params.q, rng)
        route = rm.route(source, goal)
        q_used, g_used = params.q, params.g

    stats = _finish(stats, rm, g_used, q_used, t0)
    if route is None:
        raise NoPlanFound(
            f"start and target not connected after {g_used} pebble graphs and "
            f"{rm.attempts} connection attempts",
            stats,
        )
    stats.found = True
    return _retrieve(problem, rm, route), stats


def _same_placement(a: np.ndarray, b: np.ndarray) -> bool:
    """Whether two placements are the same set of points."""
    ka = a[np.lexsort(a.T[::-1])]
    kb = b[np.lexsort(b.T[::-1])]
    return bool(np.array_equal(ka, kb))


def _finish(stats: PlanStats, rm: Roadmap, g: int, q: int, t0: float) -> PlanStats:
    stats.g = int(g)
    stats.q = int(q)
    stats.graphs = max(0, len(rm.graphs) - 2)
    stats.connections = rm.graph.number_of_edges()
    stats.planning_time_s = time.perf_counter() - t0
    stats.extra["attempts"] = rm.attempts
    return stats
