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
import logging
import math
import os
import secrets
from collections.abc import Callable, Iterable, Sequence
from contextlib import ExitStack, contextmanager
from pathlib import Path
from typing import Any

import numpy as np

from .gif import (
    GIF_MAX_FPS,
    _check_fps,
    _check_frame,
    _GifWriter,
    _palette_and_stream,
    gif_durations,
)

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
    (:func:`sim.output.files.remove_stale`).
    """
    from .files import remove_stale, temp_name

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
        self._gen: Any = None  # ffmpeg's frame generator, once started

    def add(self, frame: np.ndarray) -> None:
        if self._gen is None:
            from .files import signals_held

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
        :func:`sim.output.render.render_frames` returns) is sampled over the whole
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
        writers: list[Any] = []
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


