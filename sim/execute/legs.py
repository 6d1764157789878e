"""Chained targets: one plan that reaches every target of a scenario in turn.

A scenario's ``targets: [...]`` is a list of formations.  :func:`plan_legs`
plans each *leg* with :func:`planner.plan` from where the previous one
ended (the robots' actual order: the problem is unlabeled), appends a rest
of ``hold`` seconds (a step in which nobody moves) and concatenates the
legs into one :class:`planner.Plan`, which is then checked exactly, as a
whole, against the run's problem (start -> last target).  The physics runs
it in one go and the video shows the current leg's target.

Each leg gets the planner's full ``time_limit``.  The stats add up the
legs' planning times, graphs, connections and lower bounds (a chain must
reach every target in order, so the sum of the legs' bounds, plus the
rests, bounds the whole); ``extra["legs"]`` lists each leg.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from planner import NoPlanFound, Plan, PlanStats, check_plan, plan

__all__ = ["plan_legs"]


def plan_legs(problem, targets, params, rng: np.random.Generator, holds=(), labels=()):
    """Plan ``problem.start`` -> ``targets[0]`` -> ... -> ``targets[-1]`` as one plan.

    problem: the run's problem (its target is ``targets[-1]``).
    targets: the target placements ``(m, 2)`` in order.
    holds: seconds of rest after each leg (default none).
    labels: a name for each leg in messages and stats (default ``leg k``).
    Returns ``(plan, stats, leg_times)``: ``leg_times[k]`` is when leg ``k``
    starts [s] and the last entry is the plan's end, so leg ``k`` runs over
    ``[leg_times[k], leg_times[k + 1])``, its rest included.
    Raises :class:`planner.NoPlanFound` naming the leg that failed.
    A single target without rest is exactly ``planner.plan(problem, params, rng)``.
    """
    targets = [np.asarray(t, float) for t in targets] or [problem.target]
    n = len(targets)
    holds = [float(h) for h in holds] + [0.0] * (n - len(holds))
    labels = [str(x) for x in labels] + [f"leg {k + 1}" for k in range(len(labels), n)]
    if n == 1 and holds[0] <= 0:
        result, stats = plan(problem, params, rng)
        return result, stats, np.array([0.0, result.makespan])
    current = problem.start
    waypoints = [current[None]]
    durations: list[np.ndarray] = []
    total = PlanStats(found=True, makespan_lower_bound_s=0.0, path_length_lower_bound=0.0)
    legs = []
    times = [0.0]
    for k, (target, hold, label) in enumerate(zip(targets, holds, labels)):
        leg = replace(problem, start=current, target=target)
        try:
            result, stats = plan(leg, params, rng)
        except NoPlanFound as exc:
            _add(total, exc.stats)
            total.found = False
            total.extra["legs"] = legs
            raise NoPlanFound(f"leg {k + 1} of {n} ({label}): {exc}", total) from None
        _add(total, stats)
        waypoints.append(result.waypoints[1:])
        durations.append(result.durations)
        if hold > 0:
            waypoints.append(result.end[None])
            durations.append(np.array([hold]))
        legs.append({"target": label, "steps": result.steps, "makespan_s": result.makespan,
                     "hold_s": hold, "planning_time_s": stats.planning_time_s,
                     "min_clearance": stats.min_clearance, **({"direct": stats.extra["direct"]}
                                                              if "direct" in stats.extra else {})})
        times.append(times[-1] + result.makespan + hold)
        total.makespan_lower_bound_s += stats.makespan_lower_bound_s + hold
        total.path_length_lower_bound += stats.path_length_lower_bound
        current = result.end
    chained = Plan(problem.radius, problem.margin, np.concatenate(durations), np.concatenate(waypoints),
                   problem.max_speed, problem.max_accel)
    clearance = check_plan(problem, chained)
    total.steps = chained.steps
    total.makespan_s = chained.makespan
    total.path_length = chained.path_length
    total.min_clearance = clearance.value
    total.extra["legs"] = legs
    chained = Plan(chained.radius, chained.margin, chained.durations, chained.waypoints,
                   chained.max_speed, chained.max_accel, total)
    return chained, total, np.array(times)


def _add(total: PlanStats, stats: PlanStats) -> None:
    total.planning_time_s += stats.planning_time_s
    total.g = max(total.g, stats.g)
    total.q = max(total.q, stats.q)
    total.graphs += stats.graphs
    total.connections += stats.connections
