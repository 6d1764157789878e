"""swarmform's planner: geometry, formations, the UPUMP planner, plans and their exact validation.

A problem (workspace, obstacles, disc robots, start and target placements),
a plan for it, and the exact check of that plan:

>>> import numpy as np
>>> from planner import Circle, PlannerParams, Problem, min_clearance, plan
>>> problem = Problem(20.0, 10.0, (Circle((10.0, 5.0), 1.5),), radius=0.5, margin=0.1,
...                   start=[[2, 3], [2, 7]], target=[[18, 3], [18, 7]])
>>> result, stats = plan(problem, PlannerParams(time_limit=10), np.random.default_rng(0))
>>> stats.found, result.m, result.steps >= 1
(True, 2, True)
>>> min_clearance(problem, result).value >= problem.margin  # exact, continuous in time
True
>>> result.makespan >= stats.makespan_lower_bound_s
True
>>> sorted(result.to_dict())[:4]  # the plan file format
['durations', 'margin', 'max_accel', 'max_speed']
"""

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
