"""swarmform's validation harness: scenarios, pymunk execution, contacts, rendering, the CLI."""

from .params import RenderParams, SimParams
from .scenario import Scenario, ScenarioError, build_problem, read_scenario

__all__ = [
    "RenderParams",
    "Scenario",
    "ScenarioError",
    "SimParams",
    "build_problem",
    "read_scenario",
]
