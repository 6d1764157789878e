"""The grid stage: worlds whose starts and targets sit on one square grid.

Maps of cells (MovingAI benchmarks, occupancy grids) put every start and
target at a cell centre: on a grid ``offset + c * integers`` with
``separation <= c``, often below ``sqrt(2) * separation`` (cells of 2.4 for
robots of radius 1 and margin 0.1: separation 2.1), too fine for the
lattice stage's lattice (:mod:`planner.lattice`) but the natural graph.

1. **Detection** (:func:`detect_grid`): the spacing is the smallest gap
   between distinct coordinates of the starts and targets (or an integer
   fraction of it no smaller than the separation), and every coordinate
   must be ``offset + c * integer`` within ``1e-9`` (relative to the size
   of the workspace).
2. **Graph** (:func:`build_grid`): the grid points with exact clearance at
   least ``radius + margin``, and the 4-neighbour segments that are exactly
   clear.
3. **Routing**: TSWAP (:func:`planner.tswap.tswap`; Okumura and Defago,
   AIJ 2023), synchronous: each time step robots move to distinct
   neighbour vertices, no two swap, and a robot enters a vertex vacated in
   the same step only if the robot leaving it moves in the same direction.
   That rule is what the spacing needs.  In units of ``c`` the relative
   position of two robots moves on a segment between two non-zero integer
   vectors, by a difference of moves in ``{0, unit, unit + perpendicular
   unit, 2 unit}``: a unit or zero difference keeps it at least 1 (the
   segment lies on a grid line away from the origin, or along an axis
   from 1 to 2); a difference of two opposite units passes the origin only
   in a swap; a diagonal difference comes within ``1 / sqrt(2)`` of the
   origin only between two unit vectors, i.e. when one robot enters the
   vertex the other leaves in a perpendicular direction: following with a
   turn, ``c / sqrt(2) < separation``.  Every step is still checked with
   the exact closest-approach kernel over the pairs that can meet
   (:func:`step_separated`), and the stage gives up on a step that fails.
4. **Steps**: each time step is one plan step; consecutive steps are then
   merged where the straight joined step is exactly clear
   (:func:`planner.merge.merge_steps`), which cuts stops.  A few routings
   are tried and the shortest kept: targets assigned for the least longest
   route and by the fewest squares alone, in turns, from the third try on
   with ties broken at random (:func:`grid_plan`).
5. **Fewer steps**: TSWAP needs up to twice the shortest routing's steps
   when about half the vertices are taken.  Where the time-expanded graph
   is small enough, the routing with the fewest steps under the same rules
   is then sought as an integer program (:func:`planner.gridflow.flow_route`)
   below TSWAP's count (from :data:`FLOW_MIN_ROBOTS` robots on), within :data:`FLOW_BUDGET_S`, a third of the time
   left and :func:`route_budget` (1.2 s at 100 robots, 16.5 s at 400: TSWAP is
   close to the shortest routing when few vertices are taken), and kept when its plan
   is shorter.
6. **Steps of two cells**: every step goes from rest to rest, so a robot that
   crosses two cells straight on in one step saves the stop between them
   (4.5 s against 2 x 2.63 s at cells of 2.4).  On uniform grids the routing
   is sought again with such steps (:func:`planner.superflow.super_route`,
   same budget), each step checked exactly with a reach of two cells, and
   kept when its plan is shorter.
7. **The end again**: where TSWAP's routing is still the best (the searches
   did not run, on a sparse grid, or found nothing shorter), the robots still
   moving in its last steps are routed again by the fewest-steps search among
   the robots that stay (:func:`planner.gridflow.tail_route`, same budget):
   room-64-64-8 with 400 robots on random cells, 25 steps, the last 11 of
   which move 52 robots.
"""

from __future__ import annotations

import math
import time

import numpy as np

from .geometry import closest_approach
from .grid import Lattice
from .lattice import snap
from .mapgrid import _TOL, Lines, build_grid, detect_grid, find_grid, map_grid
from .problem import Problem
from .tswap import tswap

