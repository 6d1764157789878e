"""Online recovery: stop, plan again from where the robots are, go on.

With ``sim.recovery.replan`` the executor (:func:`sim.execute`)
watches every recorded sample.  When a working robot's tracking error
exceeds ``recovery.trigger``, or a robot fails, it runs this sequence.
With a filter (:mod:`sim.execute.estimate`) it sees only the estimate: the
estimated error, counted only while it grows (an error the controller is
already closing does not replan), and a failure ``sensing.failure_delay``
seconds after it happens.  A failure is always answered; tracking-error
replans are limited to ``recovery.max_replans``, and one refused for that is
named in the report (``budget_exhausted_at``) and fails the run unless
``recovery.on_budget`` is ``continue``.

1. **Brake.**  Every working robot's reference becomes a stop profile
   (:class:`StopReference`): from the state its controller last measured, it
   decelerates along its velocity at half the force limit
   (``0.5 * force_limit / mass``, leaving the other half to the feedback)
   until it stands still.  The controller tracks that profile like any
   reference, with the same rate, latency and noise.
2. **Stand still** for :data:`SETTLE` seconds, then for :data:`AVERAGE`
   seconds more while every controller measurement is averaged: the new
   plan starts from the mean measured positions (noise shrinks with the
   square root of the number of updates).  Simulated time runs during both
   (pushes can still come), and that is all the time the replan takes in
   the simulation: the wall-clock planning time is reported but does not
   count as simulated time, so a run does not depend on the machine.
3. **Plan** (:func:`replan`) from the measured positions of the working
   robots to the target placement, with every failed robot a static disc
   obstacle (:class:`planner.Circle` of the robot radius at its measured
   position, so a working robot's centre keeps ``2 r + margin`` from it).
   With ``k`` failed robots, ``m - k`` robots fill ``m - k`` targets
   (:func:`drop_targets` says which ``k`` stay empty; where a failed robot
   blocks more targets than that, as many working robots park where they
   stand, :func:`parking`).  Where the measured positions are closer than
   the separation or the clearance, a short separation step
   (:func:`separation_step`) comes first, checked exactly.
4. **Go on** with the new plan from the replan time; the run ends
   ``settle_time`` after it.  A replan that finds no plan ends the run there,
   robots at rest, and the report says why.

The planner is called with the scenario's planner settings, but with ``g``
and ``q`` on auto (anytime) and ``recovery.replan_time_limit``; its generator is the
run's replan stream (:func:`sim.execute.realism.streams`).
"""

from __future__ import annotations

import time as _time
from dataclasses import dataclass, replace

import numpy as np

from planner import Circle, NoPlanFound, Plan, PlannerParams, Problem, ProblemError
from planner import plan as plan_motion
from planner.geometry import closest_approach
from planner.problem import check_placement

from .contacts import static_clearances

__all__ = [
    "AVERAGE",
    "SETTLE",
    "NewPlan",
    "Replan",
    "RecoveryFailed",
    "StopReference",
    "drop_targets",
    "parking",
    "replan",
    "replan_world",
    "separation_step",
]

SETTLE = 0.2
"""Seconds the robots stand still after braking before the measurements are averaged."""
AVERAGE = 0.2
"""Seconds of controller measurements averaged into the replan's start positions."""

_SLACK = 1e-6  # [units] what a separated placement keeps above the separation
_SEPARATION_ROUNDS = 200


class RecoveryFailed(RuntimeError):
    """No way on from the measured state; ``str()`` says why in one line."""


@dataclass(frozen=True)
class Replan:
    """One replan as it happened.

    time: when the trigger fired [s]; planned_at: when the new plan started
    (after braking and standing still) [s].  reason: what fired it.
    robots: the working robots planned for; failed: the failed robots
    (static discs in the plan); dropped_targets: indices of the targets
    left empty; parked: places where working robots park instead, when
    failed robots block more targets than they leave empty.
    separation_step: whether a separation step came first.
    found, steps, makespan_s, min_clearance: the new plan (the separation
    step included), or ``found = False`` and ``error``.
    planning_time_s: wall-clock time of planning (not simulated time).
    """

    time: float
    planned_at: float
    reason: str
    robots: int
    failed: tuple[int, ...]
    dropped_targets: tuple[int, ...]
    separation_step: bool
    found: bool
    steps: int
    makespan_s: float
    min_clearance: float | None
    planning_time_s: float
    error: str = ""
    parked: tuple[tuple[float, float], ...] = ()

    def to_dict(self) -> dict:
        d = {
            "time": self.time,
            "planned_at": self.planned_at,
            "reason": self.reason,
            "robots": self.robots,
            "failed": list(self.failed),
            "dropped_targets": list(self.dropped_targets),
            "parked": [list(p) for p in self.parked],
            "separation_step": self.separation_step,
            "found": self.found,
            "steps": self.steps,
            "makespan_s": self.makespan_s,
            "min_clearance": self.min_clearance,
            "planning_time_s": self.planning_time_s,
        }
        if self.error:
            d["error"] = self.error
        return d


