"""The planner's entry point: :func:`plan` (UPUMP, then timing and exact validation)."""

from __future__ import annotations

import time

import numpy as np
from scipy.optimize import linear_sum_assignment

from .bounds import lower_bounds
from .connect import sequenced_moves
from .conveyor import DOOR_MIN_ROBOTS
from .dense import dense
from .feasibility import feasibility
from .gridstage import find_grid, grid_plan
from .guide import Late
from .mapgrid import robot_cells
from .params import PlannerParams
from .plan import Plan, PlanStats
from .problem import Problem
from .schedule import shortcut, step_clear
from .timing import _makespan, _timed
from .tries import (
    CLUTTER,
    _after_grid,
    _bounds_end,
    _cut_bound,
    _dense,
    _Direct,
    _door,
    _free_space,
    _geo_bound,
    _lattice,
    _name_direct,
)
from .upump import _GOOD_ENOUGH, STAGES, NoPlanFound, build_roadmap, retrieve, stage_chain
from .validate import PlanInvalid, check_plan

__all__ = ["NoPlanFound", "plan"]


def plan(problem: Problem, params: PlannerParams | None = None, rng: np.random.Generator | None = None):
    """Plan collision-free motions for the unlabeled problem.

    Returns ``(Plan, PlanStats)``; the plan has passed the exact validator
    (its minimum gap is at least the margin).  Raises :class:`NoPlanFound`,
    carrying the stats, when no plan is found within the limits.
    ``rng`` is the run's one generator (required: no default seed).  A plan
    found with too little of the time limit left to compute the makespan
    and path-length lower bounds (about ``1e-6 m^2`` s) is returned without
    them in its stats (NaN, and ``stats.extra["lower_bounds"]`` says why)
    unless they were already known.
    """
    params = params or PlannerParams()
    if rng is None:
        raise ValueError("rng: plan() draws from the run's one generator; pass it "
                         "(numpy.random.Generator, e.g. np.random.default_rng(seed))")
    if params.margin_extra:
        return _plan_inflated(problem, params, rng)
    problem.validate()
    t0 = time.perf_counter()
    limit = t0 + params.time_limit
    # The search stops early enough for the exact check of the plan it found,
    # which runs whatever the clock says (about 0.6 s at 1000 robots, more among
    # many obstacles): a reserve of at most 0.3 of the limit.
    deadline = limit - min(0.3 * params.time_limit, _CHECK_S_PER_ROBOT * problem.m * (1 + len(problem.obstacles) / 100))
    # A plan of one straight step needs no proof that a plan exists (and is cheap to find);
    # on a grid the grid stage goes first (the proof takes about 0.3 s on a 256 x 256 map, a
    # share of a short limit) and the proof follows only when it found nothing.
    one_step = params.auto and _at_once(problem, problem.start, problem.target, deadline) is not None
    gridded = params.auto and problem.m >= GRID_MIN_ROBOTS and find_grid(problem) is not None
    if not (one_step or gridded):
        _prove(problem, t0)
    memo: dict = {}
    same = _same_set(problem.start, problem.target)
    # on a grid, the proof runs as soon as the grid stage has failed, before the other stages
    proved = (lambda: _prove(problem, t0)) if gridded and not one_step else None
    direct = None if same else _direct(problem, params, memo, deadline, rng, on_grid_fail=proved)
    if same:
        stats = PlanStats(found=True)
        result = Plan.from_waypoints(problem.start[None], problem.radius, problem.margin,
                                     problem.max_speed, problem.max_accel)
    elif direct is not None and direct.best is None and time.perf_counter() > deadline:
        stats = PlanStats(planning_time_s=time.perf_counter() - t0)
        stats.extra["feasible"] = None  # not proven either way
        raise NoPlanFound(f"no plan within the time limit of {params.time_limit:g} s "
                          f"(the direct tries used it up)", stats)
    elif direct is not None and direct.best is None and problem.m >= ROADMAP_MAX_ROBOTS:
        stats = PlanStats(planning_time_s=time.perf_counter() - t0)
        stats.extra["feasible"] = None  # not proven either way
        raise NoPlanFound(f"no plan: the lattice and free-space stages failed, and with {problem.m} "
                          f"robots the pebble-graph roadmap is not tried", stats)
    elif direct is not None and (direct.final(problem) or time.perf_counter() > deadline):
        waypoints, sequential, _, label = direct.best
        if params.concurrent:
            waypoints = shortcut(problem, waypoints, deadline=deadline)
        result = Plan.from_waypoints(waypoints, problem.radius, problem.margin, problem.max_speed,
                                     problem.max_accel)
        stats = PlanStats(found=True, g=0, q=0, graphs=0, connections=direct.legs[label])
        stats.extra["sequential_steps"] = sequential
        _name_direct(stats, label)
        stats.extra["attempts"] = 0
    else:
        timed: dict[tuple, tuple] = {}  # route -> (waypoints, sequential steps, makespan)

        def evaluate(roadmap, route):
            key = tuple(route)
            if key not in timed:
                timed[key] = _timed(problem, params, retrieve(problem, roadmap, route), memo, deadline)
            return timed[key]

        incumbent = None if direct is None or direct.best is None else direct.best[2]
        try:
            roadmap, source, goal, stats = build_roadmap(
                problem, params, rng, deadline, makespan=lambda rm, route: evaluate(rm, route)[2],
                incumbent=incumbent, covered=set() if direct is None else direct.covered,
            )
        except NoPlanFound as exc:  # its time is the whole run's, direct tries included
            exc.stats.planning_time_s = time.perf_counter() - t0
            raise
        best = None if direct is None else direct.best  # (waypoints, sequential, makespan, label)
        for route in roadmap.routes(source, goal, _ROUTES):
            waypoints, sequential, makespan = evaluate(roadmap, route)
            if best is None or makespan < best[2]:
                best = (waypoints, sequential, makespan, route)
        waypoints, sequential, _, route = best
        if params.concurrent:
            waypoints = shortcut(problem, waypoints, deadline=deadline)
        result = Plan.from_waypoints(waypoints, problem.radius, problem.margin, problem.max_speed,
                                     problem.max_accel)
        stats.extra["sequential_steps"] = sequential
        if isinstance(route, str):  # a direct try beat every roadmap route
            _name_direct(stats, route)
        else:
            stats.extra["route"] = [int(g) for g, _ in route]
    try:
        clearance = check_plan(problem, result)
    except PlanInvalid as exc:  # a bug, never an expected outcome
        raise AssertionError(f"planner produced an invalid plan: {exc}") from exc
    _fill_stats(stats, result, clearance.value)
    left = limit - time.perf_counter()
    need = _BOUNDS_S_PER_ROBOT2 * problem.m**2
    if "_lower_bounds" in problem.__dict__ or left >= need:
        stats.makespan_lower_bound_s, stats.path_length_lower_bound = lower_bounds(problem)
    else:  # about a second at 1000 robots: the time limit comes first (the stats keep NaN)
        stats.extra["lower_bounds"] = (f"not computed: they take about {need:.2g} s and "
                                       f"{max(left, 0.0):.2g} s of the time limit was left")
    if stats.extra.get("direct") == "grid":  # elsewhere it would cost more than the plan
        end = _bounds_end(t0, limit)
        _geo_bound(problem, stats, end, limit)
    else:
        end = _bounds_end(t0, limit, least=0.05)
        stats.extra["geo_lower_bound"] = "not computed: grid worlds only (planner.geobound.geo_lower_bound)"
    _cut_bound(problem, stats, end, limit)
    stats.planning_time_s = time.perf_counter() - t0
    result = Plan(result.radius, result.margin, result.durations, result.waypoints,
                  result.max_speed, result.max_accel, stats)
    return result, stats


