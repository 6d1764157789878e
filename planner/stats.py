"""What a planning run did: :class:`PlanStats`, and its JSON form."""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field

import numpy as np

__all__ = ["PlanStats"]


@dataclass
class PlanStats:
    """What a planning run did.  Times in seconds, lengths in workspace units.

    ``min_clearance`` is the exact smallest gap between two disc boundaries,
    or between a disc and an obstacle or wall, over the whole plan (a plan
    is valid when it is at least the margin).  ``makespan_lower_bound_s`` is
    over straight-line distances, ``makespan_lower_bound_geo_s`` over shortest
    paths around the obstacles (:mod:`planner.geobound`; NaN when not computed),
    ``makespan_lower_bound_cut_s`` over robots passing a narrow passage one at a
    time (:mod:`planner.cutbound`; NaN when no passage applies or not computed).
    """

    found: bool = False
    planning_time_s: float = 0.0
    g: int = 0
    q: int = 0
    graphs: int = 0
    connections: int = 0
    steps: int = 0
    makespan_s: float = 0.0
    path_length: float = 0.0
    min_clearance: float = float("nan")
    makespan_lower_bound_s: float = float("nan")
    path_length_lower_bound: float = float("nan")
    makespan_lower_bound_geo_s: float = float("nan")  # over shortest paths around obstacles
    makespan_lower_bound_cut_s: float = float("nan")  # robots through a narrow passage in turn
    extra: dict = field(default_factory=dict)

    def to_dict(self) -> dict:
        d = asdict(self)
        extra = d.pop("extra")
        d.update(extra)
        return {k: _jsonable(v) for k, v in d.items()}


def _jsonable(v):
    if isinstance(v, float) and not math.isfinite(v):
        return None
    if isinstance(v, (np.floating,)):
        return _jsonable(float(v))
    if isinstance(v, (np.integer,)):
        return int(v)
    return v
