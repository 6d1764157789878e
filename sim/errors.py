"""The error every command turns into exit code 2: wrong input, said in one line.

:class:`InputError` is raised for input found wrong outside a scenario file
(an option, an output path, a plan that does not fit its scenario, a run
over the physics budget); its ``str()`` names the file or option, the field
and the reason.  Scenario and plan files have their own errors
(:class:`sim.scenario.ScenarioError`, :class:`planner.PlanFileError`).
"""

from __future__ import annotations

__all__ = ["InputError"]


class InputError(ValueError):
    """Wrong input found by a command (one line naming the file, the field, the reason)."""
