"""Start-up: building the command line imports none of the heavy modules.

``python -m bench.startup`` measures the times; this checks the cause, which
does not depend on the machine's load: after ``--help`` of every subcommand
and ``--version``, neither the planner, numpy, scipy, pygame nor Dask has
been imported.  The negative control shows the probe seeing such an import.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
HEAVY = ("planner", "numpy", "scipy", "pygame", "pymunk", "distributed", "matplotlib", "shapely", "networkx")

PROBE = """
import contextlib, io, json, sys
from sim.cli import main
with contextlib.redirect_stdout(io.StringIO()):
    try:
        main({argv!r})
    except SystemExit:
        pass
{extra}
print(json.dumps(sorted(m for m in {heavy!r} if m in sys.modules)))
"""


def _heavy_after(argv: list[str], extra: str = "") -> list[str]:
    code = PROBE.format(argv=argv, heavy=HEAVY, extra=extra)
    r = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    return json.loads(r.stdout.strip().splitlines()[-1])


@pytest.mark.parametrize("argv", [["--help"], ["--version"]] + [
    [c, "--help"] for c in ("formations", "show", "plan", "run", "check", "export", "tune")])
def test_help_and_version_import_nothing_heavy(argv):
    assert _heavy_after(argv) == []


def test_the_probe_sees_a_heavy_import():
    assert "planner" in _heavy_after(["--help"], extra="import sim.scenario.reader")