class StopReference:
    """Each robot decelerates from ``(pos, vel)`` at time ``t0`` at ``decel`` until at rest.

    ``sample`` has the interface of :meth:`planner.Plan.sample` (absolute
    times).  ``end`` is when the last robot stops [s].
    """

    def __init__(self, t0: float, pos: np.ndarray, vel: np.ndarray, decel: float):
        self.t0 = float(t0)
        self.pos = np.array(pos, float)
        self.vel = np.array(vel, float)
        speed = np.sqrt(np.einsum("ij,ij->i", self.vel, self.vel))
        self.dir = np.where(speed[:, None] > 0, self.vel / np.where(speed > 0, speed, 1.0)[:, None], 0.0)
        self.decel = float(decel)
        self.stop = speed / self.decel  # (m,) time each robot needs to stop
        self.end = self.t0 + float(self.stop.max(initial=0.0))

    def at(self, t: float):
        """``(pos, vel, acc)`` ``(m, 2)`` each at time ``t``."""
        pos, vel, acc = self.sample([t])
        return pos[0], vel[0], acc[0]

    def sample(self, ts):
        ts = np.asarray(ts, float).reshape(-1)
        tau = np.clip(ts[:, None] - self.t0, 0.0, None)  # (T, 1)
        moving = tau < self.stop[None, :]  # (T, m)
        tau = np.minimum(tau, self.stop[None, :])
        a = self.decel * self.dir  # (m, 2)
        pos = self.pos[None] + self.vel[None] * tau[..., None] - 0.5 * a[None] * (tau * tau)[..., None]
        vel = np.where(moving[..., None], self.vel[None] - a[None] * tau[..., None], 0.0)
        acc = np.where(moving[..., None], -a[None], 0.0)
        return pos, vel, acc


def drop_targets(targets: np.ndarray, failed: np.ndarray, separation: float) -> tuple[np.ndarray, np.ndarray]:
    """Which targets stay empty when ``k = len(failed)`` robots failed: ``(kept, dropped)``.

    A target closer than ``separation`` (``2 r + margin``) to a failed
    robot is blocked (it cannot be filled) and is always dropped.  When
    fewer than ``k`` are blocked, the others dropped are those a
    minimum-cost assignment of the failed robots to the targets gives them
    (by distance, blocked targets at cost 0, so every blocked target is
    among them): a failed robot takes the target it blocks, or else the one
    nearest it in the assignment.  When more than ``k`` are blocked, all
    blocked ones are dropped and ``len(kept) < m - k``: some working robots
    have to park (:func:`replan`).
    """
    from scipy.optimize import linear_sum_assignment

    targets = np.asarray(targets, float).reshape(-1, 2)
    failed = np.asarray(failed, float).reshape(-1, 2)
    k = len(failed)
    idx = np.arange(len(targets))
    if k == 0:
        return idx, idx[:0]
    d = np.linalg.norm(failed[:, None] - targets[None], axis=2)  # (k, n)
    blocked = (d < separation - 1e-9).any(axis=0)
    if int(blocked.sum()) >= k:
        return idx[~blocked], idx[blocked]
    cost = np.where(blocked[None], 0.0, d)
    _, cols = linear_sum_assignment(cost)
    dropped = np.sort(cols)
    kept = np.setdiff1d(idx, dropped)
    return kept, dropped