def _prove(problem: Problem, t0: float) -> None:
    """Raise :class:`NoPlanFound` (``feasible=False``) when :func:`feasibility` proves no plan exists."""
    proof = feasibility(problem)
    if proof is not None:
        stats = PlanStats(planning_time_s=time.perf_counter() - t0)
        stats.extra.update(feasible=False, infeasible_reason=proof.reason)
        raise NoPlanFound(proof.reason, stats)


def _plan_inflated(problem: Problem, params: PlannerParams, rng):
    """:func:`plan` with ``params.margin_extra``: plan with the margin inflated,
    validate against the real one, and record both in the stats
    (``margin``, ``margin_extra``; ``min_clearance`` is the exact gap)."""
    from dataclasses import replace

    from .problem import ProblemError

    extra = float(params.margin_extra)
    if not (np.isfinite(extra) and extra >= 0):
        raise ProblemError("planner.margin_extra", f"must be a number >= 0, got {params.margin_extra!r}")
    problem.validate()
    inflated = replace(problem, margin=problem.margin + extra)
    try:
        inflated.validate()
    except ProblemError as exc:
        raise ProblemError("planner.margin_extra",
                           f"with margin + margin_extra = {inflated.margin:g}, {exc.field}: {exc.reason}") from None
    try:
        result, stats = plan(inflated, replace(params, margin_extra=0.0), rng)
    except NoPlanFound as exc:
        exc.stats.extra.update(margin=problem.margin, margin_extra=extra)
        raise
    check_plan(problem, result)  # the real margin (the inflated one already held)
    stats.extra.update(margin=problem.margin, margin_extra=extra)
    result = Plan(result.radius, problem.margin, result.durations, result.waypoints,
                  result.max_speed, result.max_accel, stats)
    return result, stats


