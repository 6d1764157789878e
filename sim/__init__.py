"""swarmform's validation harness: scenarios, pymunk execution, contacts, videos, the run page, the CLI.

A scenario file runs end to end with :func:`run_scenario` (what ``swarmform
run`` does: plan, check, execute, render, write ``NAME.json``, the video and
``NAME.html``).  The pieces work on a problem built in code:

>>> import numpy as np
>>> from planner import Circle, PlannerParams, Problem, plan
>>> from sim import RenderParams, SimParams, execute, render_frames, write_video
>>> problem = Problem(20.0, 10.0, (Circle((10.0, 5.0), 1.5),), radius=0.5, margin=0.1,
...                   start=[[2, 3], [2, 7]], target=[[18, 3], [18, 7]])
>>> result, stats = plan(problem, PlannerParams(time_limit=10), np.random.default_rng(0))
>>> run = execute(problem, result, SimParams())
>>> run.ok, len(run.contacts)
(True, 0)
>>> frames = render_frames(problem, run.times, run.positions, run.contacts, RenderParams(),
...                        step_times=result.times)
>>> frames[0].dtype, frames[0].shape[2], len(frames) == frames.timing.frames
(dtype('uint8'), 3, True)
>>> import pathlib, tempfile
>>> folder = pathlib.Path(tempfile.mkdtemp())
>>> [p.name for p in write_video(folder / "demo", frames, fps=20, formats=["gif"])]
['demo.gif']
"""

from .lazy import lazy_exports

# name -> the module that defines it; imported on first use, so that the
# command line starts without loading the physics, the planner or pygame.
_WHERE = {
    "Contact": "execute.physics",
    "SimReport": "execute.physics",
    "execute": None,  # the room, which is also callable: sim.execute(problem, plan, params)
    "write_video": "output.media",
    "RenderParams": "scenario.params",
    "SimParams": "scenario.params",
    "draw_scenario": "output.render",
    "render_frames": "output.render",
    "write_run_page": "output.report",
    "InputError": "errors",
    "RunResult": "runner",
    "run_scenario": "runner",
    "Scenario": "scenario.model",
    "ScenarioError": "scenario.model",
    "build_problem": "scenario.build",
    "read_scenario": "scenario.reader",
}

__all__ = sorted(_WHERE, key=str.lower)


__getattr__, __dir__ = lazy_exports(__name__, _WHERE)
