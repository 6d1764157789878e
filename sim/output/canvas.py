"""The drawing surface shared by scenario pictures and video frames.

A :class:`Canvas` maps the workspace to pixels (y up in the workspace, down
on screen), draws a static background (walls and obstacles), and lays out a
header band above the workspace for text and a legend band below it, so
that neither ever hides a robot.  Everything is drawn anti-aliased with
pygame-ce's ``aacircle`` / ``aaline`` primitives; text is rendered
anti-aliased.

Conventions, the same in every picture and video (and named in the legend):
a start is a hollow ring, a target a filled disc, a robot a disc in its own
colour with a dark outline, a trail a pale line, a contact red, a robot that
failed grey with a dark cross.  Lengths are shown by a scale bar of a round
length (``10 units``) at the right of the legend band and by ticks at the
same spacing along the walls, from the workspace's origin (bottom left).

A map whose free space fills only a small part of its workspace (a ROS map is
mostly unknown space) is drawn cropped to that part (:func:`view_box`): the
frame then bounds the view, not the walls, and its ticks count from the view's
bottom left corner.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from planner.problem import Circle, Problem

from .._pygame import pygame
from .view import view_box

__all__ = [
    "BACKGROUND",
    "CONTACT",
    "Canvas",
    "MAX_SIZE",
    "MIN_SIZE",
    "START",
    "TARGET",
    "fit_text",
    "frame_size",
    "label_font",
    "nice_length",
    "robot_colors",
    "tint",
    "view_box",
]

BACKGROUND = (248, 248, 244)
WALL = (40, 40, 48)
OBSTACLE = (96, 100, 112)
START = (40, 90, 200)
TARGET = (236, 120, 40)
TEXT = (20, 20, 24)
CONTACT = (230, 20, 20)
OUTLINE = (60, 60, 70)
FAILED = (170, 170, 170)  # a robot that stopped actuating (videos), drawn with a cross
LABEL_ON_CONTACT = (255, 255, 255)
SCALE = WALL  # the scale bar and the wall ticks

MIN_SIZE = 480
"""Smallest automatic frame size [px]."""
MAX_SIZE = 960
"""Largest automatic frame size [px]."""

_PX_PER_RADIUS = 7.0  # automatic size: a robot's radius is at least this many pixels (up to MAX_SIZE)
_PX_PER_SQRT_M = 56.0  # automatic size: and at least this many pixels per sqrt(robots)
_LABEL_MIN_FONT = 14  # smallest label font [px]: digits about 9 px high
_TINT = 0.55  # default blend towards the background


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


def nice_length(longest: float) -> float:
    """The largest 1, 2 or 5 times a power of ten that is at most ``longest`` (> 0)."""
    if not longest > 0 or not math.isfinite(longest):
        raise ValueError(f"longest must be a finite length > 0, got {longest!r}")
    k = math.floor(math.log10(longest))
    for f in (5.0, 2.0, 1.0):
        v = f * 10.0**k
        if v <= longest * (1 + 1e-12):
            return float(f"{v:.12g}")
    return float(f"{10.0 ** (k - 1) * 5:.12g}")  # not reached: 1 * 10**k <= longest


def tint(color: tuple[int, int, int], amount: float = _TINT) -> tuple[int, int, int]:
    """``color`` blended towards the background by ``amount`` (0: unchanged, 1: background)."""
    return tuple(int(round(c + (b - c) * amount)) for c, b in zip(color, BACKGROUND))


def frame_size(problem: Problem) -> int:
    """The automatic picture size [px] of ``problem``: grows with the workspace and ``m``.

    The longer side is the smallest of ``MIN_SIZE`` .. ``MAX_SIZE`` pixels
    that gives a robot a radius of at least 7 pixels (so that labels fit,
    see :func:`label_font`) and at least ``56 * sqrt(m)`` pixels; it is
    ``MAX_SIZE`` when neither fits.  Even.
    """
    x0, y0, x1, y1 = view_box(problem)
    side = max(x1 - x0, y1 - y0)
    need = max(_PX_PER_RADIUS * side / problem.radius, _PX_PER_SQRT_M * math.sqrt(problem.m))
    need = need * 1.05 + 16  # the border
    size = int(min(MAX_SIZE, max(MIN_SIZE, math.ceil(need))))
    return size + size % 2


def _font(px: int) -> pygame.font.Font:
    if not pygame.font.get_init():
        pygame.font.init()
    return pygame.font.Font(None, int(px))


def label_font(r_px: float, m: int) -> pygame.font.Font | None:
    """The largest font whose widest robot index fits inside a disc of radius ``r_px``.

    ``None`` when even the smallest readable one (14 px, digits about 9 px
    high) does not fit: then robots go unlabelled.
    """
    widest = str(max(m - 1, 0))
    for size in range(max(int(r_px * 1.6), _LABEL_MIN_FONT), _LABEL_MIN_FONT - 1, -1):
        font = _font(size)
        w, _ = font.size(widest)
        if w <= 1.6 * r_px and font.get_ascent() <= 1.3 * r_px:
            return font
    return None


def fit_text(font: pygame.font.Font, text: str, width: int) -> str:
    """``text`` cut (with an ellipsis) to at most ``width`` pixels; unprintable characters as ``?``.

    Time and memory do not grow with the length of ``text``: no glyph of a
    kept character is narrower than a pixel, so only the first ``width``
    characters are ever measured, by bisection.
    """
    width = int(width)
    if width <= 0:
        return ""
    head = "".join(ch if ch.isprintable() else "?" for ch in str(text)[: width + 1])
    if len(head) <= width and font.size(head)[0] <= width:
        return head
    lo, hi = 0, len(head)  # the longest prefix that fits with the ellipsis is in [lo, hi)
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if font.size(head[:mid] + "...")[0] <= width:
            lo = mid
        else:
            hi = mid
    if lo == 0 and font.size("...")[0] > width:
        return ""
    return head[:lo] + "..."


class Canvas:
    """Maps the workspace to pixels and draws on a static background.

    size: the longer frame side [px] (``None``: :func:`frame_size`); the
        workspace's longer side spans it less a small border.
    legend: ``(glyph, label)`` items drawn in the band below the workspace;
        glyphs are ``robot``, ``start``, ``target``, ``trail``, ``contact``.
    start_color, target_color: the colours of start rings and target discs
        (also in the legend).
    scale_bar: draw the scale bar (right of the legend band) and the wall
        ticks; ``scale_length`` [units] is its length, ``scale_bar_rect``
        its bar [px] (None without it).

    A header band above the workspace holds two lines of text; a free edge
    of ``pad`` pixels runs all round.  Both frame sides are even (video
    encoders need it).
    """

    def __init__(
        self,
        problem: Problem,
        size: int | None = None,
        *,
        legend: Sequence[tuple[str, str]] = (),
        start_color: tuple[int, int, int] = START,
        target_color: tuple[int, int, int] = TARGET,
        scale_bar: bool = True,
    ):
        size = frame_size(problem) if size is None else int(size)
        self.problem = problem
        self.size = size
        self.start_color = start_color
        self.target_color = target_color
        border = max(4, size // 60)
        self.border = border
        self.view = view_box(problem)
        vx0, vy0, vx1, vy1 = self.view
        view_w, view_h = vx1 - vx0, vy1 - vy0
        self.scale = (size - 2 * border) / max(view_w, view_h)
        self.font = _font(max(14, size // 30))
        self.line_h = self.font.get_linesize() + 1
        self.pad = max(4, size // 80)  # free edge all round: room for a contact flash's frame
        self.header = self.pad + 2 * self.line_h + 2
        ws_w = int(round(view_w * self.scale)) + 2 * border
        self.scale_length = None
        self.scale_bar_rect = None
        if scale_bar:
            self.scale_length = nice_length(max(24.0, ws_w / 5) / self.scale)
        self._legend_rows = self._layout_legend(list(legend), ws_w)
        self.footer = len(self._legend_rows) * self.line_h + self.pad + (2 if self._legend_rows else 0)
        h = int(round(view_h * self.scale)) + 2 * border + self.header + self.footer
        self.width_px = ws_w + (ws_w % 2)
        self.height_px = h + (h % 2)
        self.r = problem.radius * self.scale  # robot radius [px], not rounded
        self.r_px = max(2, int(round(self.r)))
        self.background = self._draw_background()

    # -- coordinates ----------------------------------------------------------
    def to_px(self, pts: np.ndarray) -> np.ndarray:
        """Workspace points ``(..., 2)`` as ``(n, 2)`` pixel coordinates (x right, y down)."""
        pts = np.asarray(pts, float).reshape(-1, 2)
        x = self.border + (pts[:, 0] - self.view[0]) * self.scale
        y = self.header + self.border + (self.view[3] - pts[:, 1]) * self.scale
        return np.stack([x, y], axis=1)

    @property
    def workspace_rows(self) -> slice:
        """The pixel rows between the header and the legend."""
        return slice(self.header, self.height_px - self.footer)

    # -- drawing primitives (anti-aliased) ------------------------------------
    @staticmethod
    def disc(s: pygame.Surface, color, c, r: float) -> None:
        pygame.draw.aacircle(s, color, (float(c[0]), float(c[1])), max(1.0, float(r)))

    @staticmethod
    def ring(s: pygame.Surface, color, c, r: float, width: int) -> None:
        pygame.draw.aacircle(s, color, (float(c[0]), float(c[1])), max(1.0, float(r)), width=max(1, int(width)))

    @staticmethod
    def polygon(s: pygame.Surface, color, pts) -> None:
        pts = [(float(x), float(y)) for x, y in pts]
        pygame.draw.polygon(s, color, pts)
        pygame.draw.aalines(s, color, True, pts)

    def _draw_background(self) -> pygame.Surface:
        s = pygame.Surface((self.width_px, self.height_px))
        s.fill(BACKGROUND)
        p = self.problem
        x0, y0, x1, y1 = self.view
        corners = self.to_px(np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]]))
        pygame.draw.polygon(s, WALL, [tuple(c) for c in corners], width=max(2, self.border // 2))
        (left, top), (right, bottom) = corners[3], corners[1]
        s.set_clip(pygame.Rect(int(math.floor(left)), int(math.floor(top)),
                               int(math.ceil(right - left)) + 1, int(math.ceil(bottom - top)) + 1))
        for ob in p.obstacles:  # clipped to the view (a cropped map's obstacles run past it)
            if isinstance(ob, Circle):
                self.disc(s, OBSTACLE, self.to_px(np.array(ob.center))[0], ob.radius * self.scale)
            else:
                self.polygon(s, OBSTACLE, self.to_px(ob.vertices))
        s.set_clip(None)
        if self.scale_length is not None:
            self._draw_ticks(s)
        self._draw_legend(s)
        return s

    def _draw_ticks(self, s: pygame.Surface) -> None:
        """Ticks every ``scale_length`` units, outward from the walls into the border."""
        step = self.scale_length
        n = self.border - max(2, self.border // 2) // 2
        if n < 2 or step * self.scale < 6:
            return
        w = max(1, self.border // 6)
        vx0, vy0, vx1, vy1 = self.view
        x0, y0 = self.to_px(np.array([vx0, vy0]))[0]
        x1, y1 = self.to_px(np.array([vx1, vy1]))[0]
        for k in range(1, int(math.floor((vx1 - vx0) / step + 1e-9)) + 1):
            x = round(x0 + k * step * self.scale)  # whole pixels: pygame truncates
            if x < x1 - 1:
                pygame.draw.line(s, SCALE, (x, y0), (x, y0 + n), w)
                pygame.draw.line(s, SCALE, (x, y1), (x, y1 - n), w)
        for k in range(1, int(math.floor((vy1 - vy0) / step + 1e-9)) + 1):
            y = round(y0 - k * step * self.scale)
            if y > y1 + 1:
                pygame.draw.line(s, SCALE, (x0, y), (x0 - n, y), w)
                pygame.draw.line(s, SCALE, (x1, y), (x1 + n, y), w)

    # -- text -----------------------------------------------------------------
    def text_line(self, s, text: str, row: int, *, right: bool = False, color=TEXT, width: int | None = None):
        """Draw ``text`` (cut to fit) on header line ``row`` (0 or 1), left- or right-aligned.

        Returns the width drawn [px].
        """
        room = self.width_px - 2 * self.border - 8 if width is None else width
        img = self.font.render(fit_text(self.font, text, room), True, color, BACKGROUND)
        y = self.pad + row * self.line_h
        x = self.width_px - self.border - 4 - img.get_width() if right else self.border + 4
        s.blit(img, (x, y))
        return img.get_width()

    # -- legend ---------------------------------------------------------------
    def _glyph_w(self) -> int:
        return int(round(self.font.get_ascent() * 1.1))

    def _layout_legend(self, items, width: int) -> list[list[tuple[str, str, int]]]:
        """Items in rows that fit ``width``: ``[(glyph, label, x), ...]`` per row."""
        rows: list[list[tuple[str, str, int]]] = []
        x0 = max(4, width // 60) + 4
        gw, gap = self._glyph_w(), self.font.size("  ")[0]
        x = x0
        for glyph, label in items:
            label = fit_text(self.font, label, width - 2 * x0 - gw - 4)
            w = gw + 4 + self.font.size(label)[0]
            if not rows or (x + w > width - x0 and x > x0):
                rows.append([])
                x = x0
            rows[-1].append((glyph, label, x))
            x += w + gap
        if self.scale_length is not None:  # right-aligned on the last row, or a row of its own
            label = self._scale_label()
            w = int(round(self.scale_length * self.scale)) + 6 + self.font.size(label)[0]
            if not rows or x + w > width - x0:
                rows.append([])
            rows[-1].append(("scale", label, max(x0, width - x0 - w)))
        return rows

    def _scale_label(self) -> str:
        v = self.scale_length
        return f"{v:g} unit{'s' if v != 1 else ''} (tick spacing)"

    def _draw_legend(self, s: pygame.Surface) -> None:
        gw = self._glyph_w()
        top = self.height_px - self.footer + 2
        for n, row in enumerate(self._legend_rows):
            y = top + n * self.line_h
            cy = y + self.font.get_ascent() / 2 + 1
            for glyph, label, x in row:
                if glyph == "scale":
                    bar = int(round(self.scale_length * self.scale))
                    th = max(3, self.line_h // 5)
                    self.scale_bar_rect = pygame.Rect(x, int(round(cy - th / 2)), bar, th)
                    s.fill(SCALE, self.scale_bar_rect)
                    cap = int(self.font.get_ascent() * 0.35)
                    for cx in (x, x + bar - th):
                        s.fill(SCALE, pygame.Rect(cx, int(round(cy)) - cap, th, 2 * cap))
                    s.blit(self.font.render(label, True, TEXT, BACKGROUND), (x + bar + 6, y))
                    continue
                self.draw_glyph(s, glyph, (x + gw / 2, cy), gw / 2)
                s.blit(self.font.render(label, True, TEXT, BACKGROUND), (x + gw + 4, y))

    def draw_glyph(self, s, glyph: str, c, r: float) -> None:
        """The legend's picture of ``glyph`` centred at ``c`` with radius ``r`` [px]."""
        if glyph == "robot":  # robots have a colour each: a disc of three robots' colours
            self.disc(s, OUTLINE, c, r)
            for k, col in enumerate(robot_colors(3)):
                a = [math.radians(90 + 120 * k + 10 * j) for j in range(13)]
                pygame.draw.polygon(s, col, [(c[0], c[1])] + [(c[0] + (r - 1) * math.cos(t),
                                                                 c[1] - (r - 1) * math.sin(t)) for t in a])
            self.ring(s, OUTLINE, c, r, 1)
        elif glyph == "start":
            self.ring(s, self.start_color, c, r, max(2, int(r / 3)))
        elif glyph == "target":
            self.disc(s, self.target_color, c, r)
        elif glyph == "trail":  # pale lines in robots' colours
            w = max(2, int(r / 3))
            for k, col in enumerate(robot_colors(3)):
                dy = (k - 1) * r * 0.6
                pygame.draw.aaline(s, tint(col), (c[0] - r, c[1] + r / 3 + dy), (c[0] + r, c[1] - r / 3 + dy), w)
        elif glyph == "contact":
            self.ring(s, CONTACT, c, r, max(2, int(r / 3)))
            self.disc(s, CONTACT, c, r / 2)
        elif glyph == "failed":
            self.disc(s, FAILED, c, r)
            self.ring(s, OUTLINE, c, r, 1)
            d = r * 0.6
            w = max(1, int(round(r / 4)))
            for sx in (-1, 1):
                pygame.draw.line(s, OUTLINE, (c[0] - d, c[1] - sx * d), (c[0] + d, c[1] + sx * d), w)
        else:
            raise ValueError(f"unknown legend glyph {glyph!r}")

    # -- output ---------------------------------------------------------------
    def surface(self) -> pygame.Surface:
        return self.background.copy()

    @staticmethod
    def to_array(s: pygame.Surface) -> np.ndarray:
        """The surface as an ``(H, W, 3) uint8`` array (a fresh copy)."""
        w, h = s.get_size()
        return np.frombuffer(pygame.image.tobytes(s, "RGB"), np.uint8).reshape(h, w, 3).copy()
