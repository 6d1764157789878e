"""The door stage: a crowd through a passage one robot wide, in trains.

A door that lets one robot through at a time (a cut of :mod:`planner.cutbound`
whose free part is narrower than the separation) bounds the makespan by
about one robot per ``separation / max_speed``.  The one-at-a-time stages
need a rest-to-rest step per robot and a grid routing loses a step each time
a robot turns into the queue behind another (on a grid finer than
``sqrt(2)`` separations that is not safe, see :mod:`planner.gridstage`).
This stage moves the robots through in *trains*: a row of ``k`` robots on
the line through the door, one separation-and-a-hair apart, moves in one
straight step of ``(k + n) c`` (``n`` grid cells inside the passage) to a
row beyond it.  A long step averages ``8 / 15`` of the speed limit (the
minimum-jerk scaling), so a train costs about ``1.9`` times the cut's
interval per robot; the refilling step is shared by ``k`` robots.

1. **Frame.**  A square grid of spacing ``c`` (a hair over the
   separation) in the frame of the cut: axis ``u`` across the cut (from the
   starts' side to the targets'), axis ``v`` along it, row 0 on the line
   through the middle of the cut (in a door at the feasibility limit, the
   only line a robot can take).  Vertices are the exactly clear points,
   edges the exactly clear 4-neighbour segments (:func:`planner.grid.grid_graph`).
2. **Blocks.**  On each side a block of ``k`` columns next to the door:
   row 0 (the *queue*) and rows above and below it, every cell a vertex and
   every edge inside it clear.  The robots snap onto the grid
   (:func:`planner.lattice.snap`, exact rounds), the starts' side is routed
   into its block (TSWAP, :func:`planner.tswap.tswap`, with the grid's
   turn rule) and the targets' side is routed out of its block at the end.
3. **Trains.**  While robots are left on the starts' side: the queue row
   moves through the door to the other side's queue row (one translation:
   the train keeps its spacing, and every other robot is at least a row,
   ``c``, from the line); then one step refills the queue by moving one half
   of the block (the rows above, or those below) one row towards it, while
   on the other side the arrived row and one half move one row away from the
   line, which empties the other queue.  Translations keep the spacing
   within a half, a half and the rest of its block stay a row apart, and the
   wall keeps the two sides more than ``2 (radius + margin)`` apart.

Each step is also checked by the exact closest-approach kernel
(:func:`planner.gridstage.step_separated`), and the plan by the validator.
``None`` whenever a precondition fails: no single-file cut that every robot
must cross, a queue line that is not clear through the door, no room for
the blocks, or a routing that stalls.
"""

from __future__ import annotations

import math
import time

import numpy as np

from .grid import Lattice, grid_graph
from .problem import Problem

__all__ = ["DOOR_MIN_ROBOTS", "door_plan", "door_waypoints"]

#: Fewer robots than this go through the door with the other stages.
DOOR_MIN_ROBOTS = 20
_MAX_ENTRIES = 10_000_000  # robots x grid vertices (the routing's distance fields)
_MAX_K = 60  # train length cap [robots]
_TOL = 1e-10  # below the validator's 1e-9


def _door_frame(problem: Problem, deadline: float):
    """``(origin, u, v)`` of the single-file cut every robot must cross, or ``None``."""
    from .cutbound import cuts

    try:
        found = cuts(problem, deadline)
    except TimeoutError:
        return None
    found = [x for x in found if x.k == problem.m and math.isfinite(x.bound)]
    if not found:
        return None
    cut = max(found, key=lambda x: x.bound)
    p, q = np.asarray(cut.p, float), np.asarray(cut.q, float)
    v = (q - p) / np.linalg.norm(q - p)
    u = np.array([v[1], -v[0]])
    o = 0.5 * (p + q)
    if float(np.mean((problem.start - o) @ u)) > 0:  # u points from the starts to the targets
        u = -u
    # an axis-aligned cut keeps exact axes (no rounding in the grid points)
    u, v = np.where(np.abs(u) < 1e-12, 0.0, u), np.where(np.abs(v) < 1e-12, 0.0, v)
    if (np.abs(u) == 1.0).any():
        v = np.array([-u[1], u[0]])
    return o, u, v


