"""The frames of a run's video, drawn on demand: robots, trails, targets, contacts that flash, the clock."""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence

import numpy as np

from .._pygame import pygame
from ..words import plural
from .canvas import (
    BACKGROUND,
    CONTACT,
    LABEL_ON_CONTACT,
    OBSTACLE,
    OUTLINE,
    START,
    TARGET,
    TEXT,
    WALL,
    Canvas,
    label_font,
    robot_colors,
    tint,
)
from .playback import Timing

START_MARK = tint(START, 0.45)  # start rings in videos
TARGET_MARK = tint(TARGET, 0.55)  # target discs in videos

_FLASH_SECONDS = 0.5  # how long a contact flashes [video s]
_TRAIL_FRACTION = 0.15  # trail length as a fraction of the run
_TRAIL_MIN_SECONDS = 3.0  # shortest trail [sim s]
_TRAIL_POINTS = 30  # trail samples per trail length, up to _TRAIL_FULL robots
_TRAIL_FULL = 25  # above this many robots, fewer samples per trail (down to _TRAIL_MIN_POINTS)
_TRAIL_MIN_POINTS = 8
class _Contacts:
    """Contacts sorted by time: robots involved and, for obstacles and walls, a point."""

    def __init__(self, time, a, b, point, seen):
        self.time = time  # (n,) [s]
        self.a = a  # (n,) robot index
        self.b = b  # (n,) other robot index, or -1 when not a robot
        self.point = point  # (n, 2) contact point, NaN for robot-robot contacts
        self.seen = seen  # (n,) distinct contacts up to and including each record


def _interpolate(t: np.ndarray, pos: np.ndarray, ts: np.ndarray) -> np.ndarray:
    """Positions ``(len(ts), m, 2)`` linearly interpolated from the recording."""
    if len(t) == 1:
        return np.broadcast_to(pos[0], (len(ts), *pos.shape[1:])).copy()
    i = np.clip(np.searchsorted(t, ts, side="right") - 1, 0, len(t) - 2)
    span = t[i + 1] - t[i]
    w = np.clip(np.where(span > 0, (ts - t[i]) / np.where(span > 0, span, 1.0), 1.0), 0.0, 1.0)
    return pos[i] + w[:, None, None] * (pos[i + 1] - pos[i])


