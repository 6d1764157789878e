"""Planner parameters (a frozen record kept apart from planner state)."""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["PlannerParams"]


@dataclass(frozen=True)
class PlannerParams:
    """Settings of :func:`planner.plan`.

    g: number of sampled pebble graphs, or ``None`` for auto (anytime:
       sample until start and target connect or the time limit passes).
    q: connection attempts between two pebble graphs, or ``None`` for auto.
    time_limit: seconds of planning before :class:`planner.NoPlanFound`.
    n: vertices of each sampled pebble graph (``None``: chosen from m).
    extra: free vertices pumped into the start and target configurations
       (``None``: ceil(m / 4), at least 2).
    concurrent: schedule non-interfering moves at the same time.
    margin_extra: plan with the margin inflated by this much [units, >= 0];
       the plan is still validated against the problem's own margin, so a
       robot that strays up to about ``margin_extra / 2`` from its path
       keeps the real margin.
    """

    g: int | None = None
    q: int | None = None
    time_limit: float = 60.0
    n: int | None = None
    extra: int | None = None
    concurrent: bool = True
    margin_extra: float = 0.0

    @property
    def auto(self) -> bool:
        return self.g is None or self.q is None
