"""GIF writing: one palette shared by every frame (the flat areas kept exactly, a median cut of the rest), streamed."""

from __future__ import annotations

import itertools
import math
import struct
from collections.abc import Iterator, Sequence

import numpy as np

__all__ = ["GIF_MAX_FPS", "gif_durations"]


GIF_MAX_FPS = 50
"""GIF frame delays are whole centiseconds, and browsers slow down delays under 20 ms."""

_PALETTE_SIZE = 255  # colours in the palette; one index is left for transparency
_EXACT_COLOURS = 160  # colours of the largest flat areas, kept exactly
_REST_WEIGHT = 64  # the most a colour counts in the median cut of the others
_SAMPLE_FRAMES = 60  # frames looked at for the palette, spread over the video
_SAMPLE_BYTES = 256 << 20  # the most frames of a one-shot iterator held for the palette [bytes]
def gif_durations(n: int, fps: float) -> list[int]:
    """Per-frame GIF delays [ms] for ``n`` frames at ``fps``.

    GIF stores whole centiseconds; the delays are rounded cumulatively, so
    the total is ``n / fps`` to within 10 ms even when ``100 / fps`` is not a
    whole number (30 fps gives 30, 40, 30, 30, 40, ... ms).
    """
    return [10 * _delay_cs(k, fps) for k in range(n)]


def _delay_cs(k: int, fps: float) -> int:
    """The delay of frame ``k`` [cs] (see :func:`gif_durations`)."""
    return round((k + 1) * 100.0 / fps) - round(k * 100.0 / fps)


class _GifWriter:
    """Streams index frames into a GIF file: a few frames in memory, whatever the length.

    The header and the shared colour table are written first; each frame is
    then stored as the box of pixels that changed since the frame before,
    unchanged pixels in the box marked with the free index ``len(palette)``
    (transparent; frames are left in place).  A frame equal to the one
    before only lengthens that one's delay.
    """

    _MAX_DELAY_CS = 65535  # a GIF delay field is 16 bits

    def __init__(self, fh, palette: np.ndarray, fps: float):
        from PIL import Image

        self.fh, self.fps = fh, fps
        self.free = len(palette)
        self._pal_img = Image.new("P", (1, 1))
        self._pal_img.putpalette(palette.tobytes())
        bits = max(1, math.ceil(math.log2(self.free + 1)))
        self._table = palette.tobytes() + bytes(3 * ((1 << bits) - self.free))
        self._bits = bits
        self.count = 0
        self._pending: list | None = None  # [index frame, delay in cs]
        self._shown: np.ndarray | None = None  # what a viewer shows after the frames written

    def add(self, frame: np.ndarray) -> None:
        from PIL import Image

        idx = np.asarray(Image.fromarray(frame).quantize(palette=self._pal_img, dither=Image.Dither.NONE))
        if self.count == 0:
            h, w = idx.shape
            self.fh.write(b"GIF89a" + struct.pack("<HHBBB", w, h, 0xF0 | (self._bits - 1), 0, 0) + self._table)
            self.fh.write(b"!\xff\x0bNETSCAPE2.0\x03\x01\x00\x00\x00")  # loop forever
        delay = _delay_cs(self.count, self.fps)
        self.count += 1
        p = self._pending
        if p is not None and p[1] + delay <= self._MAX_DELAY_CS and np.array_equal(idx, p[0]):
            p[1] += delay
            return
        if p is not None:
            self._write(*p)
        self._pending = [idx, delay]

    def close(self) -> None:
        if self._pending is not None:
            self._write(*self._pending)
            self._pending = None
        self.fh.write(b";")

    def _write(self, idx: np.ndarray, delay_cs: int) -> None:
        from PIL import GifImagePlugin, Image

        params = {"duration": 10 * delay_cs, "disposal": 1}
        if self._shown is None:
            box, x0, y0 = idx, 0, 0
        else:
            changed = idx != self._shown
            rows, cols = np.flatnonzero(changed.any(axis=1)), np.flatnonzero(changed.any(axis=0))
            if len(rows) == 0:  # the same picture again (a delay too long for one frame)
                box, x0, y0 = np.full((1, 1), self.free, np.uint8), 0, 0
            else:
                y0, y1, x0, x1 = rows[0], rows[-1] + 1, cols[0], cols[-1] + 1
                box = np.where(changed[y0:y1, x0:x1], idx[y0:y1, x0:x1], np.uint8(self.free))
            params["transparency"] = self.free
        data = GifImagePlugin.getdata(Image.fromarray(np.ascontiguousarray(box), "L"),
                                      offset=(int(x0), int(y0)), **params)
        self.fh.write(b"".join(data))
        self._shown = idx