#: From this many robots on, auto mode routes the swarm through a lattice
#: (:mod:`planner.lattice`) right after the one-step try: below it the
#: structured stages find shorter plans in a few milliseconds.
LATTICE_MIN_ROBOTS = 60

#: From this many robots on, auto mode tries the grid stage (:mod:`planner.gridstage`)
#: right after the one-step try when every start and target lies on one square grid.
GRID_MIN_ROBOTS = 12

DENSE_COVERAGE = 0.3  #: robots' discs over an obstacle-free workspace from which the packing stage (planner.dense) runs
#: Robots' discs over the workspace's area outside the obstacles from which the packing stage
#: runs among obstacles, first (unless they are a map of cells a robot fills,
#: :func:`planner.mapgrid.robot_cells`), its plan then competing with the others'.
DENSE_AMONG_OBSTACLES = 0.2

#: From this many robots on, auto mode does not build the pebble-graph roadmap when its
#: direct tries found nothing: its interference graphs grow with the square of the
#: candidate pairs (gigabytes at 1000 robots) and it never connected such problems.
ROADMAP_MAX_ROBOTS = 300

_ROUTES = 3  # best routes by estimate compared by their scheduled makespan (plus one per family)
_CHECK_S_PER_ROBOT = 6e-4  # the exact check of a plan [s per robot], measured at 1000 robots, times 1 + obstacles / 100
# (0.96 s at 200 robots among the 804 rectangles of warehouse-20-40-10-2-2)
_BOUNDS_S_PER_ROBOT2 = 1e-6  # the lower bounds [s per robot squared]: about 0.9 s at 1000 robots