__all__ = ["FLOW_BUDGET_S", "FLOW_MIN_ROBOTS", "GRID_BUDGET_S", "GRID_TRIES", "build_grid", "detect_grid", "find_grid",
           "grid_plan", "grid_waypoints", "map_grid", "step_separated", "try_work"]



def step_separated(problem: Problem, a: np.ndarray, b: np.ndarray, reach: float) -> bool:
    """Whether the step ``a -> b`` (no move longer than ``reach``) keeps every pair of
    robots the separation apart, by the exact closest approach over the pairs whose
    starts are within ``separation + 2 reach``."""
    from scipy.spatial import cKDTree

    pairs = cKDTree(a).query_pairs(problem.separation + 2 * reach + 1e-9, output_type="ndarray")
    if len(pairs) == 0:
        return True
    i, j = pairs[:, 0], pairs[:, 1]
    d = closest_approach(a[i], b[i], a[j], b[j])
    return bool(d.min() >= problem.separation - 1e-9)


#: Routings tried by :func:`grid_plan` at most (the first two break ties by distance only,
#: the others also at random; the two assignments take turns), within :data:`GRID_BUDGET_S`
#: seconds of estimated work (:func:`try_work`).
GRID_TRIES = 12
GRID_BUDGET_S = 1.5
#: The work model of a try [s]: TSWAP's distance fields (first try only; later tries share
#: them) per robot and grid vertex, and the routing with its merge and checks per robot and
#: time step.  Measured on 30 MovingAI maps at 100 to 400 robots (2-core machine): fields
#: 0.1-0.15 us, later tries 2.5-9 us per robot-step (orz900d at 400: 1.0 s a try).
FIELD_S_PER_ROBOT_VERTEX = 0.15e-6
TRY_S_PER_ROBOT_STEP = 6e-6
#: Tries estimated to cost more than this [s] are not repeated for an assignment whose first
#: try with random tie-breaks routed exactly as its plain one (big sparse maps, where ties
#: seldom meet); cheaper ones run their full count (on room-32-32-4 at 50 robots the first
#: random try routes as the plain one and a later one is 5 % shorter; estimated 0.006 s).
#: From 0.1 to 0.04 s: the same plans on 42 map rows at 100 to 400 robots, and the 256 x 256
#: maps at 100 robots twice as fast (Paris_1_256 3.4 -> 1.7 s: a try there costs 0.2 s,
#: four times its estimate).
SETTLE_WORK_S = 0.04


def try_work(m: int, vertices: int, steps: int, first: bool) -> float:
    """Estimated seconds of one grid try (see :data:`TRY_S_PER_ROBOT_STEP`): a count, not a
    clock, so that the number of tries, and with it the plan, is the same on every machine
    and under any load."""
    return (FIELD_S_PER_ROBOT_VERTEX * m * vertices if first else 0.0) + TRY_S_PER_ROBOT_STEP * m * steps

#: Seconds the shortest-routing search (:mod:`planner.gridflow`) may take at most.
FLOW_BUDGET_S = 20.0
#: Fewer robots than this leave TSWAP's routing as it is (within a step or two of the shortest).
FLOW_MIN_ROBOTS = 40
#: Nor do robots on fewer than this share of the grid's vertices: on the benchmark maps at
#: 12-15 % taken no search found a shorter routing in its budget (the integer programs,
#: long horizons over a sparse grid, ran out of time), from 18 % on they did.
FLOW_MIN_OCCUPANCY = 0.15


def route_budget(m: int) -> float:
    """Seconds each of the routing searches (fewer steps, steps of two cells) may take
    for ``m`` robots: ``1e-4 m^2 + 0.5 min(1, (m / 150)^2)``, 1.2 s at 100 robots, 4.5 s
    at 200, 16.5 s at 400.  Below about 150 robots TSWAP's routing is within a step of
    the relaxed bound and the integer programs, with long horizons over a sparse grid,
    mostly run out of time (HiGHS overruns a short limit by up to a second in presolve),
    so the budget shrinks there to keep 100 robots within 3 s."""
    return 1e-4 * m**2 + 0.5 * min(1.0, (m / 150) ** 2)


