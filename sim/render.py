"""Off-screen drawing with pygame-ce: scenario pictures and video frames.

Drawing is kept apart from the model: a :class:`Canvas` takes read-only
positions and returns ``(H, W, 3) uint8`` arrays; writing files is
:mod:`sim.media`'s job.  No window is ever opened (``SDL_VIDEODRIVER=dummy``).
"""

from __future__ import annotations

import os

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("SDL_AUDIODRIVER", "dummy")
os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")

import numpy as np  # noqa: E402
import pygame  # noqa: E402

from planner.problem import Circle, Problem  # noqa: E402

__all__ = ["Canvas", "draw_scenario"]

BACKGROUND = (248, 248, 244)
WALL = (40, 40, 48)
OBSTACLE = (96, 100, 112)
START = (40, 90, 200)
TARGET = (236, 120, 40)
TARGET_MARK = (250, 200, 160)
TEXT = (20, 20, 24)
CONTACT = (230, 20, 20)
TRAIL = (150, 170, 220)


def _palette(m: int) -> list[tuple[int, int, int]]:
    """Distinct, mid-saturation robot colours (golden-ratio hues)."""
    out = []
    for i in range(m):
        h = (i * 0.61803398875) % 1.0
        c = pygame.Color(0)
        c.hsva = (h * 360.0, 55.0, 85.0, 100.0)
        out.append((c.r, c.g, c.b))
    return out


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
