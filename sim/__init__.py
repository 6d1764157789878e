"""swarmform's validation harness: scenarios, pymunk execution, contacts, rendering, the CLI."""

from .execute import Contact, SimReport, execute
from .params import RenderParams, SimParams
from .runner import InputError, RunResult, run_scenario
from .scenario import Scenario, ScenarioError, build_problem, read_scenario

__all__ = [
    "Contact",
    "InputError",
    "RenderParams",
    "RunResult",
    "Scenario",
    "ScenarioError",
    "SimParams",
    "SimReport",
    "build_problem",
    "execute",
    "read_scenario",
    "run_scenario",
]
