"""Writing pictures and videos: atomic files, GIF with one shared palette, MP4.

Every writer goes through :func:`atomic_path`: the file appears under its
final name only once it is complete, so an interrupted or failing write never
leaves a half-written file and never destroys an older one.

GIF frames share one palette, computed once from the colours of frames
spread over the whole video (:func:`_shared_palette`); every frame is then
mapped to it without dithering and without a palette of its own, which is
several times faster than a per-frame adaptive palette and looks the same
for flat-coloured drawings.
"""

from __future__ import annotations

import importlib.util
import math
import os
import secrets
from collections.abc import Iterable, Sequence
from contextlib import contextmanager
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
    edges = [round(k * 100.0 / fps) for k in range(n + 1)]
    return [10 * (b - a) for a, b in zip(edges, edges[1:])]


def write_gif(path: str | Path, frames: Iterable[np.ndarray], fps: float) -> Path:
    """Write ``(H, W, 3) uint8`` frames as a GIF that loops forever, atomically.

    fps: frames per second, in ``(0, GIF_MAX_FPS]``.

    All frames share one palette of at most 256 colours (see the module
    docstring).  Identical consecutive frames are stored once, with their
    delays summed, so the total duration is kept.
    """
    fps = _check_fps(fps, GIF_MAX_FPS)
    frames = _materialise(frames)
    _write_gif(Path(path), frames, fps)
    return Path(path)


def _write_gif(path: Path, frames: Sequence[np.ndarray], fps: float) -> None:
    import imageio.v3 as iio
    from PIL import Image

    palette = _shared_palette(frames)
    pal_img = Image.new("P", (1, 1))
    pal_img.putpalette(palette.tobytes())
    none = Image.Dither.NONE
    index = np.empty((len(frames), *frames[0].shape[:2]), np.uint8)
    for k, f in enumerate(frames):
        index[k] = np.asarray(Image.fromarray(f).quantize(palette=pal_img, dither=none))
    delays = gif_durations(len(frames), fps)
    # Index frames go in as "L" images with the palette given once: Pillow
    # then keeps the indices as they are (the palette has no repeated colour)
    # instead of building an adaptive palette for every frame.  With
    # ``optimize`` it stores only the changed box of each frame and marks the
    # unchanged pixels in it with the free index ``len(palette)``.
    with atomic_path(path) as tmp:
        iio.imwrite(
            tmp,
            index,
            extension=".gif",
            plugin="pillow",
            mode="L",
            is_batch=True,
            duration=delays if len(delays) > 1 else delays[0],
            loop=0,
            palette=palette.tobytes(),
            optimize=True,  # unchanged pixels of a frame become transparent
        )


def _shared_palette(frames: Sequence[np.ndarray]) -> np.ndarray:
    """One palette ``(n, 3) uint8`` (n <= 255, no repeated colour) for all frames.

    The colours of up to ``_SAMPLE_FRAMES`` frames spread evenly over the
    video are counted (every pixel of the first and last frame, every other
    row and column of the others).  If there are at most 256, they are the
    palette.  Otherwise the ``_EXACT_COLOURS`` colours that fill the largest
    areas (counted where a sampled pixel equals its right and lower
    neighbours: background, obstacles, discs, trails) are kept exactly, and
    the others (antialiased edges and text) are reduced by median cut with a
    short k-means refinement, each counted at most ``_REST_WEIGHT`` times so
    that large areas do not crowd out small details.

    Index ``n`` stays free and inside the GIF colour table (whose size is a
    power of two): the encoder marks unchanged pixels with it.
    """
    from PIL import Image

    n = len(frames)
    picks = np.unique(np.linspace(0, n - 1, min(n, _SAMPLE_FRAMES)).round().astype(int))
    grids = [frames[0], frames[-1]] + [frames[k][::2, ::2] for k in picks[1:-1]]
    packed = [_pack(g.reshape(-1, 3)).reshape(g.shape[:2]) for g in grids]
    colours, counts = np.unique(np.concatenate([p.ravel() for p in packed]), return_counts=True)
    if len(colours) <= _PALETTE_SIZE:
        return _with_free_index(colours)
    flat = np.concatenate(
        [p[:-1, :-1][(p[:-1, :-1] == p[1:, :-1]) & (p[:-1, :-1] == p[:-1, 1:])] for p in packed]
    )
    flat_colours, flat_counts = np.unique(flat, return_counts=True)
    order = np.argsort(-flat_counts, kind="stable")[:_EXACT_COLOURS]
    exact = np.sort(flat_colours[order])
    rest = ~np.isin(colours, exact)
    rest_px = _unpack(np.repeat(colours[rest], np.minimum(counts[rest], _REST_WEIGHT)))
    q = Image.fromarray(rest_px[None]).quantize(
        _PALETTE_SIZE - len(exact), method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE, kmeans=2
    )
    used = np.unique(np.asarray(q))
    reduced = np.asarray(q.getpalette()[: 3 * (int(used.max()) + 1)], np.uint8).reshape(-1, 3)[used]
    extra = np.setdiff1d(_pack(reduced), exact)
    return _with_free_index(np.concatenate([exact, extra])[:_PALETTE_SIZE])


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
    _write_mp4(Path(path), iter(frames), fps)
    return Path(path)


