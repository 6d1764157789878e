"""swarmform's planner: geometry, formations, the UPUMP planner, plans and their validation."""

from .formations import DEFAULT_COUNTS, FORMATIONS, formation_shape, place_formation
from .params import PlannerParams
from .problem import Circle, Polygon, Problem, ProblemError

__all__ = [
    "Circle",
    "DEFAULT_COUNTS",
    "FORMATIONS",
    "PlannerParams",
    "Polygon",
    "Problem",
    "ProblemError",
    "formation_shape",
    "place_formation",
]