def _direct(problem: Problem, params: PlannerParams, memo: dict, deadline: float = float("inf"),
            rng: np.random.Generator | None = None, on_grid_fail=None) -> _Direct | None:
    """Auto mode's tries, before any pebble graph is sampled (``None`` with fixed g and q).

    1. All robots at once, straight to their assigned targets, when that
       single step is clear: a connection in the paper's sense (m pairs,
       no two interfering), exact.
    2. The roadmap's structured stages (:data:`planner.upump.STAGES`) run
       on whole placements, without pumping pebble graphs: the robots go
       from each placement of a stage's chain to the next (see
       :func:`_chain_waypoints`), then the moves are scheduled
       concurrently.  Where every leg is a sequenced connection, this is
       the route the roadmap would find through that stage (same plan).

    Like the roadmap, it stops at the first stage before which the best
    plan is within the stage's good-enough factor of the makespan lower
    bound (``accepted``).  A stage whose chain has a thinned placement or
    a leg it cannot move is left to the roadmap (``covered`` lacks it),
    which has free vertices to work with; ``memo`` keeps every timing, so
    the roadmap does not redo an identical route.
    """
    if not params.auto or _GOOD_ENOUGH[1] is None:
        return None
    out = _Direct()
    end = _at_once(problem, problem.start, problem.target, deadline)
    if end is not None:
        one = np.stack([problem.start, end])
        out.offer("one step", 1, (one, 1, _makespan(problem, one)))
        if out.best[2] <= _GOOD_ENOUGH[1] * lower_bounds(problem)[0]:
            out.accepted = True
            return out
    if problem.m >= GRID_MIN_ROBOTS and time.perf_counter() < deadline:
        grid = find_grid(problem)
        if (problem.obstacles and (grid is None or grid[1]) and not robot_cells(problem)
                and dense(problem, DENSE_AMONG_OBSTACLES)):  # the cheap test first
            _dense(problem, out, deadline, rng)  # before snapping onto a coarser grid, which packs worse
        if grid is not None:  # starts and targets on one grid, or a map of cells: route on it
            t_grid, info = time.perf_counter(), {}
            found = grid_plan(problem, deadline, grid[0], rng, info=info)
            if found is not None:
                w, sequential = found
                out.offer("grid", sequential, (w, sequential, _makespan(problem, w)))
                if grid[1]:  # snapped onto a map's cells
                    _after_grid(problem, params, out, info, t_grid, deadline, rng,
                                lattice=problem.m >= LATTICE_MIN_ROBOTS)
                out.accepted = True
                return out
    if on_grid_fail is not None and time.perf_counter() < deadline:
        on_grid_fail()  # raises NoPlanFound when no plan exists
    if (not problem.obstacles and dense(problem, DENSE_COVERAGE)
            and time.perf_counter() < deadline):
        from .dense import dense_plan  # packings too dense for the other stages
        found_plan = dense_plan(problem, deadline - time.perf_counter(), rng)
        if found_plan is not None:
            w = np.asarray(found_plan.waypoints)
            out.offer("dense", len(w) - 1, (w, len(w) - 1, found_plan.makespan))
            out.accepted = True
            return out
    if (problem.m >= DOOR_MIN_ROBOTS and 0 < len(problem.obstacles) < CLUTTER and time.perf_counter() < deadline
            and _door(problem, out, deadline)):  # a crowd through a door one robot wide: trains
        return out
    if problem.m >= LATTICE_MIN_ROBOTS and time.perf_counter() < deadline:
        _lattice(problem, out, deadline)
        if out.best is not None:
            # the one-at-a-time stages rarely beat it with this many robots
            out.accepted = True
            return out
    # The bound costs about a second at 1000 robots: not before the lattice needs it.
    if time.perf_counter() > deadline:
        return out
    bound = lower_bounds(problem)[0]
    if len(problem.obstacles) >= CLUTTER:  # the stage that works among many obstacles, first
        _free_space(problem, out, bound, deadline, rng)
        if out.accepted:
            return out
    for factor, stage in zip(_GOOD_ENOUGH, STAGES):
        if factor is not None and out.best is not None and out.best[2] <= factor * bound:
            out.accepted = True
            return out
        if time.perf_counter() > deadline:
            return out
        chain = stage_chain(problem, stage)
        if chain is None:  # a thinned placement: left to the roadmap
            continue
        if not chain:  # nothing to add (no placement needs expanding)
            out.covered.add(stage)
            continue
        raw = _chain_waypoints(problem, chain, deadline)
        if raw is None:
            continue
        out.covered.add(stage)
        out.offer(stage, len(chain) - 1, _timed(problem, params, raw, memo, deadline))
    if problem.obstacles and out.best is None:  # nothing yet: before the pebble-graph roadmap
        _free_space(problem, out, bound, deadline, rng)
    return out