def _write_mp4(path: Path, frames: Iterable[np.ndarray], fps: float) -> None:
    # imageio-ffmpeg directly rather than through imageio's writer: that one
    # is only closed by the garbage collector after an error, so ffmpeg could
    # still be writing the temporary file after it has been removed.
    import imageio_ffmpeg

    with atomic_path(path) as tmp:
        writer = None
        shape = None
        try:
            for n, f in enumerate(frames):
                f = _check_frame(f, n, shape)
                if writer is None:
                    shape = f.shape
                    if shape[0] % 2 or shape[1] % 2:
                        raise ValueError(f"MP4 (yuv420p) frames need even height and width, got {shape[:2]}")
                    writer = imageio_ffmpeg.write_frames(
                        str(tmp),
                        (shape[1], shape[0]),
                        fps=fps,
                        codec="libx264",
                        pix_fmt_out="yuv420p",
                        quality=_MP4_QUALITY,
                        macro_block_size=1,
                        ffmpeg_log_level="error",
                        output_params=["-preset", "veryfast", "-movflags", "+faststart"],
                    )
                    writer.send(None)
                writer.send(f)
        finally:
            if writer is not None:
                writer.close()  # waits for ffmpeg to finish
        if writer is None:
            raise ValueError("frames must hold at least one frame, got none")
        if tmp.stat().st_size == 0:
            raise OSError(f"ffmpeg wrote nothing to {path}")


# ----------------------------------------------------------------------------
# several formats from one frame stream


def write_video(
    path_stem: str | Path, frames: Iterable[np.ndarray], fps: float, formats: Iterable[str]
) -> list[Path]:
    """Write the frames once per format, to ``path_stem`` + ``.gif`` / ``.mp4``.

    formats: any of ``gif`` and ``mp4``.  ``frames`` is consumed once; it is
    held in memory when a GIF is asked for (the shared palette needs frames
    from the whole video) and streamed otherwise.  MP4 is skipped when
    imageio-ffmpeg is not installed.  Returns the paths written, in the order
    of ``formats``.
    """
    formats = list(dict.fromkeys(formats))
    unknown = [f for f in formats if f not in ("gif", "mp4")]
    if unknown:
        raise ValueError(f"formats must be gif and/or mp4, got {unknown[0]!r}")
    stem = Path(path_stem)
    fps = _check_fps(fps, GIF_MAX_FPS if "gif" in formats else math.inf)
    mp4 = "mp4" in formats and has_mp4()
    if "gif" not in formats:
        if not mp4:
            return []
        _write_mp4(stem.with_name(stem.name + ".mp4"), iter(frames), fps)
        return [stem.with_name(stem.name + ".mp4")]
    frames = _materialise(frames)
    out = []
    for fmt in formats:
        target = stem.with_name(stem.name + "." + fmt)
        if fmt == "gif":
            _write_gif(target, frames, fps)
            out.append(target)
        elif mp4:
            _write_mp4(target, iter(frames), fps)
            out.append(target)
    return out


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


def _materialise(frames: Iterable[np.ndarray]) -> list[np.ndarray]:
    out: list[np.ndarray] = []
    for n, f in enumerate(frames):
        out.append(_check_frame(f, n, out[0].shape if out else None))
    if not out:
        raise ValueError("frames must hold at least one frame, got none")
    return out
