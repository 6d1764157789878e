"""Writing pictures and videos: atomic files, GIF with one shared palette, MP4.

Every writer goes through :func:`atomic_path`: the file appears under its
final name only once it is complete, so an interrupted or failing write never
leaves a half-written file and never destroys an older one.

Videos are streamed: frames are encoded one at a time into every format at
once (GIF and MP4 from one pass), so memory does not grow with the number
of frames.  GIF frames share one palette, computed once from the colours the
drawing is known to use and from frames spread over the whole video
(:func:`_shared_palette`); every frame is then mapped to it without
dithering and without a palette of its own, which is several times faster
than a per-frame adaptive palette and looks the same for flat-coloured
drawings.
"""

from __future__ import annotations

import importlib.util
import itertools
import logging
import math
import os
import secrets
import struct
from collections.abc import Callable, Iterable, Iterator, Sequence
from contextlib import ExitStack, contextmanager
from pathlib import Path

import numpy as np

__all__ = [
    "GIF_MAX_FPS",
    "atomic_path",
    "gif_durations",
    "has_mp4",
    "write_gif",
    "write_mp4",
    "write_png",
    "write_video",
]

GIF_MAX_FPS = 50
"""GIF frame delays are whole centiseconds, and browsers slow down delays under 20 ms."""

_PALETTE_SIZE = 255  # colours in the palette; one index is left for transparency
_EXACT_COLOURS = 160  # colours of the largest flat areas, kept exactly
_REST_WEIGHT = 64  # the most a colour counts in the median cut of the others
_SAMPLE_FRAMES = 60  # frames looked at for the palette, spread over the video
_SAMPLE_BYTES = 256 << 20  # the most frames of a one-shot iterator held for the palette [bytes]
_MP4_QUALITY = 6  # imageio-ffmpeg quality 0..10; 6 is x264 crf 20


@contextmanager
def atomic_path(path: str | Path):
    """Yield a temporary path beside ``path``; move it into place on success.

    Nothing half-written is ever left under the final name: on an error the
    temporary file is removed and an existing file at ``path`` is kept.  The
    file gets the permissions of a newly created file (``0o666`` less the
    umask), not the owner-only ones of a temporary file.  The temporary is
    ``.NAME.tmp-PID-XXXXXXXX``; those of the same name whose process is gone
    (killed before it could clean up) are removed first
    (:func:`sim.outputs.remove_stale`).
    """
    from .outputs import remove_stale, temp_name

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    remove_stale(path.parent, (path.name,))
    while True:
        tmp = path.parent / temp_name(path.name, secrets.token_hex(4))
        try:
            os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600))
            break
        except FileExistsError:
            continue
    try:
        yield Path(tmp)
        os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        raise


def _umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def write_png(path: str | Path, image: np.ndarray) -> Path:
    """Write an ``(H, W, 3) uint8`` image as PNG, atomically."""
    import imageio.v3 as iio

    with atomic_path(path) as tmp:
        iio.imwrite(tmp, np.ascontiguousarray(image), extension=".png")
    return Path(path)


# ----------------------------------------------------------------------------
# GIF


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


def write_gif(
    path: str | Path, frames: Iterable[np.ndarray], fps: float, *, colours: np.ndarray | None = None
) -> Path:
    """Write ``(H, W, 3) uint8`` frames as a GIF that loops forever, atomically.

    fps: frames per second, in ``(0, GIF_MAX_FPS]``.
    frames, colours: see :func:`write_video`.

    All frames share one palette of at most 256 colours (see the module
    docstring).  Identical consecutive frames are stored once, with their
    delays summed, so the total duration is kept.
    """
    fps = _check_fps(fps, GIF_MAX_FPS)
    path = Path(path)
    _write({"gif": path}, frames, fps, colours, None)
    return path


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


def has_mp4() -> bool:
    """Whether MP4 can be written (imageio-ffmpeg, which ships ffmpeg, is installed)."""
    return importlib.util.find_spec("imageio_ffmpeg") is not None


def write_mp4(path: str | Path, frames: Iterable[np.ndarray], fps: float) -> Path | None:
    """Write ``(H, W, 3) uint8`` frames (H and W even) as H.264 MP4, atomically.

    The video is ``libx264``, ``yuv420p`` (plays everywhere), at ``fps``
    frames per second.  Frames are streamed to ffmpeg, not held in memory.
    Returns None, and consumes nothing, when imageio-ffmpeg is not installed.
    """
    fps = _check_fps(fps, math.inf)
    if not has_mp4():
        return None
    path = Path(path)
    _write({"mp4": path}, frames, fps, None, None)
    return path


