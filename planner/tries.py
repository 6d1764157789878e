"""What auto mode's direct tries found (:class:`_Direct`), and how the stats
name the try that made the plan (see :func:`planner.planning._direct`)."""

from __future__ import annotations

from dataclasses import dataclass, field

from .bounds import lower_bounds
from .passages import passage_points
from .plan import PlanStats
from .problem import Problem
from .upump import _GOOD_ENOUGH

__all__ = []


def _name_direct(stats: PlanStats, label: str) -> None:
    """Record which direct try made the plan; the start-target connections are route ``[0, 1]``."""
    stats.extra["direct"] = label
    if label in ("one step", "sequenced"):
        stats.extra["route"] = [0, 1]


@dataclass
class _Direct:
    """What auto mode's direct tries found.

    ``best`` is ``(waypoints, sequential steps, makespan, label)`` of the
    shortest plan found (or ``None``); ``accepted`` when it is good enough
    to end the search; ``covered`` names the roadmap's structured stages
    whose whole route was tried here (the roadmap skips them); ``legs``
    the connections (straight or sequenced legs) of each try.
    """

    best: tuple | None = None
    accepted: bool = False
    covered: set = field(default_factory=set)
    legs: dict = field(default_factory=dict)

    def offer(self, label: str, legs: int, timed: tuple) -> None:
        self.legs[label] = legs
        if self.best is None or timed[2] < self.best[2]:
            self.best = (*timed, label)

    def final(self, problem: Problem) -> bool:
        """Whether the roadmap has nothing left to add.

        With a plan in hand, the roadmap's own versions of the stages whose
        chains failed here rarely beat it (over 20 seeds of every paper
        scenario they changed one median makespan, Table III row 4's, from
        1.45x to 1.40x the bound), and its last
        stage, one graph holding both placements, only pays where robots
        must file through a narrow passage and the plan is far from the
        bound (``_GOOD_ENOUGH[-1]``).
        """
        if self.accepted:
            return True
        if self.best is None:
            return False
        return not len(passage_points(problem)) or self.best[2] <= _GOOD_ENOUGH[-1] * lower_bounds(problem)[0]
