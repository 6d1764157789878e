"""pytest plugin: the ``swarmform`` fixture, for users' own collision-verification regression tests.

Installed with swarmform (entry point ``pytest11``), so any test can ask for it::

    def test_my_scenario(swarmform):
        report = swarmform("scenarios/mine.yaml", set={"robots.margin": 0.2})
        swarmform.assert_ok(report)

``swarmform(path, set=None, plan=None, seed=None)`` runs the scenario as
``swarmform run --no-render`` does (plan or load ``plan``, validate exactly,
execute in pymunk) in the test's ``tmp_path`` and returns the run report,
the dict written as ``NAME.json``.  A relative path is taken from the
folder pytest runs in.  :func:`assert_run_ok` (also ``swarmform.assert_ok``)
raises ``AssertionError`` with the verdict line and the first contact when
the run did not pass.  Wrong input (a bad scenario or plan file) raises the
run's own error, as ``swarmform run`` would exit 2.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

__all__ = ["SwarmformRunner", "assert_run_ok", "swarmform"]


def assert_run_ok(report: dict) -> None:
    """Fail (``AssertionError``) unless ``report`` passed: its verdict line, then its first contact."""
    from .output.verdict import verdict

    ok, line = verdict(report)
    if ok and report.get("ok"):
        return
    sim = report.get("sim") or {}
    first = sim.get("first_contact") or (sim.get("contact_list") or [None])[0]
    where = f"\nfirst contact: {_contact(first)}" if first else ""
    raise AssertionError(f"{report.get('scenario', 'run')}: {line}{where}")


def _contact(c: dict) -> str:
    keys = ("kind", "a", "b", "time", "depth", "witness")
    return ", ".join(f"{k} {c[k]}" for k in keys if k in c) or str(c)


class SwarmformRunner:
    """Runs scenarios into one folder; what the ``swarmform`` fixture gives a test."""

    assert_ok = staticmethod(assert_run_ok)

    def __init__(self, folder: Path):
        self.folder = Path(folder)
        self.runs = 0
        self.last: Any = None  # the last RunResult (report, exit code, sim, plan)

    def __call__(self, path, set: dict | None = None, plan=None, seed: int | None = None) -> dict:
        """Run ``path`` without video; return its report (the ``NAME.json`` dict)."""
        from .runner import run_scenario

        self.runs += 1
        out = self.folder / f"run{self.runs}"
        self.last = run_scenario(Path(path), seed=seed, out_dir=out, render=False,
                                 plan_path=None if plan is None else Path(plan), progress=False,
                                 out=None, overrides=dict(set) if set else None)
        return self.last.report


@pytest.fixture
def swarmform(tmp_path) -> SwarmformRunner:
    """Run a scenario: ``report = swarmform("path.yaml", set={...}, plan=None, seed=None)``;
    ``swarmform.assert_ok(report)`` fails the test with the verdict and the first contact."""
    return SwarmformRunner(tmp_path / "swarmform")
