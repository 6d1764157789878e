"""Text rendered off-screen into a glyph mask (pygame-ce fonts, no window).

:func:`render_text` draws one or more lines of text with a TrueType font
(default: the font pygame-ce ships, ``pygame.font.get_default_font()``) and
returns a :class:`Glyphs` record: a boolean ink mask in y-up pixel
coordinates and the box of every visible character.  The planner's samplers
take it from there as plain data (:mod:`planner.skeleton` turns the mask
into strokes, :mod:`planner.area` fills it).

Limits (so that time and memory stay bounded): at most :data:`MAX_CHARS`
characters on at most :data:`MAX_LINES` lines; a font file is a regular
file of at most :data:`MAX_FONT_BYTES` bytes that loads as a font and has a
glyph for every character of the text.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .._pygame import pygame

__all__ = [
    "GlyphError",
    "Glyphs",
    "MAX_CHARS",
    "MAX_FONT_BYTES",
    "MAX_LINES",
    "PIXELS",
    "check_font",
    "check_text",
    "render_text",
]

MAX_CHARS = 40  # characters of a text formation, line breaks included
MAX_LINES = 4
MAX_FONT_BYTES = 16 * 1024 * 1024
PIXELS = 96  # font size of the rendering [px]; capitals are about 0.7 of it


class GlyphError(ValueError):
    """Text or font that cannot be rendered; ``field`` is ``text`` or ``font``."""

    def __init__(self, field: str, reason: str):
        super().__init__(f"{field}: {reason}")
        self.field = field
        self.reason = reason


@dataclass(frozen=True, eq=False)
class Glyphs:
    """Rendered text.

    mask: ``(H, W)`` bool ink mask, row 0 at the *bottom* (y up), cropped to
        the ink with one pixel of border; pixel ``(row, col)`` covers
        ``[col, col + 1] x [row, row + 1]``.
    boxes: for every visible character (spaces and line breaks have none):
        ``(char, x0, y0, x1, y1)`` in the mask's pixel coordinates (its
        advance box: where the font puts that character on its line).
    text: the rendered text; font: the font file (None: pygame-ce's own).
    """

    mask: np.ndarray
    boxes: tuple[tuple[str, float, float, float, float], ...]
    text: str
    font: str | None


def _short(value: str, limit: int = 80) -> str:
    r = repr(value)
    return r if len(r) <= limit else r[: limit - 3] + "..."


def check_text(text) -> str:
    """The text, or :class:`GlyphError` unless it is 1 to 40 printable characters on 1 to 4 lines."""
    if not isinstance(text, str):
        raise GlyphError("text", f"must be a string, got {type(text).__name__}")
    if not text.strip():
        raise GlyphError("text", "must hold at least one visible character")
    if len(text) > MAX_CHARS:
        raise GlyphError("text", f"must be at most {MAX_CHARS} characters, got {len(text)}: {_short(text)}")
    lines = text.split("\n")
    if len(lines) > MAX_LINES:
        raise GlyphError("text", f"must be at most {MAX_LINES} lines, got {len(lines)}")
    for ch in text:
        if ch != "\n" and not ch.isprintable():
            raise GlyphError("text", f"holds the control character {ch!r}; use printable characters and \\n")
    return text


def check_font(path: str | Path) -> Path:
    """The font path, or :class:`GlyphError` unless it is a readable regular file of at most 16 MiB."""
    if "\x00" in str(path):
        raise GlyphError("font", "holds a NUL character (\\0), which no file path can hold")
    p = Path(path)
    try:
        st = p.stat()
    except FileNotFoundError:
        raise GlyphError("font", f"no such file: {_short(str(p))}") from None
    except OSError as exc:
        raise GlyphError("font", f"cannot be read ({exc.__class__.__name__}): {_short(str(p))}") from None
    import stat

    if not stat.S_ISREG(st.st_mode):
        raise GlyphError("font", f"is not a regular file: {_short(str(p))}")
    if st.st_size > MAX_FONT_BYTES:
        raise GlyphError("font", f"is {st.st_size} bytes; a font file may have at most {MAX_FONT_BYTES}")
    if st.st_size == 0:
        raise GlyphError("font", f"is empty: {_short(str(p))}")
    return p


def _load(font: str | None, size: int):
    """The pygame font (for rendering) and the freetype font (for glyph coverage)."""
    if not pygame.font.get_init():
        pygame.font.init()
    if not pygame.freetype.get_init():
        pygame.freetype.init()
    path = None if font is None else str(check_font(font))
    try:
        return pygame.font.Font(path, size), pygame.freetype.Font(path, size)
    except (pygame.error, OSError, ValueError, RuntimeError) as exc:
        raise GlyphError("font", f"does not load as a font ({' '.join(str(exc).split())[:60]}): "
                         f"{_short(str(font))}") from None


def render_text(text: str, font: str | Path | None = None, size: int = PIXELS) -> Glyphs:
    """Render ``text`` (``\\n`` separates lines, centred) into a :class:`Glyphs` mask.

    Raises :class:`GlyphError` for text outside the limits, a font that is
    not a loadable font file, or a character the font has no glyph for.
    """
    text = check_text(text)
    font = None if font is None else str(font)
    pf, ff = _load(font, size)
    for ch in sorted(set(text) - {"\n", " "}):
        if ff.get_metrics(ch)[0] is None:
            raise GlyphError("text", f"the font has no glyph for {ch!r} (U+{ord(ch):04X})")
    lines = text.split("\n")
    line_h = pf.get_linesize()
    widths = [max(pf.size(line)[0], 1) for line in lines]
    width = max(widths)
    height = line_h * len(lines)
    canvas = pygame.Surface((width, height))
    canvas.fill((0, 0, 0))
    boxes = []
    for n, (line, w) in enumerate(zip(lines, widths)):
        x0 = (width - w) // 2
        y0 = n * line_h
        if line:
            canvas.blit(pf.render(line, False, (255, 255, 255), (0, 0, 0)), (x0, y0))
        for i, ch in enumerate(line):
            if ch.isspace():
                continue
            a, b = pf.size(line[:i])[0], pf.size(line[: i + 1])[0]
            boxes.append((ch, x0 + a, y0, x0 + b, y0 + line_h))
    rgb = np.frombuffer(pygame.image.tobytes(canvas, "RGB"), np.uint8).reshape(height, width, 3)
    ink = rgb[:, :, 0] > 127
    if not ink.any():
        raise GlyphError("text", f"renders no ink: {_short(text)}")
    rows = np.flatnonzero(ink.any(axis=1))
    cols = np.flatnonzero(ink.any(axis=0))
    r0, r1 = rows[0] - 1, rows[-1] + 2
    c0, c1 = cols[0] - 1, cols[-1] + 2
    pad = np.zeros((height + 2, width + 2), bool)
    pad[1:-1, 1:-1] = ink
    crop = pad[r0 + 1 : r1 + 1, c0 + 1 : c1 + 1]
    h = crop.shape[0]
    mask = crop[::-1].copy()  # y up
    # boxes: x shifted by the crop, y flipped (top of the canvas is row r0)
    out = tuple(
        (ch, float(a - c0), float(r1 - y1), float(b - c0), float(r1 - y0)) for ch, a, y0, b, y1 in boxes
    )
    assert mask.shape[0] == h
    mask.setflags(write=False)
    return Glyphs(mask, out, text, font)
