"""The execute room: a plan run in a pymunk world, watched by two contact witnesses.

Modules: ``physics`` (:func:`execute` and :class:`SimReport`), ``world`` (bodies and
walls), ``control`` (the PD law and the reference), ``realism`` (noise, delay,
pushes, failures), ``estimate`` (the state filter), ``contacts`` (the witnesses), ``recovery`` (replanning online),
``drive`` and ``drive_timing`` (differential and velocity robots), ``legs`` (chained
targets), ``series`` (the recorded curves) and ``budget`` (what a run may cost).  It
imports the scenario room, never the output room.

``sim.execute`` is both this room and, called, :func:`sim.execute.physics.execute`,
so that ``from sim import execute; execute(problem, plan, SimParams())`` keeps working.
"""

import sys
import types

from ..lazy import lazy_exports

_WHERE = {
    **dict.fromkeys(("Contact", "Disturbance", "Replan", "SimReport", "execute"), "physics"),
    "plan_legs": "legs",
}

__all__ = sorted(_WHERE, key=str.lower)

__getattr__, __dir__ = lazy_exports(__name__, _WHERE)


class _Room(types.ModuleType):
    """This package's module type: calling it runs :func:`sim.execute.physics.execute`."""

    def __call__(self, problem, plan, params, rng=None, *, planner_params=None, progress=None):
        from .physics import execute

        return execute(problem, plan, params, rng, planner_params=planner_params, progress=progress)


sys.modules[__name__].__class__ = _Room
