"""The speed guard: physics steps in which a body could move too far are cut into pieces and their paths swept."""

from __future__ import annotations

import numpy as np

from .monitor import SWEEP_FRACTION

__all__ = ["MAX_PIECES", "TUNNEL_FRACTION", "SpeedGuard"]



TUNNEL_FRACTION = 0.5
"""pymunk detects overlaps at the end of each step: a step in which a body
moves more than ``TUNNEL_FRACTION`` radii is cut into pieces that do not."""

MAX_PIECES = 64
"""The most pieces one physics step is cut into; a body faster than that
still allows is reported in :attr:`SpeedGuard.warnings` (tunnelling possible)."""


class SpeedGuard:
    """Watches the bodies' speed so that neither witness misses a contact inside one step.

    At the start of each control step :meth:`begin` bounds how far any body
    can move in one physics step (its speed now plus what the largest force
    ``f_max`` [N] adds over the control step).  Nearly always that is well
    below the monitor's sweep fraction of a radius and the loop steps as
    usual.  Otherwise (or when an event falls due in the step) the loop
    calls :meth:`step` instead of ``space.step``: it reads the bodies'
    state, cuts the physics step into as many pieces as the predicted move
    needs (:data:`TUNNEL_FRACTION`, at most :data:`MAX_PIECES`), and keeps
    the positions after every piece; :meth:`end` gives that path to
    :meth:`GapMonitor.sweep`.  Warnings go to the pymunk witness's
    ``speed_warnings`` (and from there into :class:`SimReport`).
    """

    enabled = True
    """Watch at all (switch off only to show what the witnesses miss without it)."""
    subdivide = True
    """Cut fast physics steps into pieces (off: only the monitor's sweep sees inside them)."""

    def __init__(self, world, witness, monitor, radius: float, masses, f_max: float, dt: float, h: float):
        self.world = world
        self.warnings = witness.speed_warnings
        self.monitor = monitor
        self.radius = float(radius)
        self.inv_mass = 1.0 / np.asarray(masses, float)
        self.dt, self.h = float(dt), float(h)
        self.a_max = float(f_max) * float(self.inv_mass.max())
        self._watch = SWEEP_FRACTION * self.radius
        self._times: list[float] = []
        self._path: list[np.ndarray] = []

    def begin(self, t0: float, state: np.ndarray, event_due: bool = False) -> bool:
        """Whether the control step from ``t0`` (bodies at ``state`` ``(m, 4)``) must be watched."""
        if not self.enabled:
            return False
        v = state[:, 2:]
        vmax = float(np.sqrt(np.einsum("ix,ix->i", v, v).max())) if len(v) else 0.0
        if not event_due and (vmax + self.a_max * self.dt) * self.h <= self._watch:
            return False
        self._times = [float(t0)]
        self._path = [state[:, :2].copy()]
        return True

    def step(self, t_end: float) -> None:
        """One physics step ending at ``t_end``, in pieces if a body could tunnel (forces are set)."""
        world, h = self.world, self.h
        state = world.state()
        v, f = state[:, 2:], world.forces
        move = (np.sqrt(np.einsum("ix,ix->i", v, v)) + np.sqrt(np.einsum("ix,ix->i", f, f)) * self.inv_mass * h) * h
        worst = int(np.argmax(move)) if len(move) else 0
        n = max(1, int(np.ceil(float(move[worst]) / (TUNNEL_FRACTION * self.radius)))) if len(move) else 1
        if n > 1 and not self.subdivide:
            self._warn(t_end, worst, float(move[worst]), "not subdivided")
            n = 1
        elif n > MAX_PIECES:
            self._warn(t_end, worst, float(move[worst]), f"cut into only {MAX_PIECES} pieces")
            n = MAX_PIECES
        t0 = t_end - h
        for i in range(n):
            if i:
                world.apply_forces()  # Chipmunk clears forces after each step
            world.space.step(h / n)
            if i < n - 1:
                self._times.append(t0 + (i + 1) * h / n)
                self._path.append(world.state()[:, :2])
        self._times.append(float(t_end))
        self._path.append(world.state()[:, :2])

    def end(self) -> None:
        """Give the watched control step's path to the monitor."""
        if self._path:
            if len(self._path) > 1:
                self.monitor.sweep(np.array(self._times), np.array(self._path))
            self._times, self._path = [], []

    def _warn(self, t: float, robot: int, move: float, what: str) -> None:
        if len(self.warnings) < 100:
            self.warnings.append(f"tunnelling possible: robot {robot} moves {move:.3g} units in one "
                                 f"physics step at t = {t:.4f} s ({what})")
