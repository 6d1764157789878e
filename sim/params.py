"""Physics and rendering settings (the scenario's ``sim:`` and ``render:`` sections)."""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["MAX_FPS", "MAX_RENDER_SIZE", "RenderParams", "SimParams"]

MAX_RENDER_SIZE = 4096
"""The largest ``render.size`` [px]."""
MAX_FPS = 120
"""The highest ``render.fps`` [frames per video second]."""


@dataclass(frozen=True)
class SimParams:
    """PD-controlled execution in pymunk.  Units: s, workspace units, mass units.

    mass: body mass of each robot.
    kp, kd: PD gains per unit mass ([1/s^2], [1/s]); the force is
        ``mass * (kp * e + kd * de) + mass * a_ref``.
    dt: control step [s]; substeps: physics steps per control step.
    force_limit: maximum force magnitude per unit mass [units/s^2].
    settle_time: time simulated after the plan ends [s].
    tolerance: distance from a target that counts as reached [units].
    """

    mass: float = 1.0
    kp: float = 400.0
    kd: float = 40.0
    dt: float = 1.0 / 60.0
    substeps: int = 4
    force_limit: float = 200.0
    settle_time: float = 2.0
    tolerance: float = 0.05


@dataclass(frozen=True)
class RenderParams:
    """Off-screen rendering.

    fps: frames per second of the video.
    size: frame side in pixels (the longer workspace side maps to it), or
        ``None`` (auto): 480 to 960, growing with the workspace (measured in
        robot radii) and the number of robots (:func:`sim.canvas.frame_size`).
    trails: draw each robot's recent path.
    formats: any of ``gif`` and ``mp4``; mp4 is written when imageio-ffmpeg
        is installed (the ``video`` extra) and skipped otherwise.
    speedup: sim seconds per video second, or ``None`` (auto) to fit the
        whole run into about ``video_seconds``.  Either is raised when the
        video would last more than ``sim.playback.MAX_VIDEO_SECONDS`` (300 s).
    video_seconds: target video length for the automatic speed-up [s].
    """

    fps: int = 20
    size: int | None = None
    trails: bool = True
    formats: tuple[str, ...] = ("gif", "mp4")
    speedup: float | None = None
    video_seconds: float = 20.0
