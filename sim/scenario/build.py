"""From a checked scenario to a :class:`planner.Problem`: random obstacles, placements, checks.

Every draw comes from the run's one generator, in a fixed order (see :func:`build_legs`).
"""

from __future__ import annotations

import math

import numpy as np

from planner.formations import place_formation
from planner.geometry import Environment
from planner.problem import Polygon, Problem, ProblemError, check_placement

from .formation_fields import _SCATTER
from .model import FormationSpec, RandomObstacles, Scenario, ScenarioError

__all__ = ["build_legs", "build_problem"]


def _random_obstacles(spec: RandomObstacles, width, height, rng, avoid, clearance):
    """Random convex polygons: vertices at sorted random angles on a circle."""
    gen = np.random.default_rng(spec.seed) if spec.seed is not None else rng
    out = []
    for _ in range(spec.count):
        for _attempt in range(1000):
            diameter = gen.uniform(spec.size[0], spec.size[1])
            k = int(gen.integers(3, 9))
            ang = np.sort(gen.uniform(0, 2 * np.pi, size=k))
            rad = diameter / 2
            c = gen.uniform([rad, rad], [width - rad, height - rad])
            poly = Polygon(c + rad * np.stack([np.cos(ang), np.sin(ang)], axis=1))
            x, y = poly.vertices[:, 0], poly.vertices[:, 1]
            area = 0.5 * abs(float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y)))
            if area < 0.05 * diameter**2:
                continue  # a sliver; draw again
            if len(avoid):
                env = Environment.build(width, height, [poly])
                if np.any(env.point_clearance(avoid) < clearance):
                    continue
            out.append(poly)
            break
        else:
            raise ProblemError("obstacles", "cannot place a random obstacle clear of the explicit points")
    return out


def build_problem(scenario: Scenario, rng: np.random.Generator) -> Problem:
    """Instantiate the scenario: random obstacles, formations, checks.

    The problem's target is the last target (of a chained scenario:
    :func:`build_legs` gives every one).  Raises :class:`ScenarioError`
    (with the file) for placements that do not fit or overlap.
    """
    return build_legs(scenario, rng)[0]


def build_legs(scenario: Scenario, rng: np.random.Generator,
               deadline: float = math.inf) -> tuple[Problem, tuple[np.ndarray, ...]]:
    """The run's problem (start -> last target) and every target placement in order.

    Draws from ``rng`` in a fixed order: random obstacles, then each
    placement from the start on (a single-target scenario draws exactly as
    :func:`build_problem` always has).  A scatter still drawing at
    ``deadline`` (the run's time limit) raises :class:`planner.visible.Late`.
    """
    from .placements import make_shape, uses_rng

    s = scenario
    specs = [("start", s.start)] + ([(f"targets[{i}]", t) for i, t in enumerate(s.targets)] or [("target", s.target)])
    try:
        # Formations are spaced for the margin the planner plans with
        # (planner.margin_extra inflates it), so that they fit it too.
        clearance = s.radius + s.margin + s.planner.margin_extra
        sep = 2 * s.radius + s.margin + s.planner.margin_extra
        explicit = [np.asarray(p.points, float) for _, p in specs if p.points is not None]
        avoid = np.concatenate(explicit) if explicit else np.zeros((0, 2))
        obstacles = []
        for ob in s.obstacles:
            if isinstance(ob, RandomObstacles):
                obstacles.extend(_random_obstacles(ob, s.width, s.height, rng, avoid, clearance))
            else:
                obstacles.append(ob)
        # m discs at the separation pack at best hexagonally: sqrt(3)/2 sep^2
        # each, within the workspace shrunk by the wall clearance.
        need = s.count * (np.sqrt(3) / 2) * sep**2
        have = max(s.width - 2 * clearance + sep, 0) * max(s.height - 2 * clearance + sep, 0)
        if need > have:
            raise ProblemError(
                "robots.count",
                f"{s.count} robots need at least {need:.0f} square units at their separation; "
                f"the {s.width:g} x {s.height:g} workspace offers {have:.0f}",
            )
        shell = Problem(s.width, s.height, tuple(obstacles), s.radius, s.margin, np.zeros((0, 2)), np.zeros((0, 2)))
        # Shapes that do not depend on the generator (letters, lines, rings,
        # text strokes, strokes) are built first, so that one that cannot fit
        # at any rotation fails before any random placement is drawn.
        shapes = {}
        reach = float(np.hypot(s.width - 2 * clearance, s.height - 2 * clearance))
        for key, spec in specs:
            if spec.points is None and spec.formation != _SCATTER and not uses_rng(spec):
                shape = _shape(make_shape, spec, s, sep, rng, key)
                span = float(np.max(np.linalg.norm(shape[:, None] - shape[None], axis=2)))
                if span > reach:
                    raise ProblemError(
                        key,
                        f"formation {spec.describe()} of {s.count} robots spans {span:.3g} and does not fit "
                        f"the {s.width:g} x {s.height:g} workspace at any rotation; lower robots.count",
                    )
                shapes[key] = shape
        placed = []
        for key, spec in specs:
            if spec.points is not None:
                pts = np.asarray(spec.points, float)
                check_placement(shell, pts, f"{key}.points")
            elif spec.formation == _SCATTER:
                from planner.scatter import largest_part, scatter

                if "part" not in shell.__dict__:  # the start and every target share it
                    shell.__dict__["part"] = largest_part(shell)
                pts = scatter(shell.env, s.count, sep, clearance, rng, region=spec.region, field=key,
                              part=shell.__dict__["part"], deadline=deadline)
                check_placement(shell, pts, key)
            else:
                known = shapes.get(key)
                shape = known if known is not None else _shape(make_shape, spec, s, sep, rng, key)
                pts = place_formation(
                    shape,
                    shell.env,
                    clearance,
                    rotation=spec.rotation,
                    center=spec.center,
                    rng=rng,
                    field=key,
                )
                check_placement(shell, pts, key)
            placed.append(pts)
        problem = Problem(
            s.width,
            s.height,
            tuple(obstacles),
            s.radius,
            s.margin,
            placed[0],
            placed[-1],
            max_speed=s.max_speed,
            max_accel=s.max_accel,
        )
        return problem.validate(), tuple(placed[1:])
    except ProblemError as exc:
        raise ScenarioError(s.path, exc.field, exc.reason) from None


def _shape(make_shape, spec: FormationSpec, s: Scenario, sep: float, rng, key: str) -> np.ndarray:
    """The spec's shape at its scale; a sampler's refusal becomes a :class:`ProblemError` on ``key``."""
    from .placements import formation_side

    try:
        side = formation_side(spec, s.width, s.height, s.radius + s.margin)
        return make_shape(spec, s.count, side, sep, rng)
    except ValueError as exc:
        raise ProblemError(f"{key}.formation", str(exc)) from None