def _grid(problem: Problem, o, u, v, c: float, shift: float):
    """The grid graph in the cut's frame: ``(lattice, vid (nx, ny), i0, j0)`` (grid
    index ``(i, j)`` is column ``i0 + x``, row ``j0 + y`` of ``vid``), or ``None``."""
    corners = np.array([[0, 0], [problem.width, 0], [0, problem.height], [problem.width, problem.height]], float) - o
    cu, cv = corners @ u, corners @ v
    i0, i1 = math.floor(cu.min() / c - shift), math.ceil(cu.max() / c - shift)
    j0, j1 = math.floor(cv.min() / c), math.ceil(cv.max() / c)
    nx, ny = i1 - i0 + 1, j1 - j0 + 1
    if nx * ny * max(problem.m, 1) > 4 * _MAX_ENTRIES:
        return None
    gi, gj = np.meshgrid(np.arange(i0, i1 + 1) + shift, np.arange(j0, j1 + 1), indexing="ij")
    pts = o + c * (gi.ravel()[:, None] * u + gj.ravel()[:, None] * v)
    # a door exactly at the limit leaves its middle line exactly at the clearance, which
    # rounding in a rotated frame can put a hair below: the validator's tolerance
    lat, _, vid = grid_graph(problem, pts, nx, ny, c, problem.clearance - _TOL)
    if lat.n * problem.m > _MAX_ENTRIES:
        return None
    return lat, vid, i0, j0


class _Side:
    """One side's grid in the cut's frame: vertex lookups by grid index ``(i, j)``, the
    bank column next to the door and how far the blocks reach (see the module)."""

    def __init__(self, problem: Problem, o, u, v, c: float, shift: float, deadline: float):
        self.got = _grid(problem, o, u, v, c, shift)
        self.c, self.shift = c, shift

    def ready(self) -> bool:
        return self.got is not None

    @property
    def lat(self) -> Lattice:
        return self.got[0]

    def v(self, i, j):
        """Vertex ids of grid cells (``-1``: none)."""
        _, vid, i0, j0 = self.got
        i, j = np.asarray(i) - i0, np.asarray(j) - j0
        inside = (i >= 0) & (i < vid.shape[0]) & (j >= 0) & (j < vid.shape[1])
        out = np.full(np.shape(i), -1)
        out[inside] = vid[i[inside], j[inside]]
        return out

    def edge(self, i, j, slot: int) -> bool:
        a = int(self.v(i, j))
        return a >= 0 and self.lat.nbr[a, slot] >= 0

    def bank(self, step: int) -> int | None:
        """The first column from the door's middle towards ``step`` (-1: the starts' side)
        whose row-0 cell has a clear edge to row 1 or -1, along a clear row 0."""
        i = -round(self.shift)
        limit = self.got[1].shape[0]
        for _ in range(limit):
            if self.v(i, 0) < 0:
                return None
            if self.edge(i, 0, 1) or self.edge(i, 0, 3):
                return i
            if not self.edge(i, 0, 0 if step > 0 else 2):
                return None
            i += step
        return None

    def u(self, i) -> float:
        return (i + self.shift) * self.c

    def rows(self, cols: np.ndarray, step: int) -> int:
        """How many rows beyond row 0 (``step`` +1 up, -1 down) the columns ``cols`` keep
        clear: every cell a vertex, every edge down to row 0 clear."""
        n = 0
        slot = 1 if step > 0 else 3
        while all(self.edge(int(i), n * step, slot) for i in cols):
            n += 1
        return n

    def line(self, lo: int, hi: int) -> bool:
        """Row 0 clear from column ``lo`` to ``hi``."""
        return all(self.edge(i, 0, 0) for i in range(lo, hi))


