"""pygame-ce without a screen or a sound card: the drawing modules import it from here.

SDL reads its drivers when pygame is first imported, so the dummy video and
audio drivers are set before that import (a value the user set wins).  No
window is ever opened; surfaces and fonts need none.
"""

from __future__ import annotations

import os

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("SDL_AUDIODRIVER", "dummy")
os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")

import pygame  # noqa: E402
import pygame.freetype  # noqa: E402

__all__ = ["pygame"]