def grid_plan(problem: Problem, deadline: float, grid=None, rng=None, info: dict | None = None):
    """``(merged waypoints, raw time steps)`` of the shortest of a few grid routings, or
    ``None``.  Each try is routed (:func:`grid_waypoints`), merged
    (:func:`planner.merge.merge_steps`) and timed.  Tries go on while their estimated work
    (:func:`try_work`, not the clock) fits in :data:`GRID_BUDGET_S`, and before
    ``deadline``.  An assignment whose first try with random tie-breaks routes exactly as
    its try without them is not tried again when its tries are costly (:data:`SETTLE_WORK_S`).
    ``info``, when given, gets ``snap_rounds`` (the snapping rounds onto the grid and off it)
    and ``route_steps`` (the steps between them) of the first try that routed."""
    from .merge import merge_steps
    from .timing import _drop_idle, _makespan

    grid = detect_grid(problem) if grid is None else grid
    if grid is None:
        return None
    if rng is None:
        raise ValueError("rng: the grid stage draws its tie-breaks from the run's generator; pass it")
    best = None
    memo: dict = {}  # what the tries share: the snapping rounds, TSWAP's fields and assignments
    work, last, plain, settled = 0.0, 0, {}, set()  # plain: each assignment's tie-free routing
    for k in range(GRID_TRIES):
        kind = k % 2  # even tries assign the targets for the least longest route, odd ones by
        # the fewest squares alone (more robots on long routes, but at times less crowding:
        # room-32-32-4 at 100 robots, 14 steps against 15); from the third on, ties are
        # broken at random
        if k and (time.perf_counter() > deadline or work + last > GRID_BUDGET_S or len(settled) == 2):
            break
        if kind in settled:
            continue
        raw = grid_waypoints(problem, deadline, grid, None if k < 2 else rng, bottleneck=kind == 0, memo=memo)
        if raw is None:
            if k == 0:
                return None
            work += last  # a failed try counted as the last one that routed
            continue
        last = try_work(problem.m, 0, len(raw) - 1, False)
        if info is not None and "route_steps" not in info:
            info["snap_rounds"] = sum(len(memo[key][0] or ()) for key in ("start", "target") if key in memo)
            info["route_steps"] = len(memo["steps"]) - 1
        work += try_work(problem.m, _graph(problem, grid)[0].n, len(raw) - 1, k == 0)
        if k < 2:
            plain[kind] = raw
        elif (last > SETTLE_WORK_S and len(raw) == len(plain.get(kind, ()))
              and all(np.array_equal(x, y) for x, y in zip(raw, plain[kind]))):
            settled.add(kind)
        w = merge_steps(problem, _drop_idle(raw), deadline)
        span = _makespan(problem, w)
        if best is None or span < best[2]:
            best = (w, len(raw) - 1, span)
            routing = memo["steps"]
    memo.pop("tswap", None)  # its fields (robots x vertices) are not needed by the searches below
    searched = False
    if (best is not None and best[1] > 1 and problem.m >= FLOW_MIN_ROBOTS
            and problem.m >= FLOW_MIN_OCCUPANCY * _graph(problem, grid)[0].n):  # built by the tries
        # the fewest steps (planner.gridflow), then steps of two cells (planner.superflow,
        # uniform grids only), each kept when its plan is shorter
        for kind in ("flow", "twos") if not isinstance(grid, Lines) else ("flow",):
            left = deadline - time.perf_counter()
            budget = min(FLOW_BUDGET_S, left / 3, route_budget(problem.m))
            arg = {"flow": (best[1], budget)} if kind == "flow" else {"twos": (best[2], budget)}
            raw = grid_waypoints(problem, deadline, grid, memo=memo, **arg)
            if raw is not None:
                w = merge_steps(problem, _drop_idle(raw), deadline)
                span = _makespan(problem, w)
                if span < best[2]:
                    best = (w, len(raw) - 1, span)
                    searched = True
    if best is not None and not searched and problem.m >= FLOW_MIN_ROBOTS and len(routing) > 2:
        # TSWAP's routing is still the best: its end, where few robots still move, routed again
        budget = min(FLOW_BUDGET_S, (deadline - time.perf_counter()) / 3, route_budget(problem.m))
        raw = grid_waypoints(problem, deadline, grid, memo=memo, tail=(routing, budget))
        if raw is not None:
            w = merge_steps(problem, _drop_idle(raw), deadline)
            span = _makespan(problem, w)
            if span < best[2]:
                best = (w, len(raw) - 1, span)
    return None if best is None else best[:2]


