"""The pymunk world of a problem: walls, obstacles and one disc body per robot.

The space has no gravity and no damping (``damping = 1.0`` keeps every
velocity).  Every shape has friction 0 and elasticity 0.  Static geometry
hangs on ``space.static_body``.  The batch functions of pymunk
(:func:`pymunk.batch.get_space_bodies`, :func:`pymunk.batch.set_space_bodies`)
visit the dynamic bodies in the order they were added and then the static
body, so row ``i`` of a batch buffer is robot ``i`` (checked when the world
is built) and one trailing row belongs to the static body.

* Walls: four thick boxes just outside ``[0, W] x [0, H]``; their inner
  faces lie on the wall lines, so a disc that crosses a wall line overlaps
  a box.
* Polygons (convex or not, either winding) are split into convex pieces
  (:func:`convex_pieces`: ear clipping, then merging across diagonals while
  the union stays convex), which cover the polygon exactly.
* Circles are pymunk circles on the static body.

Collision types: :data:`ROBOT`, :data:`OBSTACLE`, :data:`WALL`.
``World.robot_of`` and ``World.obstacle_of`` map a shape to its robot index
and to its obstacle index (``-1`` for a wall piece).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pymunk
import pymunk.batch as _batch

__all__ = ["OBSTACLE", "ROBOT", "WALL", "World", "build_world", "convex_pieces"]

ROBOT = 1
OBSTACLE = 2
WALL = 3

_STATE = _batch.BodyFields.POSITION | _batch.BodyFields.VELOCITY
_FORCE = _batch.BodyFields.FORCE


@dataclass(eq=False)
class World:
    """A built pymunk world and the maps from its shapes back to the problem.

    space: the pymunk space; its dynamic bodies are the robots, in robot order.
    bodies: the robot bodies, ``bodies[i]`` is robot ``i``.
    robot_of: robot shape -> robot index.
    obstacle_of: static shape -> obstacle index (``-1`` for wall pieces).
    forces: ``(m, 2)`` float array, a view of the batch buffer that
        :meth:`apply_forces` writes into the bodies.
    """

    space: pymunk.Space
    bodies: tuple[pymunk.Body, ...]
    robot_of: dict[pymunk.Shape, int]
    obstacle_of: dict[pymunk.Shape, int]
    forces: np.ndarray
    _state_buf: _batch.Buffer
    _force_buf: _batch.Buffer

    @property
    def m(self) -> int:
        return len(self.bodies)

    def state(self) -> np.ndarray:
        """Positions and velocities of all robots as a new ``(m, 4)`` array ``[x, y, vx, vy]``."""
        buf = self._state_buf
        buf.clear()
        _batch.get_space_bodies(self.space, _STATE, buf)
        return np.frombuffer(buf.float_buf(), dtype=np.float64).reshape(-1, 4)[: len(self.bodies)].copy()

    def apply_forces(self) -> None:
        """Set every robot's force to the rows of :attr:`forces`.

        Chipmunk clears forces at the end of each step, so this is called
        before every physics step.
        """
        _batch.set_space_bodies(self.space, _FORCE, self._force_buf)


def build_world(problem, params) -> World:
    """Build the pymunk world of ``problem`` with the robots at ``problem.start``.

    ``params`` supplies the body mass (:class:`sim.scenario.params.SimParams`).  The
    caller may move the bodies before the first step (see
    :func:`sim.execute`, which places them at the plan's start).
    """
    space = pymunk.Space()
    space.gravity = (0.0, 0.0)
    space.damping = 1.0
    # Resting overlap that the solver tolerates; detection is unaffected
    # (any overlap opens a contact), this only limits how deep touching
    # bodies sit in each other once in contact.
    space.collision_slop = 0.01 * float(problem.radius)

    obstacle_of: dict[pymunk.Shape, int] = {}
    static = space.static_body
    for box in _wall_boxes(float(problem.width), float(problem.height)):
        shape = pymunk.Poly(static, [tuple(p) for p in box])
        _surface(shape, WALL)
        obstacle_of[shape] = -1
    for k, ob in enumerate(problem.obstacles):
        if hasattr(ob, "vertices"):
            for piece in convex_pieces(ob.vertices):
                shape = pymunk.Poly(static, [tuple(p) for p in piece])
                _surface(shape, OBSTACLE)
                obstacle_of[shape] = k
        else:
            shape = pymunk.Circle(static, float(ob.radius), offset=tuple(ob.center))
            _surface(shape, OBSTACLE)
            obstacle_of[shape] = k
    space.add(*obstacle_of)

    radius = float(problem.radius)
    mass = float(params.mass)
    moment = pymunk.moment_for_circle(mass, 0.0, radius)
    bodies, robot_of = [], {}
    for i, p in enumerate(np.asarray(problem.start, float)):
        body = pymunk.Body(mass, moment)
        body.position = (float(p[0]), float(p[1]))
        shape = pymunk.Circle(body, radius)
        _surface(shape, ROBOT)
        space.add(body, shape)
        bodies.append(body)
        robot_of[shape] = i

    ids = _batch.Buffer()
    _batch.get_space_bodies(space, _batch.BodyFields.BODY_ID, ids)
    order = np.frombuffer(ids.int_buf(), dtype=np.uintp).tolist()
    robot_ids = [b.id for b in bodies]
    if order[: len(bodies)] != robot_ids or not set(order[len(bodies) :]) <= {static.id}:
        raise RuntimeError("pymunk batch rows are not the robots in order")

    rows = np.zeros((len(order), 2))  # the static body's row stays zero
    force_buf = _batch.Buffer()
    force_buf.set_float_buf(rows)
    forces = rows[: len(bodies)]
    return World(space, tuple(bodies), robot_of, obstacle_of, forces, _batch.Buffer(), force_buf)


def _surface(shape: pymunk.Shape, collision_type: int) -> None:
    shape.friction = 0.0
    shape.elasticity = 0.0
    shape.collision_type = collision_type


def _wall_boxes(width: float, height: float) -> list[np.ndarray]:
    """Four boxes whose inner faces are the lines x=0, x=W, y=0, y=H."""
    t = max(width, height)  # thick enough that nothing tunnels through
    boxes = [
        (-t, -t, 0.0, height + t),  # left
        (width, -t, width + t, height + t),  # right
        (0.0, -t, width, 0.0),  # bottom
        (0.0, height, width, height + t),  # top
    ]
    return [np.array([(x0, y0), (x1, y0), (x1, y1), (x0, y1)]) for x0, y0, x1, y1 in boxes]


# -- convex decomposition -------------------------------------------------------


def _cross(o: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    return float((a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0]))


def _clean_ring(vertices) -> np.ndarray:
    """Counter-clockwise ring without repeated or collinear vertices."""
    v = np.asarray(vertices, float).reshape(-1, 2)
    if len(v) > 1 and np.array_equal(v[0], v[-1]):
        v = v[:-1]
    keep = np.any(v != np.roll(v, 1, axis=0), axis=1)
    v = v[keep] if keep.any() else v[:1]
    x, y = v[:, 0], v[:, 1]
    if float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y)) < 0:
        v = v[::-1]
    scale = max(float(np.ptp(v[:, 0])), float(np.ptp(v[:, 1])), 1e-300)
    eps = 1e-12 * scale * scale
    pts = [p for p in v]
    changed = True
    while changed and len(pts) > 3:
        changed = False
        for i in range(len(pts)):
            a, b, c = pts[i - 1], pts[i], pts[(i + 1) % len(pts)]
            if abs(_cross(a, b, c)) <= eps and np.dot(b - a, c - b) >= 0:
                del pts[i]
                changed = True
                break
    return np.array(pts)


def _in_triangle(p, a, b, c, eps) -> bool:
    """Point in the closed counter-clockwise triangle (a, b, c)."""
    return _cross(a, b, p) >= -eps and _cross(b, c, p) >= -eps and _cross(c, a, p) >= -eps


def _triangulate(v: np.ndarray, eps: float) -> list[list[int]]:
    """Ear clipping of a simple counter-clockwise ring; index triples."""
    idx = list(range(len(v)))
    tris: list[list[int]] = []
    guard = 0
    while len(idx) > 3:
        n = len(idx)
        found = False
        for j in range(n):
            ia, ib, ic = idx[j - 1], idx[j], idx[(j + 1) % n]
            a, b, c = v[ia], v[ib], v[ic]
            if _cross(a, b, c) <= eps:
                continue  # reflex or flat: not an ear
            corners = {tuple(a), tuple(b), tuple(c)}
            blocked = False
            for k in idx:
                if k in (ia, ib, ic) or tuple(v[k]) in corners:
                    continue
                if _in_triangle(v[k], a, b, c, eps):
                    blocked = True
                    break
            if not blocked:
                tris.append([ia, ib, ic])
                del idx[j]
                found = True
                break
        if not found:
            guard += 1
            if guard > 1:
                raise ValueError("polygon is not simple: no ear to clip")
            # Only flat vertices are left to clip; drop the flattest one.
            crosses = [abs(_cross(v[idx[j - 1]], v[idx[j]], v[idx[(j + 1) % n]])) for j in range(n)]
            del idx[int(np.argmin(crosses))]
        else:
            guard = 0
    if len(idx) == 3 and _cross(v[idx[0]], v[idx[1]], v[idx[2]]) > eps:
        tris.append(idx)
    return tris


def _is_convex(v: np.ndarray, ring: list[int], eps: float) -> bool:
    n = len(ring)
    return all(_cross(v[ring[j - 1]], v[ring[j]], v[ring[(j + 1) % n]]) >= -eps for j in range(n))


def _merge(v: np.ndarray, pieces: list[list[int]], eps: float) -> list[list[int]]:
    """Join pieces across shared diagonals while the union stays convex."""
    merged = True
    while merged:
        merged = False
        for p in range(len(pieces)):
            a = pieces[p]
            edges_a = {(a[j], a[(j + 1) % len(a)]): j for j in range(len(a))}
            for q in range(p + 1, len(pieces)):
                b = pieces[q]
                for j in range(len(b)):
                    u, w = b[j], b[(j + 1) % len(b)]
                    if (w, u) not in edges_a:
                        continue
                    ja = edges_a[(w, u)]
                    # a runs ... w -> u ...; b runs ... u -> w ...
                    ra = a[ja + 1 :] + a[: ja + 1]  # starts at u, ends at w
                    rb = b[j + 1 :] + b[: j + 1]  # starts at w, ends at u
                    ring = ra + rb[1:-1]
                    if _is_convex(v, ring, eps):
                        pieces[p] = ring
                        del pieces[q]
                        merged = True
                        break
                if merged:
                    break
            if merged:
                break
    return pieces


def convex_pieces(vertices) -> list[np.ndarray]:
    """Split a simple polygon (either winding) into convex pieces that cover it exactly.

    Returns a list of ``(k, 2)`` counter-clockwise vertex arrays.  A convex
    polygon comes back whole; otherwise ear clipping triangulates it and
    adjacent pieces are merged while their union stays convex (at most
    four times the optimal number of pieces).
    """
    v = _clean_ring(vertices)
    if len(v) < 3:
        raise ValueError(f"polygon needs at least 3 distinct vertices, got {len(v)}")
    scale = max(float(np.ptp(v[:, 0])), float(np.ptp(v[:, 1])))
    eps = 1e-12 * scale * scale
    ring = list(range(len(v)))
    if _is_convex(v, ring, eps):
        return [v]
    pieces = _merge(v, _triangulate(v, eps), eps)
    return [v[p] for p in pieces]