def _palette_and_stream(frames, colours) -> tuple[np.ndarray, Iterator[np.ndarray]]:
    """The shared palette, and the frames to encode (all of them, in order).

    A sequence (``len`` and indexing) is sampled over its whole length, one
    frame drawn at a time (none of them is kept); from a one-shot iterator
    the first ``_SAMPLE_FRAMES`` frames, but no more than ``_SAMPLE_BYTES``
    of them (at least one), are held and sampled.
    """
    if colours is None:
        colours = getattr(frames, "colours", None)
    if isinstance(frames, (Sequence, np.ndarray)):
        n = len(frames)
        if n == 0:
            raise ValueError("frames must hold at least one frame, got none")
        picks = [int(k) for k in np.unique(np.linspace(0, n - 1, min(n, _SAMPLE_FRAMES)).round())]
        sample = _Checked(frames, picks)
        stream = iter(frames)
    else:
        it = iter(frames)
        held: list[np.ndarray] = []
        size = 0
        for f in it:
            held.append(f)
            size += np.asarray(f).nbytes
            if len(held) >= _SAMPLE_FRAMES or size >= _SAMPLE_BYTES:
                break
        if not held:
            raise ValueError("frames must hold at least one frame, got none")
        sample = _Checked(held, range(len(held)))
        stream = itertools.chain(held, it)
    return _shared_palette(sample, colours), stream


class _Checked(Sequence):
    """Frames ``picks`` of ``frames``, each checked (and drawn, if lazy) when asked for."""

    def __init__(self, frames, picks):
        self._frames, self._picks = frames, list(picks)
        self._shape = None

    def __len__(self) -> int:
        return len(self._picks)

    def __getitem__(self, j):
        k = self._picks[j]
        f = _check_frame(self._frames[k], k, self._shape)
        self._shape = f.shape
        return f


