"""Physics and rendering settings (the scenario's ``sim:`` and ``render:`` sections)."""

from __future__ import annotations

from dataclasses import dataclass

__all__ = [
    "MAX_FPS",
    "MAX_RENDER_SIZE",
    "Failure",
    "Impulse",
    "Noise",
    "Pushes",
    "Recovery",
    "RenderParams",
    "SimParams",
]

MAX_RENDER_SIZE = 3072
"""The largest ``render.size`` [px] of a video.

Measured on fig1-line-to-phi, a 5 s video (100 frames), under a 3 GB
address space (``prlimit --as=3000000000``): at 3072 px the GIF peaks at
about 0.5 GB resident and takes about 40 s, the MP4 about 1.4 to 1.7 GB
(ffmpeg's x264) and 16 s.  At 4096 px the GIF takes over 70 s and the MP4
53 s at 1.9 GB, too slow and too close to the budget.  Memory grows with
the frame area only (a few frames at a time: frames are streamed, the GIF
palette is sampled one frame at a time), never with the video's length.
"""
MAX_FPS = 120
"""The highest ``render.fps`` [frames per video second]."""


@dataclass(frozen=True)
class Noise:
    """Standard deviation of the measured state, per coordinate and per controller update.

    position: [units], velocity: [units/s].  The noise is added to what the
    controller measures, never to the bodies.
    """

    position: float = 0.0
    velocity: float = 0.0


@dataclass(frozen=True)
class Impulse:
    """A scheduled impulse: ``impulse`` [N s] given to ``robot`` at ``time`` [s]."""

    robot: int
    time: float
    impulse: tuple[float, float]


@dataclass(frozen=True)
class Pushes:
    """Random impulses: a Poisson process of ``rate`` pushes per robot per second,
    each of magnitude ``impulse`` [N s] in a uniformly random direction."""

    rate: float = 0.0
    impulse: float = 0.0


@dataclass(frozen=True)
class Failure:
    """At ``time`` [s] ``robot`` stops actuating and brakes to rest; it stays a passive body."""

    robot: int
    time: float


@dataclass(frozen=True)
class Recovery:
    """Online recovery (:mod:`sim.execute.recovery`).

    replan: when any robot's tracking error exceeds ``trigger`` [units], or a
        robot fails, every robot brakes to rest and the planner plans again
        from the measured positions.
    time_limit: planning time allowed for each replan [s].
    max_replans: the most replans of one run; later triggers are ignored.
    """

    replan: bool = False
    trigger: float = 0.05
    time_limit: float = 10.0
    max_replans: int = 10


@dataclass(frozen=True)
class SimParams:
    """PD-controlled execution in pymunk.  Units: s, workspace units, mass units.

    A workspace unit counts as one metre and a mass unit as one kilogram
    wherever a force is named in newtons: a force of 1 N accelerates a mass
    of 1 by 1 unit/s^2.

    mass: the model's body mass of each robot.
    kp, kd: PD gains per unit mass ([1/s^2], [1/s]); the commanded force is
        ``mass * (kp * e + kd * de + a_ref)``, saturated at ``force_limit``.
    dt: control step [s]; substeps: physics steps per control step.
    force_limit: largest actuator force of one robot [N]; with the default
        mass 1 it equals the largest commanded acceleration [units/s^2].
    settle_time: time simulated after the plan ends [s].
    tolerance: distance from a target that counts as reached [units].

    Realistic execution (every one off by default; see :mod:`sim.execute.realism`):

    control_rate: controller updates per second [Hz], with a zero-order hold
        between them; ``None`` updates once per control step ``dt``.
    latency: time between measuring the state and applying the force
        computed from it [s].
    noise: measurement noise (:class:`Noise`).
    mass_error: each body's real mass is ``(1 + u) * mass`` with ``u`` drawn
        from ``U(-mass_error, mass_error)``; the controller keeps ``mass``.
    friction: planar Coulomb friction coefficient against the floor: a force
        of magnitude ``friction * m * g``, ``g = 9.81`` units/s^2, opposing
        the velocity.
    disturbances: scheduled impulses (:class:`Impulse`).
    pushes: random impulses (:class:`Pushes`).
    failures: robots that stop actuating (:class:`Failure`).
    recovery: online recovery (:class:`Recovery`).
    """

    mass: float = 1.0
    kp: float = 400.0
    kd: float = 40.0
    dt: float = 1.0 / 60.0
    substeps: int = 4
    force_limit: float = 200.0
    settle_time: float = 2.0
    tolerance: float = 0.05
    control_rate: float | None = None
    latency: float = 0.0
    noise: Noise = Noise()
    mass_error: float = 0.0
    friction: float = 0.0
    disturbances: tuple[Impulse, ...] = ()
    pushes: Pushes = Pushes()
    failures: tuple[Failure, ...] = ()
    recovery: Recovery = Recovery()

    @property
    def realistic(self) -> bool:
        """Whether any realism knob or recovery is on (else the ideal robots of the plain loop)."""
        return bool(
            self.control_rate
            or self.latency > 0
            or self.noise.position > 0
            or self.noise.velocity > 0
            or self.mass_error > 0
            or self.friction > 0
            or self.disturbances
            or (self.pushes.rate > 0 and self.pushes.impulse > 0)
            or self.failures
            or self.recovery.replan
        )


@dataclass(frozen=True)
class RenderParams:
    """Off-screen rendering.

    fps: frames per second of the video.
    size: frame side in pixels (the longer workspace side maps to it), or
        ``None`` (auto): 480 to 960, growing with the workspace (measured in
        robot radii) and the number of robots (:func:`sim.output.canvas.frame_size`).
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
