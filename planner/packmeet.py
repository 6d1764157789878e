"""Packings in roomy worlds: both placements flowed onto one square lattice, routed between on it.

:mod:`planner.dense` flows the target placement onto a lattice's sites and then the
start placement onto exactly the sites the target took.  In a box that a lattice
about fills this works; where the lattice has many more sites than robots (a hall
with pillars, an arena of a ROS map, robots small against it) the second flow
often stalls: the last robots must reach holes scattered among robots already
seated.  Here instead:

1. **Lattices** (:func:`meet_lattices`): square grids of spacing
   ``SLACK * separation`` shifted by thirds of it along both axes, their points
   clear of walls and obstacles; the ones with the most points, when they hold at
   least ``MIN_ROOM * m``.
2. **Flows**: the start and the target placements are each flowed onto the lattice
   (:func:`planner.dense.flow`: every step exactly checked, robots and obstacles),
   ending on site sets ``Cs`` and ``Ct``.
3. **Routing**: ``Cs`` to ``Ct`` on the lattice's grid graph by the grid stage
   (:func:`planner.gridstage.grid_plan`, exactly checked step by step), which
   moves whole rows of robots in long straight steps.
4. **Plan**: the start's flow, the routing, the target's flow reversed (a reversed
   step is clear when the step is), its rows matched where they meet.

The slack keeps pushes able to settle robots on sites (pairs are pushed to the
sites' spacing at most, :func:`planner.dense.flow`).  Measured on 2026-12-08:
250 robots of radius 0.2 among six pillars in a 10 x 10 hall (32 % covered), the
flows take 1.9 and 2.0 s and the routing 2.3 s, where the target-first flow
planned 9.3 s.
"""

from __future__ import annotations

import math
import time

import numpy as np

from .dense import BEST_OF_SHARE, FLOW_SETTINGS, _better, _joined, flow
from .plan import Plan
from .problem import Problem

__all__ = ["FLOW_STEPS", "MIN_ROOM", "SLACK", "meet_lattices", "meet_plan", "meet_waypoints"]

SLACK = 1.02  #: the lattice's spacing over the separation
MIN_ROOM = 1.1  #: the least number of lattice points per robot (the routing needs free sites)
#: Steps a flow onto the lattice may take: those that landed took at most 24 (Nav2's maps,
#: 30 to 600 robots), those that stall run to the cap (900 robots: 0.07 s a step)
FLOW_STEPS = 60
_SHIFTS = (0.0, 1 / 3, 2 / 3)  # shifts of the lattice along each axis, in spacings
_KEEP = 2  # lattices kept, the roomiest first


def meet_lattices(problem: Problem, deadline: float = math.inf) -> list[tuple[np.ndarray, float, np.ndarray]]:
    """``(offset, spacing, points)`` of the square lattices of step 1 (module docstring),
    the roomiest first: ``points`` are ``offset + spacing * integers`` clear of every
    wall and obstacle; those tested before ``deadline``."""
    c = problem.separation * SLACK
    lo = problem.clearance
    if problem.width <= 2 * lo or problem.height <= 2 * lo:
        return []
    found = []
    for fx in _SHIFTS:
        for fy in _SHIFTS:
            if time.perf_counter() > deadline:
                break
            x0, y0 = lo + fx * c, lo + fy * c
            gx = x0 + c * np.arange(max(0, int((problem.width - lo - x0) // c) + 1))
            gy = y0 + c * np.arange(max(0, int((problem.height - lo - y0) // c) + 1))
            pts = np.stack(np.meshgrid(gx, gy, indexing="ij"), axis=-1).reshape(-1, 2)
            pts = pts[problem.env.points_clear(pts, problem.clearance)]
            if len(pts) >= MIN_ROOM * problem.m:
                found.append((np.array([x0 % c, y0 % c]), c, pts))
    found.sort(key=lambda f: -len(f[2]))
    return found[:_KEEP]


def meet_waypoints(problem: Problem, lattice: tuple[np.ndarray, float, np.ndarray], deadline: float,
                   rng: np.random.Generator, h: float, eps: float) -> np.ndarray | None:
    """Raw waypoints of steps 2 to 4 (module docstring) on one lattice, or ``None``
    (a flow stalled, the routing found nothing, or ``deadline``)."""
    from .gridstage import grid_plan

    offset, c, sites = lattice
    ours = flow(problem, problem.start, sites, deadline, rng, h, eps, FLOW_STEPS)
    theirs = None if ours is None else flow(problem, problem.target, sites, deadline, rng, h, eps, FLOW_STEPS)
    if theirs is None:
        return None
    seated = Problem(problem.width, problem.height, problem.obstacles, problem.radius, problem.margin,
                     ours[-1], theirs[-1], max_speed=problem.max_speed, max_accel=problem.max_accel)
    routed = grid_plan(seated, deadline, (offset, c), rng)
    if routed is None:
        return None
    w = np.asarray(routed[0], float)
    if not np.array_equal(w[0], ours[-1]):  # rows as the flow left them (never expected otherwise)
        return None
    joined = _joined(list(ours) + list(w[1:]), list(theirs))
    return None if joined is None else np.asarray(joined)


def meet_plan(problem: Problem, time_limit: float, rng: np.random.Generator,
              deadline: float | None = None) -> Plan | None:
    """The shortest exactly validated plan of :func:`meet_waypoints` over the first two
    :data:`planner.dense.FLOW_SETTINGS` and the lattices of :func:`meet_lattices`, or
    ``None``; after the first plan, tries go on within
    :data:`planner.dense.BEST_OF_SHARE` of the limit."""
    t0 = time.perf_counter()
    deadline = min(t0 + time_limit, deadline if deadline is not None else math.inf)
    best = None
    lattices = meet_lattices(problem, deadline)
    for h, eps in FLOW_SETTINGS[:2]:
        for lattice in lattices:
            now = time.perf_counter()
            if now > deadline or (best is not None and now > t0 + BEST_OF_SHARE * time_limit):
                return best
            best = _better(problem, meet_waypoints(problem, lattice, deadline, rng, h, eps), best, deadline) or best
    return best