def parking(start: np.ndarray, targets: np.ndarray, count: int, separation: float) -> np.ndarray:
    """``count`` places for robots that have no target left: ``(count, 2)``.

    The places are the current positions of the working robots that are
    at least ``separation`` from every target, farthest from the targets
    first (a robot parked there is out of the others' way; any robot may
    end there, the problem being unlabeled).  ``start`` must be separated
    and clear.  Raises :class:`RecoveryFailed` when there are too few.
    """
    start = np.asarray(start, float).reshape(-1, 2)
    if count <= 0:
        return np.zeros((0, 2))
    targets = np.asarray(targets, float).reshape(-1, 2)
    if len(targets):
        near = np.linalg.norm(start[:, None] - targets[None], axis=2).min(axis=1)
    else:
        near = np.full(len(start), np.inf)
    ok = np.flatnonzero(near >= separation + 1e-9)
    if len(ok) < count:
        raise RecoveryFailed(f"{count} working robots have no target left and only {len(ok)} can park "
                             f"clear of the other targets")
    order = ok[np.argsort(-near[ok], kind="stable")]
    return start[np.sort(order[:count])]


def _signed_clearance(problem: Problem, pts: np.ndarray) -> np.ndarray:
    """Signed distance of centres to the nearest obstacle or wall (negative inside)."""
    return static_clearances(problem.env, pts, len(problem.obstacles)).min(axis=1)


def separation_step(problem: Problem, pos: np.ndarray) -> np.ndarray | None:
    """Positions near ``pos`` that are separated and clear in ``problem``, or ``None``.

    Pairs closer than the separation are pushed apart along their centre
    line and robots too near an obstacle or wall are pushed out along the
    clearance gradient, a little past the limits, until nothing is left to
    fix.  The straight step ``pos -> result`` (all robots at once, one
    time scaling) is then checked exactly: no pair comes closer than it was
    at the start or than the separation, and no robot comes closer to the
    world than it was or than the clearance.  ``None`` when the pushing does
    not settle or the step fails the check.
    """
    from scipy.spatial import cKDTree

    p0 = np.asarray(pos, float).reshape(-1, 2)
    sep, clear = problem.separation, problem.clearance
    slack = _SLACK * max(1.0, problem.radius)
    p = p0.copy()
    h = 1e-6 * max(1.0, problem.radius)
    for _ in range(_SEPARATION_ROUNDS):
        fixed = True
        if len(p) > 1:
            pairs = cKDTree(p).query_pairs(sep + slack, output_type="ndarray")
            if len(pairs):
                fixed = False
                i, j = pairs[:, 0], pairs[:, 1]
                d = p[j] - p[i]
                dist = np.sqrt(np.einsum("ij,ij->i", d, d))
                # Coincident centres: split them along a fixed direction.
                unit = np.where(dist[:, None] > 1e-12, d / np.maximum(dist, 1e-12)[:, None], [1.0, 0.0])
                shift = (0.5 * (sep + 2 * slack - dist))[:, None] * unit
                np.add.at(p, i, -shift)
                np.add.at(p, j, shift)
        c = _signed_clearance(problem, p)
        bad = np.flatnonzero(c < clear + slack)
        if len(bad):
            fixed = False
            q = p[bad]
            gx = (_signed_clearance(problem, q + [h, 0.0]) - _signed_clearance(problem, q - [h, 0.0])) / (2 * h)
            gy = (_signed_clearance(problem, q + [0.0, h]) - _signed_clearance(problem, q - [0.0, h])) / (2 * h)
            g = np.stack([gx, gy], axis=1)
            gn = np.sqrt(np.einsum("ij,ij->i", g, g))
            if np.any(gn < 1e-6):
                return None  # on a ridge of the clearance: no direction out
            p[bad] = q + ((clear + 2 * slack - c[bad]) / gn)[:, None] * g / gn[:, None]
        if fixed:
            break
    else:
        return None
    if not _step_is_safe(problem, p0, p):
        return None
    return p


def _step_is_safe(problem: Problem, a: np.ndarray, b: np.ndarray) -> bool:
    """The exact check of :func:`separation_step`'s step ``a -> b``."""
    from scipy.spatial import cKDTree

    tol = 1e-9
    sep = problem.separation
    env = problem.env
    if len(a) > 1:
        reach = float(np.linalg.norm(b - a, axis=1).max())
        pairs = cKDTree(a).query_pairs(sep + 2 * reach + tol, output_type="ndarray")
        if len(pairs):
            i, j = pairs[:, 0], pairs[:, 1]
            start = np.linalg.norm(a[i] - a[j], axis=1)
            low = closest_approach(a[i], b[i], a[j], b[j])
            if np.any(low < np.minimum(start, sep) - tol):
                return False
    start = env.point_clearance(a)
    low = env.segment_clearance(a, b)
    return bool(np.all(low >= np.minimum(start, problem.clearance) - tol))


