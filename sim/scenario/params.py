"""Physics and rendering settings (the scenario's ``sim:`` and ``render:`` sections)."""

from __future__ import annotations

from dataclasses import dataclass

__all__ = [
    "MAX_FPS",
    "MAX_RENDER_SIZE",
    "DriveParams",
    "Failure",
    "Impulse",
    "Noise",
    "Pushes",
    "Recovery",
    "RenderParams",
    "Sensing",
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
        from the measured (estimated) positions.
    replan_time_limit: planning time allowed for each replan [s].  The YAML
        key ``sim.recovery.time_limit`` is an alias of it (giving both is an
        error); :attr:`time_limit` reads it too.
    max_replans: the most replans for tracking errors in one run.  A robot
        failure is always answered with a replan and does not count (there
        are at most as many as robots).  A tracking-error trigger that finds
        the budget used up exhausts it: the report names the time
        (``budget_exhausted_at``) and the run fails, unless ``on_budget``
        is ``"continue"`` (the old rule: later triggers are ignored).
    on_budget: ``"fail"`` (default) or ``"continue"``.
    """

    replan: bool = False
    trigger: float = 0.05
    replan_time_limit: float = 10.0
    max_replans: int = 10
    on_budget: str = "fail"

    @property
    def time_limit(self) -> float:
        """The old name of :attr:`replan_time_limit` [s]."""
        return self.replan_time_limit


@dataclass(frozen=True)
class Sensing:
    """What the controller measures (:mod:`sim.execute.estimate`), when given as ``sim.sensing``.

    With a ``sim.sensing`` section, or with ``noise.position > 0``, the
    controller and recovery's trigger see only the state a filter estimates
    from position measurements; velocity is never measured.  Without both,
    or with ``estimator: oracle``, the controller measures the true state
    plus :class:`Noise` (position and velocity) as before.

    rate: position measurements per second [Hz]; ``None`` = the controller's
        update rate.  Range (0, 10000].
    dropout: probability that a measurement of one robot is lost, [0, 1).
    latency_jitter: each measurement reaches the filter ``U(0, jitter)``
        seconds after it was taken [s], [0, 1]; one older than the last one
        used for that robot is discarded.
    bias_drift: each robot's measured position carries a bias that is a
        random walk of ``bias_drift`` units per square-root second, per
        axis, unknown to the filter [units/sqrt(s)], [0, 10].
    estimator: ``kalman`` (constant-velocity Kalman filter, default),
        ``alpha_beta`` (its steady-state gains) or ``oracle``.
    process_noise: the filter's white-acceleration spectral density
        [units^2/s^3], (0, 1e8]; unmodelled forces (pushes, friction).
    failure_delay: seconds from a robot's failure until recovery is told
        [s], [0, 60]; ``None`` = 0.5 s with a filter, 0 with ``oracle``.
    """

    rate: float | None = None
    dropout: float = 0.0
    latency_jitter: float = 0.0
    bias_drift: float = 0.0
    estimator: str = "kalman"
    process_noise: float = 100.0
    failure_delay: float | None = None


@dataclass(frozen=True)
class DriveParams:
    """How a robot moves (``sim.drive``; :mod:`sim.execute.drive`).

    model: ``holonomic`` (default: a force in any direction, PD +
        feed-forward), ``differential`` (two wheels, no lateral slip) or
        ``velocity`` (first-order tracking of velocity set-points).
    wheel_base: distance between the wheels [units], (0, 100] (differential).
    wheel_speed: largest wheel speed [units/s], (0, 1000] (differential);
        the largest turn rate is ``2 wheel_speed / wheel_base`` [rad/s].
    wheel_accel: largest wheel acceleration [units/s^2], (0, 1e5] (differential).
    lookahead: distance of the tracked point ahead of the axle [units],
        (0, 100] (differential).
    time_constant: ``tau`` of ``v' = (v_cmd - v) / tau`` [s], (0, 10] (velocity).
    max_speed: largest velocity set-point [units/s], (0, 1000] (velocity).
    kp_v: position gain of the set-point ``v_ref + kp_v (p_ref - p)``
        [1/s], [0, 1000] (differential and velocity).
    """

    model: str = "holonomic"
    wheel_base: float = 0.8
    wheel_speed: float = 3.0
    wheel_accel: float = 10.0
    lookahead: float = 0.3
    time_constant: float = 0.1
    max_speed: float = 3.0
    kp_v: float = 5.0


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
    sensing: measurement and state estimation (:class:`Sensing`), or
        ``None``: a filter when ``noise.position > 0``, else the true state.
    accept: the rule of ``SimReport.ok`` besides "no contact":
        ``"targets"`` (default): every target of the problem holds a working
        robot at the end; ``"working"``: every working robot ends on a
        distinct target (or its parking place), targets may stay empty.
    drive: the drive model (:class:`DriveParams`); any but ``holonomic``
        runs the realistic loop.
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
    sensing: Sensing | None = None
    accept: str = "targets"
    drive: DriveParams = DriveParams()

    @property
    def estimating(self) -> bool:
        """Whether the controller sees a filter's estimate (see :class:`Sensing`)."""
        if self.sensing is not None:
            return self.sensing.estimator != "oracle"
        return self.noise.position > 0

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
            or self.sensing is not None
            or self.drive.model != "holonomic"
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