def grid_waypoints(problem: Problem, deadline: float, grid=None, rng=None,
                   flow: tuple[int, float] | None = None,
                   twos: tuple[float, float] | None = None, bottleneck: bool = True,
                   memo: dict | None = None, tail: tuple[list[np.ndarray], float] | None = None
                   ) -> list[np.ndarray] | None:
    """Raw waypoints (one per time step) of the grid stage, or ``None`` (no grid, a start
    or target off the graph, routing stalled, or the deadline).  ``rng``: ties among
    equally far robots broken at random (another try).  ``flow = (steps, budget)``:
    route by :func:`planner.gridflow.flow_route` in fewer than ``steps`` instead.
    ``twos = (seconds, budget)``: route with steps of two cells
    (:func:`planner.superflow.super_route`, uniform grids only) in less than
    ``seconds`` instead.  ``bottleneck``: TSWAP's first assignment (see
    :func:`planner.tswap.tswap`).  ``memo``: a dict kept between the tries of one problem,
    which then share the snapping rounds and TSWAP's distance fields and assignments; the
    vertices of the last routing are left in it under ``"steps"``.  ``tail = (steps,
    budget)``: the routing ``steps`` (vertices after each step) with its end routed again
    (:func:`planner.gridflow.tail_route`) instead."""
    grid = detect_grid(problem) if grid is None else grid
    if grid is None:
        return None
    lines = grid if isinstance(grid, Lines) else None
    c, offset = (lines.reach, None) if lines is not None else (grid[1], grid[0])
    built = _graph(problem, grid)
    if built is None or built[0].n == 0:
        return None
    lat, _, vid = built

    def vertex(p: np.ndarray) -> np.ndarray:
        if lines is not None:  # the nearest vertex (the placement is on it only if _on says so)
            from scipy.spatial import cKDTree

            return np.asarray(cKDTree(lat.points).query(p)[1], int)
        i0 = math.ceil(-float(offset[0]) / c - _TOL)
        j0 = math.ceil(-float(offset[1]) / c - _TOL)
        ij = np.round((p - offset) / c).astype(int) - np.array([i0, j0])
        if (ij < 0).any() or (ij[:, 0] >= vid.shape[0]).any() or (ij[:, 1] >= vid.shape[1]).any():
            return np.full(len(p), -1)
        return vid[ij[:, 0], ij[:, 1]]

    sv, gv = vertex(problem.start), vertex(problem.target)
    memo = {} if memo is None else memo
    entry = leave = None  # snapping rounds onto the grid (placements off it; no random draws)
    if not _on(lat, sv, problem.start):
        got = memo.get("start") or snap(problem, lat, problem.start, deadline)
        if got is None:
            return None
        memo["start"] = got
        entry, sv = got
    if not _on(lat, gv, problem.target):
        got = memo.get("target") or snap(problem, lat, problem.target, deadline)
        if got is None:
            return None
        memo["target"] = got
        leave, gv = got
    # sqrt(2) * separation or more: following with a turn is safe too
    turns = (lines.gap if lines is not None else c) >= math.sqrt(2.0) * problem.separation
    reach = [c * (1 + 1e-9)]
    if twos is not None:
        if lines is not None:
            return None
        steps = _two_cell_steps(problem, built, sv, gv, c, twos, deadline)
        if steps is None:
            return None
        reach = [c * (1 + 1e-9) * k for k in steps[1]]
        steps = steps[0]
    elif tail is not None:
        from .gridflow import tail_route

        steps = tail_route(lat, np.stack([np.asarray(sv, int), *tail[0]]), deadline, turns=turns, budget=tail[1])
    elif flow is not None:
        from .gridflow import flow_route

        steps = flow_route(lat, sv, gv, deadline, turns=turns, below=flow[0], budget=flow[1])
    else:
        steps = tswap(lat, sv, gv, deadline, turns=turns, rng=rng, bottleneck=bottleneck,
                      memo=memo.setdefault("tswap", {}))
    if steps is None:
        return None
    memo["steps"] = steps
    raw = [np.asarray(problem.start, float), *(entry or [])]
    for k, where in enumerate(steps):
        if time.perf_counter() > deadline:
            return None
        nxt = lat.points[where]
        if not step_separated(problem, raw[-1], nxt, reach[min(k, len(reach) - 1)]):
            return None  # never expected: the rule above keeps every step separated
        raw.append(nxt)
    if leave is None:
        # the robots end on the very target points (grid points equal them within 1e-9)
        raw[-1] = _exact_targets(problem, raw[-1])
        return raw
    # the target's snapping rounds played backwards: the robot on vertex gv[j] ends on target j
    at = np.full(lat.n, -1)
    at[steps[-1] if steps else sv] = np.arange(problem.m)
    robot = at[gv]
    if (robot < 0).any():
        return None
    inv = np.empty(problem.m, int)
    inv[robot] = np.arange(problem.m)
    back = [np.asarray(problem.target, float), *leave][::-1]  # target j's robot in row j
    raw += [cfg[inv] for cfg in back[1:]]
    return raw


