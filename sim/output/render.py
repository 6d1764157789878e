"""Off-screen drawing with pygame-ce: scenario pictures and video frames.

Drawing is kept apart from the model: :func:`draw_scenario` and
:func:`render_frames` take read-only positions and return ``(H, W, 3)
uint8`` arrays; writing files is :mod:`sim.output.media`'s job.  No window is ever
opened (``SDL_VIDEODRIVER=dummy``).  The surface, its layout, colours and
legend are :mod:`sim.output.canvas`'s; playback timing is :mod:`sim.output.playback`'s.

:func:`render_frames` turns a physics recording (sample times, positions and
contacts) into a :class:`Frames` sequence: frame ``k`` is drawn when it is
asked for, so a video of any length is written with a few frames in memory.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from planner.problem import Circle, Problem

from ..execute.events import SAME_CONTACT_SECONDS
from ..scenario.params import MAX_RENDER_SIZE, RenderParams
from ..words import plural
from .canvas import (
    CONTACT,
    START,
    TARGET,
    TEXT,
    Canvas,
    frame_size,
    label_font,
    robot_colors,
)
from .frames import START_MARK, TARGET_MARK, Frames, _Contacts, _interpolate
from .playback import MAX_VIDEO_SECONDS, frame_times, playback_speedup, timing

__all__ = [
    "CONTACT",
    "START_MARK",
    "TARGET_MARK",
    "MAX_VIDEO_SECONDS",
    "Canvas",
    "Frames",
    "draw_scenario",
    "frame_size",
    "frame_times",
    "playback_speedup",
    "render_frames",
    "robot_colors",
]

_SAME_CONTACT_SECONDS = SAME_CONTACT_SECONDS  # records of one pair this close in time are one contact [sim s]


def draw_scenario(problem: Problem, size: int | None = None, title: str = "") -> np.ndarray:
    """The workspace, obstacles, start (hollow rings) and target (filled discs) as an image.

    size: the longer side [px]; ``None`` picks :func:`sim.output.canvas.frame_size`.
    Starts carry robot indices where the discs are big enough for them.
    """
    legend = [("start", "start (hollow)"), ("target", "target (filled)")]
    cv = Canvas(problem, size, legend=legend)
    s = cv.surface()
    for c in cv.to_px(problem.target):
        cv.disc(s, TARGET, c, cv.r)
    font = label_font(cv.r, problem.m)
    for i, c in enumerate(cv.to_px(problem.start)):
        cv.ring(s, START, c, cv.r, max(2, int(cv.r / 4)))
        if font is not None:
            img = font.render(str(i), True, TEXT)
            s.blit(img, img.get_rect(center=(int(round(c[0])), int(round(c[1])))))
    if title:
        cv.text_line(s, title, 0)
    cv.text_line(s, plural(problem.m, "robot") + (f", {plural(len(problem.obstacles), 'obstacle')}"
                                                  if problem.obstacles else ""), 1)
    return cv.to_array(s)


# ----------------------------------------------------------------------------
# video frames


def render_frames(
    problem: Problem,
    times: np.ndarray,
    positions: np.ndarray,
    contacts: Sequence = (),
    params: RenderParams | None = None,
    *,
    step_times: np.ndarray | None = None,
    title: str = "",
    targets: Sequence[tuple[float, np.ndarray]] | None = None,
    replans: Sequence = (),
    failures: Sequence[tuple[int, float]] = (),
    headings: np.ndarray | None = None,
) -> Frames:
    """The video frames of a recorded run, as a :class:`Frames` sequence.

    times: ``(T,)`` non-decreasing sample times [s] of the recording.
    positions: ``(T, m, 2)`` robot centres at those times [workspace units].
    contacts: records with ``time`` [s], ``kind`` (``robot-robot``,
        ``robot-obstacle`` or ``robot-wall``), ``a`` (robot index), ``b``
        (other robot, obstacle index, or -1 for the wall); a ``witness``
        that is a point ``(x, y)`` is taken as the contact point, anything
        else there (such as the name of the detector) is ignored and the
        boundary point nearest to the robot is used.  For half a video
        second after a contact the frame gets a red border, the robots in
        it are drawn red, and a big red ring marks where it happened.  The
        header counts the contacts so far; records of one pair less than
        0.1 s apart (one contact seen by several detectors) count once.
    params: frame rate, size (``None``: grows with the workspace and m),
        trails and playback speed (see :func:`sim.output.playback.timing`: the
        video lasts at most ``MAX_VIDEO_SECONDS``).
    step_times: the plan's step start times and end time ``(K + 1,)``; the
        header then names the active step, counted from 1 (``step 1/5``),
        and says when the plan is over and the robots are settling.
    title: first header line (cut to fit).
    targets: for chained targets, ``(start time [s], placement (m, 2))``
        of each leg in time order; a frame marks the placement of the leg
        under way (the first one's before its start time) and the header
        names the leg.  Default: ``problem.target`` throughout.
    replans: records with ``time`` (the trigger [s]), ``planned_at`` [s]
        and ``steps`` (:class:`sim.execute.recovery.Replan`) of a run with online
        recovery; from a trigger on the header says the swarm is braking
        for replan k, then follows the new plan (``replan k: 6 steps``)
        instead of the first plan's steps.
    failures: ``(robot, time [s])`` of robots that stopped actuating; from
        that time on the robot is drawn grey with a dark cross (and the
        legend names it).

    headings: ``(T, m)`` robot headings [rad, from +x, counter-clockwise]
        of a drive that has them (:mod:`sim.execute.drive`); each robot is
        drawn with a line from its centre to its rim along its heading.

    The arguments are checked at once; frames are drawn when asked for.
    """
    params = params if params is not None else RenderParams()
    t = np.asarray(times, float).reshape(-1)
    pos = np.asarray(positions, float)
    if len(t) < 1 or not np.all(np.isfinite(t)):
        raise ValueError(f"times must hold at least one finite sample time, got {len(t)} samples")
    if np.any(np.diff(t) < 0):
        i = int(np.flatnonzero(np.diff(t) < 0)[0])
        raise ValueError(f"times must be non-decreasing, got times[{i + 1}] = {t[i + 1]:g} < {t[i]:g}")
    if pos.shape != (len(t), problem.m, 2):
        raise ValueError(f"positions must be (T, m, 2) = ({len(t)}, {problem.m}, 2), got {pos.shape}")
    size = params.size
    if size is not None and (isinstance(size, bool) or not isinstance(size, (int, np.integer))
                             or not 64 <= size <= MAX_RENDER_SIZE):
        raise ValueError(f"size must be an integer in [64, {MAX_RENDER_SIZE}] pixels or None (auto), got {size!r}")
    steps = None
    if step_times is not None:
        steps = np.asarray(step_times, float).reshape(-1)
        if len(steps) < 1 or not np.all(np.isfinite(steps)) or np.any(np.diff(steps) < 0):
            raise ValueError("step_times must be a non-empty, non-decreasing (K + 1,) array of finite times")
    legs = None
    if targets is not None:
        legs = [(float(t0), np.asarray(p, float).reshape(-1, 2)) for t0, p in targets]
        if not legs or any(p.shape != (problem.m, 2) for _, p in legs) or any(
                b[0] < a[0] for a, b in zip(legs, legs[1:])):
            raise ValueError("targets must be (time, (m, 2) placement) pairs in time order")
    try:
        marks = sorted((float(r.time), float(r.planned_at), int(r.steps)) for r in replans)
    except (AttributeError, TypeError, ValueError) as e:
        raise ValueError(f"replans need time, planned_at and steps attributes: {e}") from None
    try:
        broken = sorted((float(tf), int(i)) for i, tf in failures)
    except (TypeError, ValueError) as e:
        raise ValueError(f"failures must be (robot, time) pairs: {e}") from None
    if any(not 0 <= i < problem.m for _, i in broken):
        raise ValueError(f"failures must name robots in [0, {problem.m})")
    clock = timing(t[-1] - t[0], params)
    rows = _contact_table(problem, contacts, t, pos)
    heads = None
    if headings is not None:
        heads = np.asarray(headings, float)
        if heads.shape != (len(t), problem.m) or not np.all(np.isfinite(heads)):
            raise ValueError(f"headings must be a finite (T, m) = ({len(t)}, {problem.m}) array, got {heads.shape}")
    return Frames(problem, t, pos, rows, params, clock, steps, str(title), legs, marks, broken, headings=heads)


def _contact_table(problem: Problem, contacts: Sequence, t: np.ndarray, pos: np.ndarray) -> _Contacts:
    """Check and sort the contact records; find the points of obstacle and wall contacts.

    A record without a usable ``witness`` gets the boundary point nearest to
    the robot's recorded position at the contact time.
    """
    rows = []
    keys = []
    for n, c in enumerate(contacts):
        try:
            time, kind, a, b = float(c.time), str(c.kind), int(c.a), int(c.b)
        except (AttributeError, TypeError, ValueError) as e:
            raise ValueError(f"contacts[{n}] needs time, kind, a and b attributes: {e}") from None
        if not 0 <= a < problem.m:
            raise ValueError(f"contacts[{n}].a must be a robot index in [0, {problem.m}), got {a}")
        robot_pair = kind == "robot-robot"
        if robot_pair and not 0 <= b < problem.m:
            raise ValueError(f"contacts[{n}].b must be a robot index in [0, {problem.m}), got {b}")
        point = (math.nan, math.nan)
        if not robot_pair:
            w = getattr(c, "witness", None)
            try:
                w = np.asarray(w, float).reshape(-1)
            except (TypeError, ValueError):
                w = np.empty(0)
            if len(w) == 2 and np.all(np.isfinite(w)):
                point = (float(w[0]), float(w[1]))
            else:
                at = _interpolate(t, pos, np.array([time]))[0, a]
                q = _closest_boundary_point(problem, at, b if kind == "robot-obstacle" else -1)
                point = (float(q[0]), float(q[1]))
        rows.append((time, a, b if robot_pair else -1, point))
        keys.append((kind, a, b))
    order = sorted(range(len(rows)), key=lambda n: rows[n][0])
    # One contact reported by several detectors (same pair, about the same
    # time) is counted once.
    last: dict[tuple, float] = {}
    distinct = []
    for n in order:
        time, key = rows[n][0], keys[n]
        distinct.append(not (key in last and time - last[key] <= _SAME_CONTACT_SECONDS))
        last[key] = time
    return _Contacts(
        np.array([rows[n][0] for n in order], float),
        np.array([rows[n][1] for n in order], int),
        np.array([rows[n][2] for n in order], int),
        np.array([rows[n][3] for n in order], float).reshape(-1, 2),
        np.cumsum(np.array(distinct, int)),
    )


def _closest_boundary_point(problem: Problem, p: np.ndarray, b: int) -> np.ndarray:
    """The point of obstacle ``b`` (or of the wall when ``b < 0``) nearest to ``p``."""
    x, y = float(p[0]), float(p[1])
    if b < 0 or b >= len(problem.obstacles):
        cands = [(0.0, y), (problem.width, y), (x, 0.0), (x, problem.height)]
        d = [x, problem.width - x, y, problem.height - y]
        return np.array(cands[int(np.argmin(d))], float)
    ob = problem.obstacles[b]
    if isinstance(ob, Circle):
        c = np.array(ob.center)
        v = p - c
        n = float(np.hypot(*v))
        return c + (v / n if n > 0 else np.array([1.0, 0.0])) * ob.radius
    a = ob.vertices
    e = np.roll(a, -1, axis=0) - a
    u = np.clip(np.einsum("ij,ij->i", p - a, e) / np.maximum(np.einsum("ij,ij->i", e, e), 1e-300), 0, 1)
    q = a + u[:, None] * e
    return q[int(np.argmin(np.hypot(*(q - p).T)))]


