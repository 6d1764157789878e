"""The ``sim`` package's public names are the documented objects, whatever was imported first."""

import subprocess
import sys

import pytest

import sim

_CHECK = """
import importlib, sys
for first in sys.argv[1:]:
    importlib.import_module(first)
import sim
from sim import execute, render_frames, write_video, run_scenario, SimReport
# sim.execute is the execute room, a module that runs the physics when called
assert callable(execute) and execute.__name__ in ("execute", "sim.execute"), execute
assert sim.execute is execute
assert callable(render_frames) and callable(write_video) and callable(run_scenario)
assert isinstance(SimReport, type)
print("ok")
"""


@pytest.mark.parametrize("first", [[], ["sim.runner"], ["sim.execute.physics"], ["sim.execute"], ["sim.tune"], ["sim.cli"]])
def test_public_names_are_functions_whichever_module_loads_first(first):
    out = subprocess.run([sys.executable, "-c", _CHECK, *first], capture_output=True, text=True,
                         timeout=120)
    assert out.returncode == 0 and out.stdout.strip() == "ok", out.stderr[-600:]


def test_a_submodule_shadowing_a_public_name_is_caught():
    # Negative control: with the package attribute replaced by the module of the same
    # role (what a lazy package gets when a submodule shares a public name), the check fails.
    shadow = "import sim, sim.runner, sim.output.render, sim.execute.physics\nsim.execute = sim.execute.physics\n" + _CHECK
    out = subprocess.run([sys.executable, "-c", shadow], capture_output=True, text=True,
                         timeout=120)
    assert out.returncode != 0 and "AssertionError" in out.stderr


def test_every_public_name_resolves():
    for name in sim.__all__:
        assert getattr(sim, name) is not None
    with pytest.raises(AttributeError):
        sim.no_such_name  # noqa: B018