def _graph(problem: Problem, grid):
    """The grid graph of ``grid`` (:func:`build_grid`), built once per problem: every
    try and every routing search use the same one."""
    if isinstance(grid, Lines):
        key: tuple = ("_grid_graph", id(grid))
    else:
        key = ("_grid_graph", tuple(np.asarray(grid[0], float)), float(grid[1]))
    if key not in problem.__dict__:
        problem.__dict__[key] = build_grid(problem, grid) if isinstance(grid, Lines) else build_grid(problem, *grid)
    return problem.__dict__[key]


def _two_cell_steps(problem: Problem, built, sv, gv, c: float, twos: tuple[float, float], deadline: float):
    """``(vertices after every step, step kinds)`` of :func:`planner.superflow.super_route`
    with its loops cut (:func:`planner.gridflow._park`) where every step stays separated
    after the cut (a robot parked on the middle of another's two-cell move would not)."""
    from .gridflow import _park
    from .profile import step_duration
    from .superflow import super_route

    lat, ij, vid = built
    t1, t2 = (float(step_duration(d, problem.max_speed, problem.max_accel)) for d in (c, 2 * c))
    got = super_route(lat, ij, vid, sv, gv, problem.separation / c, t1, t2, twos[0], deadline, twos[1])
    if got is None:
        return None
    kinds, where = got
    parked = list(_park(np.stack([np.asarray(sv, int), *where]))[1:])
    prev = lat.points[sv]
    for k, w in zip(kinds, parked):
        if not step_separated(problem, prev, lat.points[w], k * c * (1 + 1e-9)):
            return where, kinds
        prev = lat.points[w]
    return parked, kinds


def _on(lat: Lattice, v: np.ndarray, pts: np.ndarray) -> bool:
    """Whether every point sits on its grid vertex ``v`` (-1: none) within 1e-9 of the workspace."""
    if (v < 0).any():
        return False
    return bool(np.abs(lat.points[v] - pts).max(initial=0.0) <= 1e-9 * max(1.0, float(np.abs(pts).max(initial=1.0))))


def _exact_targets(problem: Problem, end: np.ndarray) -> np.ndarray:
    """Each final grid point replaced by the target it stands for."""
    from scipy.spatial import cKDTree

    _, k = cKDTree(problem.target).query(end)
    out = np.asarray(problem.target, float)[k]
    return out if len(np.unique(k)) == len(k) else end
