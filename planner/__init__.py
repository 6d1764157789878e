"""swarmform's planner: geometry, formations, the UPUMP planner, plans and their validation."""

from .feasibility import Infeasible, feasibility
from .formations import DEFAULT_COUNTS, FORMATIONS, formation_shape, place_formation
from .params import PlannerParams
from .plan import Plan, PlanFileError, PlanStats
from .planning import plan
from .problem import Circle, Polygon, Problem, ProblemError
from .upump import NoPlanFound
from .validate import Clearance, PlanInvalid, check_plan, min_clearance

__all__ = [
    "Circle",
    "Clearance",
    "DEFAULT_COUNTS",
    "FORMATIONS",
    "Infeasible",
    "NoPlanFound",
    "Plan",
    "PlanFileError",
    "PlanInvalid",
    "PlanStats",
    "PlannerParams",
    "Polygon",
    "Problem",
    "ProblemError",
    "check_plan",
    "feasibility",
    "formation_shape",
    "min_clearance",
    "place_formation",
    "plan",
]