def _layout(a: _Side, b: _Side, ia: int, ib: int, m: int, problem: Problem, above: float = 0.5,
            longest: bool = False):
    """``(k, cells of the starts' block (m, 2), rows up and down on the targets' side)``
    minimising the estimated train time (``longest``: with the longest trains), or
    ``None``.  ``above``: the share of the
    starts on the side of row 0 the rows up are (the block's halves follow it)."""
    from .profile import step_duration

    c = a.c
    gap = b.u(ib) - a.u(ia)  # the door: from the starts' last queue cell to the first beyond
    best = None
    for k in range(1, _MAX_K + 1):
        left, right = np.arange(ia - k + 1, ia + 1), np.arange(ib, ib + k)
        if not (a.line(ia - k + 1, ia) and b.line(ib, ib + k - 1)):
            break
        la, lb = a.rows(left, 1), a.rows(left, -1)
        ra, rb = b.rows(right, 1), b.rows(right, -1)
        nb = -(-m // k)
        if la + lb + 1 < nb or ra + rb + 1 < nb:
            continue
        span = gap + (k - 1) * c
        t = nb * float(step_duration(span, problem.max_speed, problem.max_accel)) + (nb - 1) * float(
            step_duration(c, problem.max_speed, problem.max_accel))
        if best is None or t < best[0] or longest:
            best = (t, k, la, lb, ra, rb)
    if best is None:
        return None
    _, k, la, lb, ra, rb = best
    nb = -(-m // k)
    # balanced halves on the starts' side; the partial row farthest out, nearest the door
    up = min(la, max(nb - 1 - lb, round((nb - 1) * above)))
    down = nb - 1 - up
    cells = []
    for j in [0] + list(range(1, up + 1)) + list(range(-1, -down - 1, -1)):
        cells += [(i, j) for i in range(ia, ia - k, -1)]
    far = up if up >= down else -down
    full = [x for x in cells if x[1] != far]
    partial = [x for x in cells if x[1] == far][: m - len(full)]
    return k, np.array(full + partial), ra, rb


def _trains(cells: np.ndarray, k: int, ia: int, ib: int, ra: int, rb: int, above: float = 0.5):
    """``(grid positions (m, 2), on the targets' side (m,))`` after every train and
    refill step, from ``cells`` (all on the starts' side).  ``above``: the share of the
    targets on the side of row 0 the rows up are (the arrived rows follow it)."""
    pos = np.array(cells, int)
    side = np.zeros(len(pos), bool)  # on the targets' side
    move = ib - (ia - k + 1)  # column offset of a train, from one grid to the other
    out = []
    turn = 0
    while True:
        queue = ~side & (pos[:, 1] == 0)
        if queue.any():
            pos, side = pos.copy(), side.copy()
            pos[queue, 0] += move
            side[queue] = True
            out.append((pos, side))
        if side.all():
            return out
        # refill the starts' queue from one half, empty the other queue into one half
        pos = pos.copy()
        up, down = ~side & (pos[:, 1] > 0), ~side & (pos[:, 1] < 0)
        halves = [h for h in ((up, -1), (down, 1)) if h[0].any()]
        half, dj = halves[turn % len(halves)]
        if not (half & (np.abs(pos[:, 1]) == 1)).any():
            return None
        pos[half, 1] += dj
        room_up = ra - pos[side & (pos[:, 1] > 0), 1].max(initial=0)
        room_down = rb + pos[side & (pos[:, 1] < 0), 1].min(initial=0)
        rows_up = pos[side & (pos[:, 1] > 0), 1].max(initial=0)
        rows_down = -pos[side & (pos[:, 1] < 0), 1].min(initial=0)
        go_up = (rows_up < above * (rows_up + rows_down + 1) and room_up > 0) or room_down <= 0
        if (room_up if go_up else room_down) <= 0:
            return None
        r_half = side & ((pos[:, 1] >= 0) if go_up else (pos[:, 1] <= 0))
        pos[r_half, 1] += 1 if go_up else -1
        out.append((pos, side))
        turn += 1


def _snapped(problem: Problem, o, u, v, c: float, placement: np.ndarray, step: int, deadline: float):
    """``(side grid, snap rounds, vertices, bank column)`` of the first shift along ``u``
    whose grid takes ``placement`` (snap rounds, :func:`planner.lattice.snap`), or ``None``."""
    from .lattice import snap

    for shift in _SHIFTS:
        if time.perf_counter() > deadline:
            return None
        side = _Side(problem, o, u, v, c, shift, deadline)
        if not side.ready():
            return None
        bank = side.bank(step)
        if bank is None:
            continue
        got = snap(problem, side.lat, placement, deadline)
        if got is not None:
            return side, got[0], got[1], bank
    return None


#: Shifts of each side's grid along the line through the door, in cells (dense
#: placements snap onto some and not others).
_SHIFTS = (0.0, 0.5, 0.25, 0.75, 0.125, 0.625, 0.375, 0.875)


def door_waypoints(problem: Problem, deadline: float, c: float | None = None, longest: bool = False,
                   follow: bool = True) -> np.ndarray | None:
    """Raw waypoints ``(K + 1, m, 2)`` of the door stage, or ``None`` (see the module)."""
    from .gridstage import step_separated
    from .tswap import tswap

    if problem.m < 2:
        return None
    frame = _door_frame(problem, deadline)
    if frame is None:
        return None
    o, u, v = frame
    c = problem.separation * (1 + 1e-6) if c is None else c
    got_a = _snapped(problem, o, u, v, c, problem.start, -1, deadline)
    got_b = _snapped(problem, o, u, v, c, problem.target, 1, deadline) if got_a is not None else None
    if got_b is None:
        return None
    a, entry, sv, ia = got_a
    b, leave, tv, ib = got_b
    if b.u(ib) - a.u(ia) < c * (1 - 1e-9):
        return None
    share = (lambda pts: float(np.mean((pts - o) @ v > 0))) if follow else (lambda pts: 0.5)
    lay = _layout(a, b, ia, ib, problem.m, problem, share(problem.start), longest)
    if lay is None:
        return None
    k, cells, ra, rb = lay
    block_v = a.v(cells[:, 0], cells[:, 1])
    if (block_v < 0).any() or time.perf_counter() > deadline:
        return None
    gather = tswap(a.lat, sv, block_v, deadline, turns=False)
    if gather is None:
        return None
    at_block = gather[-1] if gather else sv
    index = {int(x): n for n, x in enumerate(block_v)}
    trains = _trains(cells[[index[int(x)] for x in at_block]], k, ia, ib, ra, rb,
                     share(problem.target))
    if trains is None:
        return None
    end_v = b.v(trains[-1][0][:, 0], trains[-1][0][:, 1])
    if (end_v < 0).any():
        return None
    spread = tswap(b.lat, end_v, tv, deadline, turns=False)
    if spread is None:
        return None
    where = spread[-1] if spread else end_v
    at = np.full(b.lat.n, -1)
    at[where] = np.arange(problem.m)
    robot_of_target = at[tv]
    if (robot_of_target < 0).any():
        return None
    inv = np.empty(problem.m, int)
    inv[robot_of_target] = np.arange(problem.m)
    steps = [problem.start.copy(), *entry]
    steps += [a.lat.points[r] for r in gather]
    for pos, side in trains:
        pts = np.empty((problem.m, 2))
        pts[~side] = a.lat.points[a.v(pos[~side, 0], pos[~side, 1])]
        pts[side] = b.lat.points[b.v(pos[side, 0], pos[side, 1])]
        steps.append(pts)
    steps += [b.lat.points[r] for r in spread]
    back = [problem.target, *leave][::-1]
    steps += [cfg[inv] for cfg in back[1:]]
    raw = np.asarray(steps)
    # the train's way through the door (grid edges cover the rest)
    if not problem.env.segments_clear(a.lat.points[a.v([ia], [0])], b.lat.points[b.v([ib], [0])],
                                      problem.clearance - _TOL)[0]:
        return None
    for p0, p1 in zip(raw[:-1], raw[1:]):
        if time.perf_counter() > deadline:
            return None
        reach = float(np.linalg.norm(p1 - p0, axis=1).max(initial=0.0))
        if reach > 0 and not step_separated(problem, p0, p1, reach * (1 + 1e-9)):
            return None
    return raw


def door_plan(problem: Problem, deadline: float) -> tuple[np.ndarray, int] | None:
    """``(merged waypoints, raw steps)`` of the shortest door-stage plan over two grid
    spacings, with the blocks' halves sized by where the robots are or equal, or
    ``None``.  Tries after the first run while they use under a third of the time left."""
    from .merge import merge_steps
    from .timing import _drop_idle, _makespan

    best = None
    sep = problem.separation
    t0 = time.perf_counter()
    for n, (c, follow) in enumerate(((sep * (1 + 1e-6), True), (sep * (1 + 1e-6), False),
                                     (sep * 1.05, True), (sep * 1.05, False))):
        now = time.perf_counter()
        if now > deadline or (best is not None and (now - t0) / n > (deadline - now) / 3):
            break
        raw = door_waypoints(problem, deadline, c, follow=follow)
        if raw is None:
            continue
        w = merge_steps(problem, _drop_idle(list(raw)), deadline)
        span = _makespan(problem, w)
        if best is None or span < best[2]:
            best = (w, len(raw) - 1, span)
    return None if best is None else best[:2]
