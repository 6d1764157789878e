"""The UPUMP roadmap: pebble graphs, the connections between them, routes
through them and the retrieval of a route's waypoints (see :mod:`planner.upump`).

Roadmap nodes are ``(pebble graph, signature)`` pairs; its edges are
connections (:mod:`planner.connect`).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field

import networkx as nx
import numpy as np

from .connect import Connection, connect, connect_sequenced
from .pebble import PebbleGraph, build_pebble_graph, sample_free_points, solve_pebbles
from .plan import step_duration
from .problem import Problem

__all__ = ["Roadmap", "pump", "retrieve"]


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
    preferred: list[np.ndarray | None] = field(default_factory=list)
    graph: nx.Graph = field(default_factory=nx.Graph)
    families: list[list[int]] = field(default_factory=list)
    attempts: int = 0
    found: int = 0

    def add_graph(self, g: PebbleGraph, preferred: np.ndarray | None = None) -> int:
        """Add a pebble graph; ``preferred`` are its own placement's vertices.

        Connections favour preferred vertices (scanned first), and routes
        that land elsewhere are charged the pebble moves this costs.
        """
        self.graphs.append(g)
        self.preferred.append(None if preferred is None else np.asarray(preferred, int))
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

        On a graph with a preferred placement, the connection's vertices off
        it are matched (minimum sum) with the preferred vertices it leaves
        free, and each matched move is charged its own duration, as if the
        moves ran one after another.  On other graphs, half the robots are
        assumed to make one move across the graph's typical edge.
        """
        from scipy.optimize import linear_sum_assignment

        p = self.problem
        cost = 0.0
        for gid, verts in ((c.a, c.src), (c.b, c.dst)):
            g = self.graphs[gid]
            pref = self.preferred[gid]
            if pref is None:
                cost += p.m / 2 * step_duration(4 * p.separation, p.max_speed, p.max_accel)
                continue
            off = np.setdiff1d(verts, pref)
            free = np.setdiff1d(pref, verts)
            if len(off) == 0 or len(free) == 0:
                continue
            d = np.linalg.norm(g.vertices[off][:, None] - g.vertices[free][None], axis=2)
            r, k = linear_sum_assignment(d)
            cost += float(np.sum(step_duration(d[r, k], p.max_speed, p.max_accel)))
        return cost

    def connect_pair(self, a: int, b: int, attempts: int, rng) -> int:
        """Connect graphs ``a`` and ``b`` and add what is found to the roadmap.

        Between two graphs that both carry a whole preferred placement, the
        sequenced connection between those placements comes first; when it
        exists, the random attempts are skipped.  Otherwise CON_GEN runs.
        On the start graph (0) and the target graph (1) only the start's
        and the target's signatures are useful.
        """
        m = self.problem.m
        own = np.arange(m)
        need = {0: self.graphs[0].signature(own), 1: self.graphs[1].signature(own)}
        pa, pb = self.preferred[a], self.preferred[b]
        if pa is not None and pb is not None and len(pa) == m and len(pb) == m:
            # Straight moves; for a pair touching the start or the target,
            # also moves around the obstacles (guided chain legs are chosen
            # straight already).
            bends = (False, True) if self.problem.obstacles and (a in need or b in need) else (False,)
            for bent in bends:
                seq = connect_sequenced(self.problem, self.graphs[a], self.graphs[b], a, b, pa, pb, bent)
                if seq is not None and seq.sig_a == need.get(a, seq.sig_a) and seq.sig_b == need.get(b, seq.sig_b):
                    self.add_connections([seq])
                    return 1
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
            prefer_a=pa,
            prefer_b=pb,
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

    def routes(self, source, goal, k: int) -> list[list]:
        """Candidate routes: the ``k`` best by estimated time, plus the best
        route inside each family of graphs built to work together (the
        shared start-target graph, the guided chains), without repeats."""
        if self.route(source, goal) is None:
            return []
        out = list(itertools.islice(nx.shortest_simple_paths(self.graph, source, goal, weight="weight"), k))
        for fam in self.families:
            keep = set(fam) | {0, 1}
            sub = nx.subgraph_view(self.graph, filter_node=lambda node, keep=keep: node[0] in keep)
            try:
                r = nx.dijkstra_path(sub, source, goal, weight="weight")
            except (nx.NetworkXNoPath, nx.NodeNotFound):
                continue
            if r not in out:
                out.append(r)
        return out


def retrieve(problem: Problem, roadmap: Roadmap, route: list) -> list[np.ndarray]:
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
        if conn.order is None:  # everybody at once
            pos = pos.copy()
            pos[robots] = nb.vertices[conn.dst]
            waypoints.append(pos)
        else:  # one at a time, in dependency order, leg by leg around obstacles
            for k in conn.order:
                legs = [] if conn.via is None else list(conn.via[k])
                for point in legs + [nb.vertices[conn.dst[k]]]:
                    pos = pos.copy()
                    pos[robots[k]] = point
                    waypoints.append(pos)
        occ = {int(d): r for d, r in zip(conn.dst, robots)}
        gid = conn.b
    assert gid == 1
    pebble_moves(roadmap.graphs[1], range(m))
    return waypoints
