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
* ``g`` and ``q`` may be ``auto``: an anytime loop that first runs the
  structured stages (:data:`STAGES`; those the planner's direct tries
  already ran on whole placements are skipped, see
  :func:`planner.planning._direct`), then keeps adding one sampled pebble
  graph at a time, connecting it to every graph so far, doubling the
  attempts per pair every few graphs, until the start and target nodes are
  connected or the time limit passes (the paper's open problem, Sec. VI).
"""

from __future__ import annotations

import math
import time

import numpy as np

from .bounds import lower_bounds
from .connect import Connection
from .guide import expanded_placement, guided_placements
from .params import PlannerParams
from .passages import passage_points
from .pebble import build_pebble_graph, sample_free_points
from .plan import PlanStats
from .problem import Problem
from .roadmap import Roadmap, pump, retrieve

__all__ = ["STAGES", "NoPlanFound", "Roadmap", "build_roadmap", "pump", "retrieve", "stage_chain"]


class NoPlanFound(RuntimeError):
    """No plan within the limits; ``stats`` tells what was tried."""

    def __init__(self, message: str, stats: PlanStats):
        super().__init__(message)
        self.stats = stats


#: The structured stages of auto mode, in the order they run.
STAGES = ("sequenced", "expand-cross-contract", "guided chain")


def stage_chain(problem: Problem, stage: str) -> list[np.ndarray] | None:
    """A structured stage's chain of whole placements, start first, target last.

    These are the placements whose pebble graphs the stage adds to the
    roadmap (before thinning).  ``[]`` when the stage adds nothing (no
    placement needs expanding); ``None`` when one of them is thinned (the
    roadmap's free vertices must make up for the dropped points).
    """
    m = problem.m
    if stage == "sequenced":
        return [problem.start, problem.target]
    if stage == "expand-cross-contract":
        es, et = _capt_ends(problem)
        if es is None and et is None:
            return []
        a = problem.start if es is None else es
        b = problem.target if et is None else et
        inner = [] if es is None else [es]
        inner_end = [] if et is None else [et]
    else:
        a, b, inner, inner_end = problem.start, problem.target, [], []
    placements, _ = guided_placements(problem, a, b)
    chain = [problem.start, *inner, *placements, *inner_end, problem.target]
    if any(len(p) != m for p in chain):
        return None
    return chain


def _capt_ends(problem: Problem):
    """The expanded start and target (``None`` where no expansion is needed or fits); cached."""
    if "_capt_ends" not in problem.__dict__:
        problem.__dict__["_capt_ends"] = (expanded_placement(problem, problem.start),
                                          expanded_placement(problem, problem.target))
    return problem.__dict__["_capt_ends"]


#: Before each structured stage (after the first), the factor of the
#: makespan lower bound within which the best plan found so far ends the
#: search: 1.5 before the chains, 2 before the costly shared graph (over 20
#: seeds of the paper's line and random-to-line rows it changed no median
#: makespan below that; the 2.3-wide gap's went from 1.81x to 1.84x).
_GOOD_ENOUGH = (None, 1.5, 1.5, 2.0)


def _graph_size(problem: Problem, params: PlannerParams) -> int:
    if params.n is not None:
        return max(params.n, problem.m)
    return int(math.ceil(1.5 * problem.m)) + 2


def build_roadmap(problem: Problem, params: PlannerParams, rng: np.random.Generator, deadline: float,
                  makespan=None, incumbent: float | None = None, covered=frozenset()):
    """Sample pebble graphs and connections until the start and target connect.

    ``makespan(roadmap, route)``, when given, is the time of the plan a route
    makes (after scheduling); in auto mode the structured stages stop once
    the best route found is within a factor (``_GOOD_ENOUGH``) of the
    makespan lower bound.  ``incumbent`` is the makespan of a plan already
    found without the roadmap (the direct tries); it counts for that test,
    and with it the roadmap only looks for something better: no uniform
    sampling, no failure when nothing connects.  ``covered`` names the
    structured stages (:data:`STAGES`) the direct tries already ran.
    Returns ``(roadmap, source node, goal node, stats)``; raises
    :class:`NoPlanFound` when they stay unconnected within the limits and
    there is no incumbent.
    """
    t0 = time.perf_counter()
    m = problem.m
    stats = PlanStats()
    extra = params.extra if params.extra is not None else max(2, math.ceil(m / 4))
    own = np.arange(m)
    rm = Roadmap(problem)
    rm.add_graph(pump(problem, problem.start, extra, rng), own)
    if time.perf_counter() > deadline and incumbent is None:
        stats = _finish(stats, rm, 0, 0, t0)
        stats.extra["feasible"] = None
        raise NoPlanFound("no plan within the time limit", stats)
    rm.add_graph(pump(problem, problem.target, extra, rng), own)
    source = (0, rm.graphs[0].signature(own))
    goal = (1, rm.graphs[1].signature(own))
    n = _graph_size(problem, params)
    bridge = 0.2 if problem.obstacles else 0.0
    def sample_graph():
        lanes = passage_points(problem)  # fixed vertices lining the narrow passages
        v = sample_free_points(problem, n, rng, existing=lanes, bridge_fraction=bridge)
        if len(v) + len(lanes) < m:
            return None
        return build_pebble_graph(problem, np.vstack([lanes, v]))

    def connected():
        return rm.route(source, goal) is not None

    def good_enough(factor: float | None) -> bool:
        """The best plan so far is already within ``factor`` of the lower bound."""
        if makespan is None or factor is None:
            return False
        if incumbent is not None and incumbent <= factor * bound:
            return True
        route = rm.route(source, goal)
        return route is not None and makespan(rm, route) <= factor * bound

    if params.auto:
        q = params.q if params.q is not None else 16
        g_cap = params.g  # None: unlimited
        bound = lower_bounds(problem)[0]
        # Structured candidates first, cheapest and most often best first;
        # each is skipped once a route (or the incumbent) is already close
        # to the bound, or when the direct tries covered it.
        stages = {
            "sequenced": lambda: rm.connect_pair(0, 1, q, rng),
            "expand-cross-contract": lambda: _add_capt(problem, rm, extra, q, rng),
            "guided chain": lambda: _add_direct_chain(problem, rm, extra, q, rng),
        }
        done = False
        for factor, name in zip(_GOOD_ENOUGH, STAGES):
            if good_enough(factor) or time.perf_counter() > deadline:
                done = True
                break
            if name not in covered:
                stages[name]()
        # One graph holding both placements (and the narrow-passage lanes):
        # worth its cost where robots must file through a passage, or when
        # nothing connects yet.
        if not done and not good_enough(_GOOD_ENOUGH[-1]) and time.perf_counter() < deadline:
            lanes = passage_points(problem)
            if len(lanes) or not (connected() or incumbent is not None):
                _add_shared(problem, rm, extra, rng, lanes)
        sampled = 0
        while (not connected() and incumbent is None and time.perf_counter() < deadline
               and (g_cap is None or sampled < g_cap)):
            g = sample_graph()
            sampled += 1
            if g is None:
                continue
            gid = rm.add_graph(g)
            for other in range(gid):
                rm.connect_pair(other, gid, q, rng)
                if time.perf_counter() > deadline:
                    break
            if not connected() and params.q is None and sampled % 3 == 0:
                q = min(2 * q, 512)
        # g used: every pebble graph sampled besides the start's and the
        # target's (structured and uniform); q used: attempts per pair.
        q_used, g_used = q, len(rm.graphs) - 2
    else:
        # Fixed g and q: the paper's algorithm as it stands, g uniform graphs
        # and q attempts between every two graphs.
        for _ in range(params.g):
            if time.perf_counter() > deadline:
                break
            g = sample_graph()
            if g is not None:
                rm.add_graph(g)
        for a in range(len(rm.graphs)):
            for b in range(a + 1, len(rm.graphs)):
                if time.perf_counter() > deadline:
                    break
                rm.connect_pair(a, b, params.q, rng)
        q_used, g_used = params.q, params.g

    stats = _finish(stats, rm, g_used, q_used, t0)
    if not connected() and incumbent is None:
        stats.extra["feasible"] = None  # not proven either way
        raise NoPlanFound(
            f"start and target not connected after {g_used} pebble graphs and "
            f"{rm.attempts} connection attempts",
            stats,
        )
    stats.found = True
    return rm, source, goal, stats


def _add_shared(problem: Problem, rm: Roadmap, extra: int, rng, lanes: np.ndarray) -> None:
    """One pebble graph holding both the start and the target, when they are separated.

    It joins the start and target graphs by zero-length connections (the
    robots stay where they are), so routes may solve the whole problem by
    pebble moves in one graph, which are short when the formations are
    near each other.
    """
    m = problem.m
    d = np.linalg.norm(problem.start[:, None] - problem.target[None], axis=2)
    if d.min() < problem.separation:
        return
    both = np.vstack([problem.start, problem.target])
    if len(lanes):  # narrow-passage lanes that do not crowd the placements
        d = np.linalg.norm(lanes[:, None] - both[None], axis=2).min(axis=1)
        both = np.vstack([both, lanes[d >= problem.separation]])
    g = pump(problem, both, extra, rng)
    gid = rm.add_graph(g, np.arange(2 * m))
    rm.families.append([gid])
    own = np.arange(m)
    for a, verts in ((0, own), (1, own + m)):
        sig_g = g.signature(verts)
        c = Connection(a, gid, own, verts, 0.0, rm.graphs[a].signature(own), sig_g)
        rm.add_connections([c])


def _placement_graph(problem: Problem, pts: np.ndarray, extra: int, rng, rm: Roadmap) -> int | None:
    """Add the pebble graph of a (thinned) placement plus free vertices near it."""
    if len(pts) == 0:
        return None
    free = sample_free_points(
        problem, extra + problem.m - len(pts), rng, existing=pts,
        low=pts.min(axis=0) - 2 * problem.separation, high=pts.max(axis=0) + 2 * problem.separation,
    )
    if len(pts) + len(free) < problem.m:
        free = np.vstack([free, sample_free_points(problem, problem.m - len(pts) - len(free), rng,
                                                   existing=np.vstack([pts, free]))])
    g = build_pebble_graph(problem, np.vstack([pts, free]))
    if g.n < problem.m:
        return None
    return rm.add_graph(g, np.arange(len(pts)))


def _add_chain(problem, rm, extra, attempts, rng, first, last, start_pts, target_pts):
    """Guided placements from ``start_pts`` to ``target_pts``, chained ``first`` -> ``last``."""
    placements, _ = guided_placements(problem, start_pts, target_pts)
    chain = [first]
    for pts in placements:
        gid = _placement_graph(problem, pts, extra, rng, rm)
        if gid is not None:
            chain.append(gid)
    chain.append(last)
    for a, b in zip(chain[:-1], chain[1:]):
        if (a, b) != (0, 1):
            rm.connect_pair(a, b, attempts, rng)
    return chain


def _add_direct_chain(problem: Problem, rm: Roadmap, extra: int, attempts: int, rng) -> None:
    """Guided placements straight from the start to the target."""
    rm.families.append(_add_chain(problem, rm, extra, attempts, rng, 0, 1, problem.start, problem.target))


def _add_capt(problem: Problem, rm: Roadmap, extra: int, attempts: int, rng) -> None:
    """Expand, cross, contract: spread the start out (a scaling never brings
    robots closer), cross to the spread-out target along a CAPT-spaced
    chain, and contract into the target."""
    es, et = _capt_ends(problem)
    a = 0 if es is None else _placement_graph(problem, es, extra, rng, rm)
    b = 1 if et is None else _placement_graph(problem, et, extra, rng, rm)
    if a is None or b is None or (a, b) == (0, 1):
        return
    if a != 0:
        rm.connect_pair(0, a, attempts, rng)
    if b != 1:
        rm.connect_pair(b, 1, attempts, rng)
    chain = _add_chain(problem, rm, extra, attempts, rng, a, b,
                       rm.graphs[a].vertices[rm.preferred[a]], rm.graphs[b].vertices[rm.preferred[b]])
    rm.families.append([0, *chain, 1])


def _finish(stats: PlanStats, rm: Roadmap, g: int, q: int, t0: float) -> PlanStats:
    stats.g = int(g)
    stats.q = int(q)
    stats.graphs = max(0, len(rm.graphs) - 2)
    stats.connections = rm.graph.number_of_edges()
    stats.planning_time_s = time.perf_counter() - t0
    stats.extra["attempts"] = rm.attempts
    return stats
