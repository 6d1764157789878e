"""Off-screen drawing with pygame-ce: scenario pictures and video frames.

Drawing is kept apart from the model: a :class:`Canvas` takes read-only
positions and returns ``(H, W, 3) uint8`` arrays; writing files is
:mod:`sim.media`'s job.  No window is ever opened (``SDL_VIDEODRIVER=dummy``).

:func:`render_frames` turns a physics recording (sample times, positions and
contacts) into video frames.  Playback runs ``speedup`` sim seconds per video
second; frame ``k`` shows sim time ``k * speedup / fps``, positions linearly
interpolated from the recording, and the last recorded time is shown and held
for about a second at the end.
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterator, Sequence

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("SDL_AUDIODRIVER", "dummy")
os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")

import numpy as np  # noqa: E402
import pygame  # noqa: E402

from planner.problem import Circle, Problem  # noqa: E402

from .params import RenderParams  # noqa: E402

__all__ = [
    "Canvas",
    "draw_scenario",
    "frame_times",
    "playback_speedup",
    "render_frames",
    "robot_colors",
]

BACKGROUND = (248, 248, 244)
WALL = (40, 40, 48)
OBSTACLE = (96, 100, 112)
START = (40, 90, 200)
TARGET = (236, 120, 40)
TARGET_MARK = (250, 200, 160)
TEXT = (20, 20, 24)
CONTACT = (230, 20, 20)
TRAIL = (150, 170, 220)
OUTLINE = (60, 60, 70)
LABEL_ON_CONTACT = (255, 255, 255)

_READABLE = (1.0, 1.5, 2.0, 2.5, 3.0, 4.0, 5.0, 6.0, 8.0)
"""Mantissas of the automatic speed-ups: 1, 1.5, 2, 2.5, 3, 4, 5, 6, 8, 10, 15, ..."""

_HOLD_SECONDS = 1.0  # how long the last frame is held [video s]
_FLASH_SECONDS = 0.5  # how long a contact stays red [video s]
_TRAIL_FRACTION = 0.15  # trail length as a fraction of the run
_TRAIL_MIN_SECONDS = 3.0  # shortest trail [sim s]
_TRAIL_POINTS = 40  # trail samples per trail length
_TINT = 0.55  # how far a trail colour is blended towards the background
_SAME_CONTACT_SECONDS = 0.1  # records of one pair this close in time are one contact [sim s]


def robot_colors(m: int) -> list[tuple[int, int, int]]:
    """The RGB colour of each of ``m`` robots: distinct, mid-saturation, golden-ratio hues.

    Hues near pure red are left out: red marks contacts.
    """
    out = []
    for i in range(m):
        h = (i * 0.61803398875) % 1.0
        c = pygame.Color(0)
        c.hsva = (25.0 + h * 310.0, 55.0, 85.0, 100.0)
        out.append((c.r, c.g, c.b))
    return out


def _tint(color: tuple[int, int, int], amount: float = _TINT) -> tuple[int, int, int]:
    """``color`` blended towards the background by ``amount`` (0: unchanged)."""
    return tuple(int(round(c + (b - c) * amount)) for c, b in zip(color, BACKGROUND))


class Canvas:
    """Maps the workspace to pixels and draws on a static background.

    The longer workspace side spans ``size`` pixels minus a small border;
    a header band above the workspace holds the text so that it never hides
    a robot; both frame sides are even (video encoders need it); y points up.
    """

    def __init__(self, problem: Problem, size: int = 480):
        if not pygame.font.get_init():
            pygame.font.init()
        self.problem = problem
        border = max(4, size // 60)
        self.scale = (size - 2 * border) / max(problem.width, problem.height)
        self.font = pygame.font.Font(None, max(14, size // 30))
        self.header = 2 * self.font.get_linesize() + 4
        w = int(round(problem.width * self.scale)) + 2 * border
        h = int(round(problem.height * self.scale)) + 2 * border + self.header
        self.width_px = w + (w % 2)
        self.height_px = h + (h % 2)
        self.border = border
        self.label_font = pygame.font.Font(None, max(10, int(problem.radius * self.scale * 1.2)))
        self.r_px = max(2, int(round(problem.radius * self.scale)))
        self.background = self._draw_background()

    # -- coordinates ----------------------------------------------------------
    def to_px(self, pts: np.ndarray) -> np.ndarray:
        """Workspace points ``(..., 2)`` as ``(n, 2)`` pixel coordinates (x right, y down)."""
        pts = np.asarray(pts, float).reshape(-1, 2)
        x = self.border + pts[:, 0] * self.scale
        y = self.height_px - self.border - pts[:, 1] * self.scale
        return np.stack([x, y], axis=1)

    def _draw_background(self) -> pygame.Surface:
        s = pygame.Surface((self.width_px, self.height_px))
        s.fill(BACKGROUND)
        p = self.problem
        corners = self.to_px(np.array([[0, 0], [p.width, 0], [p.width, p.height], [0, p.height]]))
        pygame.draw.polygon(s, WALL, [tuple(c) for c in corners], width=max(2, self.border // 2))
        for ob in p.obstacles:
            if isinstance(ob, Circle):
                c = self.to_px(np.array(ob.center))[0]
                pygame.draw.circle(s, OBSTACLE, tuple(c), ob.radius * self.scale)
            else:
                pygame.draw.polygon(s, OBSTACLE, [tuple(v) for v in self.to_px(ob.vertices)])
        return s

    # -- pieces ---------------------------------------------------------------
    def surface(self) -> pygame.Surface:
        return self.background.copy()

    def draw_discs(self, s, pts, color, *, width=0, labels=False, colors=None):
        for i, c in enumerate(self.to_px(pts)):
            col = colors[i] if colors is not None else color
            pygame.draw.circle(s, col, (float(c[0]), float(c[1])), self.r_px, width=width)
            if labels and self.r_px >= 6:
                img = self.label_font.render(str(i), True, TEXT)
                s.blit(img, img.get_rect(center=(int(c[0]), int(c[1]))))

    def text(self, s, lines: list[str], corner: str = "top-left"):
        y = 2
        for line in lines:
            img = self.font.render(line, True, TEXT, BACKGROUND)
            x = self.border + 4 if corner == "top-left" else self.width_px - self.border - 4 - img.get_width()
            s.blit(img, (x, y))
            y += img.get_height() + 1

    @staticmethod
    def to_array(s: pygame.Surface) -> np.ndarray:
        w, h = s.get_size()
        return np.frombuffer(pygame.image.tobytes(s, "RGB"), np.uint8).reshape(h, w, 3)


def draw_scenario(problem: Problem, size: int = 480, title: str = "") -> np.ndarray:
    """The workspace, obstacles, start (hollow) and target (filled) as an image."""
    cv = Canvas(problem, size)
    s = cv.surface()
    cv.draw_discs(s, problem.target, TARGET)
    cv.draw_discs(s, problem.start, START, width=max(2, cv.r_px // 4), labels=True)
    lines = [title] if title else []
    lines.append(f"m={problem.m}  start: hollow  target: filled")
    cv.text(s, lines)
    return cv.to_array(s)


# ----------------------------------------------------------------------------
# playback timing


def _readable(x: float) -> float:
    """The value of ``1, 1.5, 2, 2.5, 3, 4, 5, 6, 8`` times a power of ten nearest to ``x``
    (in ratio), never below 1."""
    if not x > 1.0:
        return 1.0
    e = math.floor(math.log10(x))
    cands = [v * 10.0**k for k in (e - 1, e, e + 1) for v in _READABLE]
    best = min(cands, key=lambda v: abs(math.log(v / x)))
    return max(1.0, float(f"{best:.6g}"))


def playback_speedup(duration: float, params: RenderParams) -> float:
    """Sim seconds per video second.

    ``params.speedup`` when set; otherwise the readable value (1, 1.5, 2,
    2.5, 3, 4, 5, 6, 8, 10, 15, ...) that makes a run of ``duration`` sim
    seconds last closest to ``params.video_seconds``, and at least 1 (a short
    run plays in real time rather than in slow motion).
    """
    if params.speedup is not None:
        if not params.speedup > 0:
            raise ValueError(f"speedup must be > 0 or None (auto), got {params.speedup!r}")
        return float(params.speedup)
    if not params.video_seconds > 0:
        raise ValueError(f"video_seconds must be > 0, got {params.video_seconds!r}")
    return _readable(max(0.0, float(duration)) / params.video_seconds)


def frame_times(duration: float, speedup: float, fps: int) -> np.ndarray:
    """Sim time shown by every frame [s], the held end included.

    Frames ``k = 0, 1, ...`` show ``k * speedup / fps`` up to ``duration``;
    a frame at exactly ``duration`` follows when the grid misses it, and the
    last time is then repeated for about one video second.
    """
    duration = max(0.0, float(duration))
    dt = speedup / fps
    n = int(math.floor(duration / dt + 1e-9)) + 1
    t = np.arange(n) * dt
    if duration - t[-1] > 1e-9 * max(1.0, duration):
        t = np.append(t, duration)
    hold = int(round(_HOLD_SECONDS * fps))
    return np.concatenate([t, np.full(hold, t[-1])])


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
) -> Iterator[np.ndarray]:
    """Video frames ``(H, W, 3) uint8`` (H and W even) of a recorded run.

    times: ``(T,)`` non-decreasing sample times [s] of the recording.
    positions: ``(T, m, 2)`` robot centres at those times [workspace units].
    contacts: records with ``time`` [s], ``kind`` (``robot-robot``,
        ``robot-obstacle`` or ``robot-wall``), ``a`` (robot index), ``b``
        (other robot, obstacle index, or -1 for the wall); a ``witness``
        that is a point ``(x, y)`` is taken as the contact point, anything
        else there (such as the name of the detector) is ignored and the
        boundary point nearest to the robot is used.  Robots in a contact
        from the last half video second are drawn red with a red ring, and an
        obstacle or wall contact marks its contact point.  The header counts
        the contacts so far; records of one pair less than 0.1 s apart (one
        contact seen by several detectors) count once.
    params: frame rate, size, trails and playback speed (see
        :func:`playback_speedup` and :func:`frame_times`).
    step_times: the plan's step start times and end time ``(K + 1,)``; the
        header then names the active step ``k`` (``step_times[k] <= t <
        step_times[k + 1]``, 0-based like the validator's messages).
    title: first header line.
    targets: for chained targets, ``(start time [s], placement (m, 2))``
        of each leg in time order; a frame marks the placement of the leg
        under way (the first one's before its start time) and the header
        names the leg.  Default: ``problem.target`` throughout.

    The arguments are checked at once; frames are drawn lazily, one per
    ``next()``.  Each yielded array is a fresh copy.
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
    if not isinstance(params.fps, (int, np.integer)) or params.fps < 1:
        raise ValueError(f"fps must be an integer >= 1, got {params.fps!r}")
    if not params.size >= 64:
        raise ValueError(f"size must be >= 64 pixels, got {params.size!r}")
    steps = None
    if step_times is not None:
        steps = np.asarray(step_times, float).reshape(-1)
        if len(steps) < 1 or np.any(np.diff(steps) < 0):
            raise ValueError("step_times must be a non-empty, non-decreasing (K + 1,) array")
    legs = None
    if targets is not None:
        legs = [(float(t0), np.asarray(p, float).reshape(-1, 2)) for t0, p in targets]
        if not legs or any(p.shape != (problem.m, 2) for _, p in legs) or any(
                b[0] < a[0] for a, b in zip(legs, legs[1:])):
            raise ValueError("targets must be (time, (m, 2) placement) pairs in time order")
    contact_rows = _contact_table(problem, contacts, t, pos)
    speedup = playback_speedup(t[-1] - t[0], params)
    return _frames(problem, t, pos, contact_rows, params, speedup, steps, str(title), legs)


class _Contacts:
    """Contacts sorted by time: robots involved and, for obstacles and walls, a point."""

    def __init__(self, time, a, b, point, seen):
        self.time = time  # (n,) [s]
        self.a = a  # (n,) robot index
        self.b = b  # (n,) other robot index, or -1 when not a robot
        self.point = point  # (n, 2) contact point, NaN for robot-robot contacts
        self.seen = seen  # (n,) distinct contacts up to and including each record


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


def _interpolate(t: np.ndarray, pos: np.ndarray, ts: np.ndarray) -> np.ndarray:
    """Positions ``(len(ts), m, 2)`` linearly interpolated from the recording."""
    if len(t) == 1:
        return np.broadcast_to(pos[0], (len(ts), *pos.shape[1:])).copy()
    i = np.clip(np.searchsorted(t, ts, side="right") - 1, 0, len(t) - 2)
    span = t[i + 1] - t[i]
    w = np.clip(np.where(span > 0, (ts - t[i]) / np.where(span > 0, span, 1.0), 1.0), 0.0, 1.0)
    return pos[i] + w[:, None, None] * (pos[i + 1] - pos[i])


def _label_font(r_px: int, m: int) -> pygame.font.Font | None:
    """The largest font whose widest index fits in a disc of radius ``r_px``; None if none."""
    if r_px < 6:
        return None
    widest = str(max(m - 1, 0))
    for size in range(int(r_px * 1.5), 8, -1):
        font = pygame.font.Font(None, size)
        w, h = font.size(widest)
        if w <= 1.7 * r_px and h <= 2.0 * r_px:
            return font
    return None


def _fit_text(font: pygame.font.Font, text: str, width: int) -> str:
    """``text`` cut (with an ellipsis) to at most ``width`` pixels."""
    if font.size(text)[0] <= width:
        return text
    while text and font.size(text + "...")[0] > width:
        text = text[:-1]
    return text + "..." if text else ""


def _target_layer(cv: Canvas, base: pygame.Surface, target: np.ndarray, r: int) -> pygame.Surface:
    """``base`` with the target markers (a ring and a cross at every target) drawn on a copy."""
    layer = base.copy()
    ring = max(1, r // 5)
    for c in cv.to_px(target):
        pygame.draw.circle(layer, TARGET_MARK, (float(c[0]), float(c[1])), r, width=ring)
        if r >= 4:
            h = max(2, r // 3)
            pygame.draw.line(layer, TARGET_MARK, (c[0] - h, c[1]), (c[0] + h, c[1]))
            pygame.draw.line(layer, TARGET_MARK, (c[0], c[1] - h), (c[0], c[1] + h))
    return layer


def _frames(problem, t, pos, contacts: _Contacts, params, speedup, steps, title, legs=None):
    cv = Canvas(problem, params.size)
    fps = int(params.fps)
    t0 = float(t[0])
    duration = float(t[-1] - t0)
    ft = frame_times(duration, speedup, fps)
    n_drawn = len(ft) - int(round(_HOLD_SECONDS * fps))
    m = problem.m
    r = cv.r_px

    frame_px = cv.to_px(_interpolate(t, pos, t0 + ft[:n_drawn])).reshape(n_drawn, m, 2)
    colors = robot_colors(m)
    tints = [_tint(c) for c in colors]

    # static layer: background, walls, obstacles, target markers (one per leg)
    legs = legs or [(float(t0), problem.target)]
    statics = [_target_layer(cv, cv.background, target, r) for _, target in legs]
    leg_starts = np.array([t0 for t0, _ in legs])

    # trails: positions on a uniform grid, in pixels
    trail_len = max(_TRAIL_FRACTION * duration, _TRAIL_MIN_SECONDS)
    trail_dt = trail_len / _TRAIL_POINTS
    trail_px = None
    if params.trails and duration > 0:
        grid = np.arange(int(math.floor(duration / trail_dt)) + 1) * trail_dt
        trail_px = cv.to_px(_interpolate(t, pos, t0 + grid)).reshape(len(grid), m, 2)
    trail_w = max(1, int(round(0.4 * r)))

    # labels, pre-rendered once
    lf = _label_font(r, m)
    labels = [lf.render(str(i), True, TEXT) for i in range(m)] if lf else None
    labels_hot = [lf.render(str(i), True, LABEL_ON_CONTACT) for i in range(m)] if lf else None
    label_off = [(-img.get_width() / 2, -img.get_height() / 2) for img in labels] if labels else None

    # header pieces that do not change
    font = cv.font
    line_h = font.get_linesize() + 1
    left_x = cv.border + 4
    right_x = cv.width_px - cv.border - 4
    speed_img = font.render(f"x{speedup:g}", True, TEXT, BACKGROUND)
    title_img = font.render(
        _fit_text(font, title, right_x - left_x - speed_img.get_width() - 12), True, TEXT, BACKGROUND
    )
    for layer in statics:
        layer.blit(title_img, (left_x, 2))
        layer.blit(speed_img, (right_x - speed_img.get_width(), 2))

    flash = _FLASH_SECONDS * speedup
    hot_ring = max(2, r // 3)
    spot_r = max(3, r // 2)
    surf = pygame.Surface((cv.width_px, cv.height_px))
    total = f"{duration:.1f}"
    frame = None
    for k in range(n_drawn):
        now = float(ft[k])
        leg = max(0, int(np.searchsorted(leg_starts, t0 + now, side="right")) - 1)
        surf.blit(statics[leg], (0, 0))
        cur = frame_px[k]

        if trail_px is not None:
            j1 = min(int(math.floor(now / trail_dt + 1e-9)), len(trail_px) - 1)
            j0 = max(0, int(math.ceil((now - trail_len) / trail_dt - 1e-9)))
            seg = np.concatenate([trail_px[j0 : j1 + 1], cur[None]], axis=0)
            if len(seg) >= 2:
                extent = (seg.max(axis=0) - seg.min(axis=0)).max(axis=1)
                for i in np.flatnonzero(extent >= 1.0):
                    pygame.draw.lines(surf, tints[i], False, seg[:, i].tolist(), trail_w)

        # contacts: records within the flash window, and the count so far
        tc = t0 + now
        i0 = int(np.searchsorted(contacts.time, tc - flash, side="left"))
        i1 = int(np.searchsorted(contacts.time, tc, side="right"))
        hot = np.zeros(m, bool)
        spots = ()
        if i1 > i0:
            hot[contacts.a[i0:i1]] = True
            bb = contacts.b[i0:i1]
            hot[bb[bb >= 0]] = True
            spots = _contact_spots(cv, contacts, i0, i1)

        for i in np.flatnonzero(~hot):
            c = (cur[i, 0], cur[i, 1])
            pygame.draw.circle(surf, colors[i], c, r)
            pygame.draw.circle(surf, OUTLINE, c, r, width=1)
            if labels is not None:
                surf.blit(labels[i], (c[0] + label_off[i][0], c[1] + label_off[i][1]))
        for p in spots:
            pygame.draw.circle(surf, CONTACT, p, spot_r)
        for i in np.flatnonzero(hot):  # on top, with a thick red ring
            c = (cur[i, 0], cur[i, 1])
            pygame.draw.circle(surf, CONTACT, c, r + hot_ring)
            pygame.draw.circle(surf, OUTLINE, c, r, width=1)
            if labels is not None:
                surf.blit(labels_hot[i], (c[0] + label_off[i][0], c[1] + label_off[i][1]))

        status = f"t = {now:.1f} s / {total} s"
        if steps is not None:
            K = len(steps) - 1
            if K > 0 and tc < steps[-1]:
                k_step = int(np.clip(np.searchsorted(steps, tc, side="right") - 1, 0, K - 1))
                status += f"   step {k_step}/{K}"
            else:
                status += f"   step -/{K} (settling)" if K > 0 else "   no steps"
        if len(legs) > 1:
            status += f"   target {leg + 1}/{len(legs)}"
        surf.blit(font.render(status, True, TEXT, BACKGROUND), (left_x, 2 + line_h))
        if i1 > 0:
            img = font.render(f"CONTACTS: {contacts.seen[i1 - 1]}", True, CONTACT, BACKGROUND)
            surf.blit(img, (right_x - img.get_width(), 2 + line_h))

        frame = Canvas.to_array(surf)
        yield frame.copy()
    for _ in range(len(ft) - n_drawn):
        yield frame.copy()


def _contact_spots(cv: Canvas, contacts: _Contacts, i0: int, i1: int) -> list[tuple[int, int]]:
    """Distinct pixel centres of the obstacle and wall contact points in ``[i0, i1)``."""
    pts = contacts.point[i0:i1]
    pts = pts[np.all(np.isfinite(pts), axis=1)]
    if len(pts) == 0:
        return []
    px = np.round(cv.to_px(pts)).astype(int)
    return [(int(x), int(y)) for x, y in np.unique(px, axis=0)]
