"""Video timing: how fast a recorded run plays and which sim time each frame shows.

Playback runs ``speedup`` sim seconds per video second.  Frame ``k`` shows
sim time ``min(k * speedup / fps, duration)``; the last time is shown once
more when the frame grid misses it, and is then held for about a second.

A video never lasts more than :data:`MAX_VIDEO_SECONDS` (plus the held
end): when the asked-for speed-up (or a huge run) would make it longer, the
speed-up is raised to the readable value that keeps it within the limit,
and :class:`Timing` says so (``raised``).  So the number of frames is at
most ``MAX_VIDEO_SECONDS * fps + 2 + fps``, whatever the run's length
(``fps`` is at most :data:`MAX_FPS`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..scenario.params import MAX_FPS

__all__ = ["MAX_FPS", "MAX_VIDEO_SECONDS", "Timing", "frame_times", "playback_speedup", "timing"]


MAX_VIDEO_SECONDS = 300.0
"""The longest video [video s], the held end not counted."""

HOLD_SECONDS = 1.0
"""How long the last frame is held [video s]."""

_READABLE = (1.0, 1.5, 2.0, 2.5, 3.0, 4.0, 5.0, 6.0, 8.0)
"""Mantissas of the automatic speed-ups: 1, 1.5, 2, 2.5, 3, 4, 5, 6, 8, 10, 15, ..."""


@dataclass(frozen=True)
class Timing:
    """How a run of ``duration`` sim seconds becomes a video.

    speedup: sim seconds per video second, as used.
    asked: the speed-up asked for (``None``: automatic).
    raised: the speed-up was raised to keep the video within
        :data:`MAX_VIDEO_SECONDS`.
    fps: video frames per second.
    drawn: frames that show a new time; held: frames repeating the last one.
    """

    duration: float
    speedup: float
    asked: float | None
    raised: bool
    fps: int
    drawn: int
    held: int

    @property
    def frames(self) -> int:
        return self.drawn + self.held

    @property
    def video_seconds(self) -> float:
        return self.frames / self.fps

    def time(self, k: int) -> float:
        """Sim time shown by frame ``k`` [s, from the start of the run]."""
        k = min(max(int(k), 0), self.drawn - 1)
        return min(k * (self.speedup / self.fps), self.duration)

    def to_dict(self) -> dict:
        return {
            "speedup": self.speedup,
            "speedup_asked": self.asked if self.asked is not None else "auto",
            "speedup_raised": self.raised,
            "fps": self.fps,
            "frames": self.frames,
            "seconds": round(self.video_seconds, 3),
        }


def _readable(x: float) -> float:
    """The value of ``1, 1.5, 2, 2.5, 3, 4, 5, 6, 8`` times a power of ten nearest to ``x``
    (in ratio), never below 1."""
    if not x > 1.0:
        return 1.0
    return max(1.0, min(_candidates(x), key=lambda v: abs(math.log(v / x))))


def _readable_up(x: float) -> float:
    """The smallest value of ``1, 1.5, 2, 2.5, 3, 4, 5, 6, 8`` times a power of ten ``>= x > 0``."""
    return min(c for c in _candidates(x) if c >= x * (1 - 1e-12))


def _candidates(x: float) -> list[float]:
    e = math.floor(math.log10(x))
    return [float(f"{v * 10.0**k:.6g}") for k in (e - 1, e, e + 1) for v in _READABLE]


def playback_speedup(duration: float, params) -> float:
    """Sim seconds per video second (``params`` is a :class:`sim.scenario.params.RenderParams`).

    ``params.speedup`` when set; otherwise the readable value (1, 1.5, 2,
    2.5, 3, 4, 5, 6, 8, 10, 15, ...) that makes a run of ``duration`` sim
    seconds last closest to ``params.video_seconds``, and at least 1 (a short
    run plays in real time rather than in slow motion).  Either is raised
    when the video would last more than :data:`MAX_VIDEO_SECONDS`.
    """
    return timing(duration, params).speedup


def timing(duration: float, params) -> Timing:
    """The :class:`Timing` of a run of ``duration`` sim seconds under ``params``."""
    duration = max(0.0, float(duration))
    if not math.isfinite(duration):
        raise ValueError(f"duration must be finite, got {duration!r}")
    fps = params.fps
    if isinstance(fps, bool) or not isinstance(fps, (int, np.integer)) or not 1 <= fps <= MAX_FPS:
        raise ValueError(f"fps must be an integer in [1, {MAX_FPS}], got {fps!r}")
    fps = int(fps)
    asked = params.speedup
    if asked is not None:
        if not (isinstance(asked, (int, float)) and not isinstance(asked, bool) and 0 < asked < math.inf):
            raise ValueError(f"speedup must be a number > 0 or None (auto), got {asked!r}")
        speedup = float(asked)
    else:
        if not 0 < params.video_seconds < math.inf:
            raise ValueError(f"video_seconds must be a number > 0, got {params.video_seconds!r}")
        speedup = _readable(duration / params.video_seconds)
    raised = duration / speedup > MAX_VIDEO_SECONDS
    if raised:
        speedup = _readable_up(duration / MAX_VIDEO_SECONDS)
    dt = speedup / fps
    drawn = int(math.floor(duration / dt + 1e-9)) + 1
    if duration - (drawn - 1) * dt > 1e-9 * max(1.0, duration):
        drawn += 1  # the end, which the grid misses
    return Timing(duration, speedup, None if asked is None else float(asked), raised, fps, drawn,
                  int(round(HOLD_SECONDS * fps)))


def frame_times(duration: float, speedup: float, fps: int) -> np.ndarray:
    """Sim time shown by every frame [s], the held end included.

    Frames ``k = 0, 1, ...`` show ``k * speedup / fps`` up to ``duration``;
    a frame at exactly ``duration`` follows when the grid misses it, and the
    last time is then repeated for about one video second.  (No length
    limit here: :func:`timing` chooses a ``speedup`` that keeps it bounded.)
    """
    duration = max(0.0, float(duration))
    dt = speedup / fps
    n = int(math.floor(duration / dt + 1e-9)) + 1
    t = np.arange(n) * dt
    if duration - t[-1] > 1e-9 * max(1.0, duration):
        t = np.append(t, duration)
    hold = int(round(HOLD_SECONDS * fps))
    return np.concatenate([t, np.full(hold, t[-1])])