@dataclass(frozen=True, eq=False)
class NewPlan:
    """What :func:`replan` found.

    plan: moves the working robots (in the order of ``start``), a separation
    step first when ``separated``.  kept, dropped: indices of ``targets``.
    parked: ``(p, 2)`` parking places that replace blocked targets.
    targets: ``(m - k, 2)`` where the working robots go (kept targets,
    then parking places).  planning_time_s: wall-clock time.
    """

    plan: Plan
    kept: np.ndarray
    dropped: np.ndarray
    parked: np.ndarray
    targets: np.ndarray
    separated: bool
    planning_time_s: float


def replan(base: Problem, start: np.ndarray, failed: np.ndarray, targets: np.ndarray,
           params: PlannerParams, time_limit: float, rng: np.random.Generator) -> NewPlan:
    """Plan for the working robots from ``start`` to ``m - k`` of ``targets``.

    ``base`` gives the world, radius, margin and limits; ``failed`` holds the
    ``k`` failed robots' positions (static disc obstacles).  The steps:
    drop ``k`` targets (:func:`drop_targets`); separate the start
    (:func:`separation_step`) where it is closer than the separation or
    clearance; where failed robots block more than ``k`` targets, park as
    many working robots as needed (:func:`parking`); plan.  Raises
    :class:`RecoveryFailed` with the reason when there is no way on.
    """
    t0 = _time.perf_counter()
    extra = float(getattr(params, "margin_extra", 0.0) or 0.0)
    obstacles = tuple(base.obstacles) + tuple(Circle((float(x), float(y)), base.radius) for x, y in failed)
    sep = 2 * base.radius + base.margin + extra
    targets = np.asarray(targets, float).reshape(-1, 2)
    kept, dropped = drop_targets(targets, failed, sep)
    start = np.asarray(start, float).reshape(-1, 2)
    world = Problem(base.width, base.height, obstacles, base.radius, base.margin + extra, start, start,
                    base.max_speed, base.max_accel)
    first = start
    separated = False
    try:
        check_placement(world, start, "start")
    except ProblemError as exc:
        moved = separation_step(world, start)
        if moved is None:
            raise RecoveryFailed(f"no separation step from the measured positions ({exc})") from None
        separated = True
        first = moved
    parked = parking(first, targets[kept], len(start) - len(kept), sep)
    goal = np.concatenate([targets[kept], parked])
    try:
        check_placement(world, goal, "target")
    except ProblemError as exc:
        raise RecoveryFailed(f"the targets do not fit around the failed robots: {exc}") from None
    # The planner gets the real margin; margin_extra inflates it inside.
    problem = Problem(base.width, base.height, obstacles, base.radius, base.margin, first, goal,
                      base.max_speed, base.max_accel)
    settings = replace(params, g=None, q=None, time_limit=float(time_limit))
    try:
        result, _ = plan_motion(problem, settings, rng)
    except (NoPlanFound, ProblemError) as exc:
        raise RecoveryFailed(f"no plan: {exc}") from None
    if separated:
        step = Plan.from_waypoints(np.stack([start, first]), base.radius, base.margin,
                                   base.max_speed, base.max_accel)
        result = Plan(base.radius, base.margin, np.concatenate([step.durations, result.durations]),
                      np.concatenate([start[None], result.waypoints]),
                      base.max_speed, base.max_accel, result.stats)
    return NewPlan(result, kept, dropped, parked, goal, separated, _time.perf_counter() - t0)


def replan_world(problem: Problem, fixed: np.ndarray, start: np.ndarray, targets: np.ndarray) -> Problem:
    """The replan's world (failed robots as discs) for measuring the new plan's exact clearance."""
    obstacles = tuple(problem.obstacles) + tuple(Circle((float(x), float(y)), problem.radius) for x, y in fixed)
    return Problem(problem.width, problem.height, obstacles, problem.radius, problem.margin, start, targets,
                   problem.max_speed, problem.max_accel)