class _Mp4Writer:
    """Streams frames to ffmpeg (through imageio-ffmpeg), started by the first frame."""

    def __init__(self, path: Path, fps: float):
        self.path, self.fps = path, fps
        self._gen = None

    def add(self, frame: np.ndarray) -> None:
        if self._gen is None:
            from .outputs import signals_held

            h, w = frame.shape[:2]
            if h % 2 or w % 2:
                raise ValueError(f"MP4 (yuv420p) frames need even height and width, got {(h, w)}")
            # ffmpeg starts with the signals held: an interrupt between its
            # start and the generator's cleanup block would leave it running
            # (and writing into a folder already removed).
            with signals_held():
                self._gen = self._start(w, h)
                self._gen.send(None)
        self._gen.send(frame)

    def _start(self, w: int, h: int):
        # imageio-ffmpeg directly rather than through imageio's writer: that
        # one is only closed by the garbage collector after an error, so
        # ffmpeg could still be writing the temporary file after it has been
        # removed.
        import imageio_ffmpeg

        return imageio_ffmpeg.write_frames(
            str(self.path),
            (w, h),
            fps=self.fps,
            codec="libx264",
            pix_fmt_out="yuv420p",
            quality=_MP4_QUALITY,
            macro_block_size=1,
            ffmpeg_log_level="fatal",  # an interrupted pipe is not worth a line of its own
            output_params=["-preset", "veryfast", "-movflags", "+faststart"],
        )

    def close(self, check: bool = True) -> None:
        """Wait for ffmpeg to finish (also after an error); idempotent.

        check: raise when ffmpeg wrote nothing.  Off on the error path, so
        that an interrupt or an earlier error is what the caller sees, not
        the empty file it left.
        """
        if self._gen is not None:
            gen, self._gen = self._gen, None
            # imageio-ffmpeg warns on stderr when it is closed before the
            # first frame (an interrupt there): the check below says it instead.
            log = logging.getLogger("imageio_ffmpeg")
            level = log.level
            log.setLevel(logging.ERROR)
            try:
                gen.close()
            finally:
                log.setLevel(level)
            if check and self.path.stat().st_size == 0:
                raise OSError(f"ffmpeg wrote nothing to {self.path}")


# ----------------------------------------------------------------------------
# several formats from one frame stream


def write_video(
    path_stem: str | Path,
    frames: Iterable[np.ndarray],
    fps: float,
    formats: Iterable[str],
    *,
    colours: np.ndarray | None = None,
    progress: Callable[[float], None] | None = None,
) -> list[Path]:
    """Write the frames once per format, to ``path_stem`` + ``.gif`` / ``.mp4``.

    formats: any of ``gif`` and ``mp4``; MP4 is skipped when imageio-ffmpeg
        is not installed.
    frames: ``(H, W, 3) uint8`` arrays, all the same shape.  Every format is
        written in one pass over them, frame by frame, so memory does not
        grow with the number of frames.  For the GIF's shared palette, a
        sequence (``len`` and indexing, such as what
        :func:`sim.render.render_frames` returns) is sampled over the whole
        video first, one frame at a time; of a one-shot iterator the first
        60 frames (at most 256 MB of them) are held and sampled.
    colours: ``(n, 3) uint8`` colours kept exactly in the GIF palette, most
        important first (default: the ``colours`` attribute of ``frames``,
        if any).
    progress: called with the fraction of frames written, when the number
        of frames is known.

    Returns the paths written, in the order of ``formats``.  Nothing is left
    under a final name unless every file was written.
    """
    formats = list(dict.fromkeys(formats))
    unknown = [f for f in formats if f not in ("gif", "mp4")]
    if unknown:
        raise ValueError(f"formats must be gif and/or mp4, got {unknown[0]!r}")
    stem = Path(path_stem)
    fps = _check_fps(fps, GIF_MAX_FPS if "gif" in formats else math.inf)
    targets = {f: stem.with_name(stem.name + "." + f) for f in formats if f == "gif" or has_mp4()}
    if targets:
        _write(targets, frames, fps, colours, progress)
    return list(targets.values())


def _write(targets: dict[str, Path], frames, fps: float, colours, progress) -> None:
    """Stream ``frames`` into every target format at once, each file atomically."""
    total = len(frames) if isinstance(frames, (Sequence, np.ndarray)) else None
    with ExitStack() as stack:
        writers = []
        if "gif" in targets:
            palette, stream = _palette_and_stream(frames, colours)
            tmp = stack.enter_context(atomic_path(targets["gif"]))
            gif = _GifWriter(stack.enter_context(open(tmp, "wb")), palette, fps)
            writers.append(gif)
        else:
            stream = iter(frames)
        if "mp4" in targets:
            mp4 = _Mp4Writer(stack.enter_context(atomic_path(targets["mp4"])), fps)
            stack.callback(mp4.close, check=False)  # ffmpeg is waited for, also after an error
            writers.append(mp4)
        shape = None
        n = 0
        for n, f in enumerate(stream, 1):
            f = _check_frame(f, n - 1, shape)
            shape = f.shape
            for w in writers:
                w.add(f)
            if progress is not None and total:
                progress(n / total)
        if n == 0:
            raise ValueError("frames must hold at least one frame, got none")
        for w in writers:
            w.close()


# ----------------------------------------------------------------------------
# checks


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