def _shared_palette(frames: Sequence[np.ndarray], colours: np.ndarray | None = None) -> np.ndarray:
    """One palette ``(n, 3) uint8`` (n <= 255, no repeated colour) for all frames.

    ``frames`` is a sample of the video (the first and last frames in full,
    every other row and column of the others are counted); ``colours`` are
    colours known to be drawn, most important first.  If there are at most
    255 colours in all, they are the palette.  Otherwise the known colours
    and then the colours that fill the largest areas (counted where a
    sampled pixel equals its right and lower neighbours: background,
    obstacles, discs, trails) are kept exactly, up to ``_EXACT_COLOURS``, and
    the others (anti-aliased edges and text) are reduced by median cut with
    a short k-means refinement, each counted at most ``_REST_WEIGHT`` times
    so that large areas do not crowd out small details.

    The frames are asked for one at a time and only their colour counts are
    kept, so memory holds one frame, whatever the sample's length and size.

    Index ``n`` stays free and inside the GIF colour table (whose size is a
    power of two): the encoder marks unchanged pixels with it.
    """
    from PIL import Image

    known = np.zeros(0, np.uint32)
    if colours is not None and len(colours):
        known = _pack(np.asarray(colours, np.uint8).reshape(-1, 3))
        known = known[np.sort(np.unique(known, return_index=True)[1])][:_EXACT_COLOURS]
    n = len(frames)
    colours_seen, counts = np.zeros(0, np.uint32), np.zeros(0, np.int64)
    flat_colours, flat_counts = np.zeros(0, np.uint32), np.zeros(0, np.int64)
    for j in range(n):
        f = frames[j]
        g = f if j in (0, n - 1) else f[::2, ::2]
        p = _pack(g.reshape(-1, 3)).reshape(g.shape[:2])
        del f, g
        colours_seen, counts = _add_counts(colours_seen, counts, *np.unique(p, return_counts=True))
        inner = p[:-1, :-1]
        flat = inner[(inner == p[1:, :-1]) & (inner == p[:-1, 1:])]
        flat_colours, flat_counts = _add_counts(flat_colours, flat_counts, *np.unique(flat, return_counts=True))
        del p, inner, flat
    every = np.union1d(colours_seen, known)
    if len(every) <= _PALETTE_SIZE:
        return _with_free_index(every)
    by_area = flat_colours[np.argsort(-flat_counts, kind="stable")]
    exact = np.sort(np.concatenate([known, by_area[~np.isin(by_area, known)]])[:_EXACT_COLOURS])
    rest = ~np.isin(colours_seen, exact)
    if not rest.any():
        return _with_free_index(exact)
    rest_px = _unpack(np.repeat(colours_seen[rest], np.minimum(counts[rest], _REST_WEIGHT)))
    q = Image.fromarray(rest_px[None]).quantize(
        _PALETTE_SIZE - len(exact), method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE, kmeans=2
    )
    used = np.unique(np.asarray(q))
    reduced = np.asarray(q.getpalette()[: 3 * (int(used.max()) + 1)], np.uint8).reshape(-1, 3)[used]
    extra = np.setdiff1d(_pack(reduced), exact)
    return _with_free_index(np.concatenate([exact, extra])[:_PALETTE_SIZE])


def _add_counts(values, counts, new_values, new_counts):
    """Merge two (sorted unique values, counts) tallies into one."""
    if len(values) == 0:
        return new_values.astype(np.uint32), new_counts.astype(np.int64)
    u, inv = np.unique(np.concatenate([values, new_values]), return_inverse=True)
    return u, np.bincount(inv.reshape(-1), weights=np.concatenate([counts, new_counts]),
                          minlength=len(u)).astype(np.int64)


def _with_free_index(packed: np.ndarray) -> np.ndarray:
    """The colours, plus unused ones while their count is a power of two."""
    packed = list(packed)
    used = set(packed)
    spare = (v for v in range(1 << 24) if v not in used)
    while len(packed) & (len(packed) - 1) == 0:
        packed.append(next(spare))
    return _unpack(np.array(packed, np.uint32))


def _pack(rgb: np.ndarray) -> np.ndarray:
    """``(n, 3) uint8`` colours as ``(n,) uint32`` (0xRRGGBB)."""
    rgb = rgb.astype(np.uint32)
    return (rgb[:, 0] << 16) | (rgb[:, 1] << 8) | rgb[:, 2]


def _unpack(packed: np.ndarray) -> np.ndarray:
    p = np.asarray(packed, np.uint32)
    return np.stack([p >> 16, (p >> 8) & 255, p & 255], axis=1).astype(np.uint8)


# ----------------------------------------------------------------------------
# MP4


def _check_fps(fps, upper: float) -> float:
    try:
        ok = 0 < float(fps) <= upper
    except (TypeError, ValueError):
        ok = False
    if not ok:
        bound = f"(0, {upper:g}]" if math.isfinite(upper) else "(0, inf)"
        raise ValueError(f"fps must be a number in {bound}, got {fps!r}")
    return float(fps)


def _check_frame(f, n: int, shape: tuple | None) -> np.ndarray:
    f = np.asarray(f)
    if f.dtype != np.uint8 or f.ndim != 3 or f.shape[2] != 3:
        raise ValueError(f"frames[{n}] must be an (H, W, 3) uint8 array, got {f.dtype} {f.shape}")
    if shape is not None and f.shape != shape:
        raise ValueError(f"frames[{n}] has shape {f.shape}, the first frame {shape}")
    return np.ascontiguousarray(f)