class Frames(Sequence):
    """The frames of a recorded run: ``(H, W, 3) uint8`` arrays, H and W even.

    A sequence: ``len(frames)``, ``frames[k]`` (drawn on demand, a fresh
    array) and iteration (each frame drawn once, the held end repeated).
    Nothing per frame is kept, so memory does not grow with the video's
    length.  ``timing`` is the :class:`sim.output.playback.Timing` used (speed-up,
    frame count), ``speedup`` its speed-up, ``colours`` the flat colours of
    the drawing ``(n, 3) uint8``, most important first (for a GIF palette).
    """

    def __init__(self, problem, t, pos, contacts: _Contacts, params, clock: Timing, steps, title, legs=None,
                 replans=(), failures=(), headings=None):
        self.problem = problem
        self.timing = clock
        self.speedup = clock.speedup
        self._t, self._pos, self._contacts, self._steps = t, pos, contacts, steps
        self._replans = tuple(replans)  # (trigger time, planned at, steps), in time order
        self._failures = tuple(failures)  # (time, robot), in time order
        # (T, m, 2) unit vectors of the robots' headings, or None (no heading to draw)
        self._dir = None if headings is None else np.stack([np.cos(headings), np.sin(headings)], axis=-1)
        legend = [("robot", "robots (one colour each)"), ("start", "start (hollow)"), ("target", "target (filled)")]
        if params.trails:
            legend.append(("trail", "trail"))
        legend.append(("contact", "contact"))
        if failures:
            legend.append(("failed", "failed"))
        cv = Canvas(problem, params.size, legend=legend, start_color=START_MARK, target_color=TARGET_MARK)
        self.canvas = cv
        m = problem.m
        self._colors = robot_colors(m)
        self._tints = [tint(c) for c in self._colors]
        r = cv.r

        # static layers, one per leg of a chain: background, walls, obstacles,
        # the start rings (first leg), the leg's target discs, fixed header text
        legs = legs or [(float(t[0]), problem.target)]
        self._leg_starts = np.array([t0 for t0, _ in legs])
        self._statics = []
        for n, (_, target) in enumerate(legs):
            static = cv.background.copy()
            for c in cv.to_px(target):
                cv.disc(static, TARGET_MARK, c, r)
            if n == 0:
                for c in cv.to_px(problem.start):
                    cv.ring(static, START_MARK, c, r, max(1, int(r / 5)))
            speed = f"{clock.speedup:g}x speed"
            speed_w = cv.text_line(static, speed, 0, right=True)
            cv.text_line(static, title, 0, width=cv.width_px - 2 * cv.border - 20 - speed_w)
            self._statics.append(static)
        self._surf = pygame.Surface((cv.width_px, cv.height_px))

        # trails: positions on a uniform grid, in pixels (at most a few hundred points per robot)
        duration = clock.duration
        self._trail_len = max(_TRAIL_FRACTION * duration, _TRAIL_MIN_SECONDS)
        points = max(_TRAIL_MIN_POINTS, int(_TRAIL_POINTS * min(1.0, math.sqrt(_TRAIL_FULL / m))))
        self._trail_dt = self._trail_len / points
        self._trail_px = None
        if params.trails and duration > 0:
            grid = np.arange(int(math.floor(duration / self._trail_dt)) + 1) * self._trail_dt
            self._trail_px = cv.to_px(_interpolate(t, pos, t[0] + grid)).reshape(len(grid), m, 2)
        self._trail_w = max(1, int(round(0.4 * r)))

        # labels, pre-rendered once, only where discs are big enough for them
        lf = label_font(r, m)
        self._labels = [lf.render(str(i), True, TEXT) for i in range(m)] if lf else None
        self._labels_hot = [lf.render(str(i), True, LABEL_ON_CONTACT) for i in range(m)] if lf else None

        self._flash = _FLASH_SECONDS * clock.speedup
        self._hot_ring = max(2.0, r / 3)
        self._spot_r = max(3.0, r / 2)
        self._marker_r = max(2.5 * r, 12.0)
        self._marker_w = max(3, int(r / 3))
        self._last: tuple[int, np.ndarray] | None = None

    # -- the sequence ---------------------------------------------------------
    def __len__(self) -> int:
        return self.timing.frames

    def __getitem__(self, k):
        if isinstance(k, slice):
            return [self[i] for i in range(*k.indices(len(self)))]
        k = int(k)
        n = len(self)
        if k < 0:
            k += n
        if not 0 <= k < n:
            raise IndexError(f"frame index {k} out of range for {n} frames")
        return self._draw(min(k, self.timing.drawn - 1))

    def __iter__(self) -> Iterator[np.ndarray]:
        frame = None
        for k in range(self.timing.drawn):
            frame = self._draw(k)
            yield frame
        for _ in range(self.timing.held):
            yield frame.copy()

    @property
    def colours(self) -> np.ndarray:
        """The flat colours of the drawing ``(n, 3) uint8``: fixed ones first, then robots and trails."""
        fixed = [BACKGROUND, WALL, OBSTACLE, TEXT, CONTACT, OUTLINE, LABEL_ON_CONTACT, START_MARK, TARGET_MARK]
        swatch = robot_colors(3) + [tint(c) for c in robot_colors(3)]  # the legend's robot and trail glyphs
        return np.array(list(dict.fromkeys(fixed + [c for pair in zip(self._colors, self._tints) for c in pair]
                                           + swatch)), np.uint8)

    # -- one frame --------------------------------------------------------------
    def _draw(self, k: int) -> np.ndarray:
        cv = self.canvas
        now = self.timing.time(k)
        t0 = float(self._t[0])
        tc = t0 + now
        cur = cv.to_px(_interpolate(self._t, self._pos, np.array([tc]))[0])
        surf = self._surf
        leg = max(0, int(np.searchsorted(self._leg_starts, tc, side="right")) - 1)
        surf.blit(self._statics[leg], (0, 0))
        self._draw_trails(surf, now, cur)

        # contacts: records within the flash window, and the count so far
        ct = self._contacts
        i0 = int(np.searchsorted(ct.time, tc - self._flash, side="left"))
        i1 = int(np.searchsorted(ct.time, tc, side="right"))
        m = self.problem.m
        hot = np.zeros(m, bool)
        if i1 > i0:
            hot[ct.a[i0:i1]] = True
            bb = ct.b[i0:i1]
            hot[bb[bb >= 0]] = True

        r = cv.r
        broken = {i for tf, i in self._failures if tf <= tc}
        for i in np.flatnonzero(~hot):
            if i in broken:
                cv.draw_glyph(surf, "failed", cur[i], r)
                continue
            cv.disc(surf, self._colors[i], cur[i], r)
            cv.ring(surf, OUTLINE, cur[i], r, 1)
            self._label(surf, self._labels, i, cur[i])
        if self._dir is not None:
            self._draw_headings(surf, tc, cur, broken)
        if i1 > i0:
            self._draw_flash(surf, i0, i1, cur, hot)

        status = f"t = {now:.1f} s / {self.timing.duration:.1f} s" + self._step_text(tc)
        if len(self._statics) > 1:
            status += f"   target {leg + 1}/{len(self._statics)}"
        if i1 > 0:
            seen = plural(int(ct.seen[i1 - 1]), "contact")
            if i1 > i0:
                img = cv.font.render(f" CONTACT  ({seen}) ", True, LABEL_ON_CONTACT, CONTACT)
            else:
                img = cv.font.render(seen, True, CONTACT, BACKGROUND)
            x = cv.width_px - cv.border - 4 - img.get_width()
            surf.blit(img, (x, cv.pad + cv.line_h))
            cv.text_line(surf, status, 1, width=x - cv.border - 12)
        else:
            cv.text_line(surf, status, 1)
        return Canvas.to_array(surf)

    def _label(self, surf, labels, i: int, c) -> None:
        if labels is not None:
            img = labels[i]
            surf.blit(img, (int(round(c[0] - img.get_width() / 2)), int(round(c[1] - img.get_height() / 2))))

    def _draw_headings(self, surf, tc: float, cur: np.ndarray, broken) -> None:
        """A line from each working robot's centre to its rim, along its heading."""
        cv = self.canvas
        ts = np.array([tc])
        here = _interpolate(self._t, self._pos, ts)[0]
        ahead = _interpolate(self._t, self._dir, ts)[0]
        norm = np.maximum(np.hypot(ahead[:, 0], ahead[:, 1]), 1e-12)[:, None]
        tips = cv.to_px(here + 0.95 * float(self.problem.radius) * ahead / norm)
        w = max(1, int(round(cv.r / 5)))
        for i in range(len(cur)):
            if i not in broken:
                pygame.draw.line(surf, OUTLINE, cur[i], tips[i], w)

    def _draw_trails(self, surf, now: float, cur: np.ndarray) -> None:
        if self._trail_px is None:
            return
        dt = self._trail_dt
        j1 = min(int(math.floor(now / dt + 1e-9)), len(self._trail_px) - 1)
        j0 = max(0, int(math.ceil((now - self._trail_len) / dt - 1e-9)))
        seg = np.concatenate([self._trail_px[j0 : j1 + 1], cur[None]], axis=0)
        if len(seg) < 2:
            return
        extent = (seg.max(axis=0) - seg.min(axis=0)).max(axis=1)
        w = self._trail_w
        for i in np.flatnonzero(extent >= 1.0):
            pts = seg[:, i].tolist()
            col = self._tints[i]
            if w <= 1:
                pygame.draw.aalines(surf, col, False, pts)
            else:
                for a, b in zip(pts, pts[1:]):
                    pygame.draw.aaline(surf, col, a, b, w)

    def _draw_flash(self, surf, i0: int, i1: int, cur: np.ndarray, hot: np.ndarray) -> None:
        """Robots in a recent contact in red, a big ring where it happened, a red frame border."""
        cv, ct, r = self.canvas, self._contacts, self.canvas.r
        for i in np.flatnonzero(hot):  # on top, with a thick red ring
            cv.disc(surf, CONTACT, cur[i], r + self._hot_ring)
            cv.ring(surf, OUTLINE, cur[i], r, 1)
            self._label(surf, self._labels_hot, i, cur[i])
        places = []
        for n in range(i0, i1):
            if ct.b[n] >= 0:  # two robots: between them, now
                places.append((cur[ct.a[n]] + cur[ct.b[n]]) / 2)
            else:
                p = cv.to_px(ct.point[n])[0]
                cv.disc(surf, CONTACT, p, self._spot_r)
                places.append(p)
        for p in np.unique(np.round(np.array(places)), axis=0):
            cv.ring(surf, CONTACT, p, self._marker_r, self._marker_w)
        pygame.draw.rect(surf, CONTACT, surf.get_rect(), width=cv.pad)

    def _step_text(self, tc: float) -> str:
        steps = self._steps
        if steps is None:
            return ""
        due = [n for n, (t0, _, _) in enumerate(self._replans) if t0 <= tc]
        if due:
            k = due[-1]
            _, planned_at, count = self._replans[k]
            if tc < planned_at:
                return f"   braking for replan {k + 1}"
            return f"   replan {k + 1}: {plural(count, 'step')}"
        k_all = len(steps) - 1
        if k_all == 0:
            return "   no motion planned"
        if tc < steps[-1]:
            k = int(np.clip(np.searchsorted(steps, tc, side="right") - 1, 0, k_all - 1))
            return f"   step {k + 1}/{k_all}"
        return f"   plan done ({plural(k_all, 'step')}), settling"