#: The one-step try's assignment and test [s per pair of robots], about 1.3 s at 4000 robots.
_AT_ONCE_S_PER_PAIR = 1e-7


def _at_once(problem: Problem, pos: np.ndarray, nxt: np.ndarray, deadline: float = float("inf")) -> np.ndarray | None:
    """Every robot at once from ``pos`` straight to ``nxt`` along the minimum
    sum-of-squares assignment: the placement it reaches (robot ``i`` at row
    ``i``) when that step is exactly clear, else ``None``; also ``None``, not
    remembered, when the assignment would not end before ``deadline``
    (:data:`_AT_ONCE_S_PER_PAIR`).  Remembered per problem and pair of
    placements (the one-step try is also the first leg of the sequenced
    stage's chain)."""
    from scipy.spatial.distance import cdist

    pos = np.ascontiguousarray(pos, float)
    nxt = np.ascontiguousarray(nxt, float)
    key = (pos.tobytes(), nxt.tobytes())
    memo = problem.__dict__.setdefault("_at_once", {})
    if key not in memo:
        if time.perf_counter() + _AT_ONCE_S_PER_PAIR * len(pos) * len(nxt) > deadline:
            return None
        # the same squares as ((pos[:, None] - nxt[None]) ** 2).sum(axis=2), bit for bit, without
        # the (m, m, 2) array (256 MB at 4000 robots)
        _, cols = linear_sum_assignment(cdist(pos, nxt, "sqeuclidean"))
        memo[key] = nxt[cols] if step_clear(problem, pos, nxt[cols]) else None
    return memo[key]


def _chain_waypoints(problem: Problem, chain: list[np.ndarray], deadline: float = float("inf")) -> list[np.ndarray] | None:
    """Raw waypoints from ``chain[0]`` (the start) through each whole placement in turn.

    Each leg is, in this order of preference: every robot at once,
    straight along the minimum sum-of-squares assignment, when that step
    is clear (:func:`_at_once`: a connection in the paper's sense; between
    CAPT-spaced placements it is clear of the other robots by
    construction); or :func:`planner.connect.sequenced_moves` with groups,
    straight or, among obstacles, around them when straight moves fail.
    ``None`` when a leg has neither.
    """
    pos = np.asarray(chain[0], float)
    raw = [pos]
    bends = (False, True) if problem.obstacles else (False,)
    for nxt in chain[1:]:
        if time.perf_counter() > deadline:
            return None
        end = _at_once(problem, pos, nxt, deadline)
        if end is not None:
            pos = end
            raw.append(pos)
            continue
        for bent in bends:
            try:
                seq = sequenced_moves(problem, pos, np.asarray(nxt, float), bent, groups=True, deadline=deadline)
            except Late:
                return None
            if seq is not None:
                break
        else:
            return None
        steps = seq.waypoints(pos, seq.rows)
        raw += steps
        if steps:
            pos = steps[-1]
    return raw


def _same_set(a: np.ndarray, b: np.ndarray) -> bool:
    """Whether two placements are the same set of points."""
    return bool(np.array_equal(a[np.lexsort(a.T[::-1])], b[np.lexsort(b.T[::-1])]))


def _fill_stats(stats: PlanStats, plan: Plan, clearance: float):
    stats.found = True
    stats.extra["feasible"] = True
    stats.steps = plan.steps
    stats.makespan_s = plan.makespan
    stats.path_length = plan.path_length
    stats.min_clearance = clearance
