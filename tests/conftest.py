"""Shared test settings: headless SDL, the repository root, the slow marker, and the
``marker`` fixture (a file that any run of a sweep creates)."""

import os
from pathlib import Path

import pytest

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("SDL_AUDIODRIVER", "dummy")

ROOT = Path(__file__).resolve().parents[1]
SCENARIOS = ROOT / "scenarios"


@pytest.fixture
def marker(tmp_path, monkeypatch):
    """A file that any run of a sweep creates (the hook is inherited by the forked workers)."""
    import sim.tune.spec as tune_spec

    path = tmp_path / "a-run-started"
    real = tune_spec.run_one

    def run_one(spec):
        path.touch()
        return real(spec)

    monkeypatch.setattr(tune_spec, "run_one", run_one)
    return path


_CASE_HEAD = """
name: case
workspace: [20, 20]
robots: {radius: 1.0, margin: 0.1, count: 4}
start: {formation: line, rotation: 0, center: [10, 5]}
target: {formation: line, rotation: 0, center: [10, 15]}
"""


@pytest.fixture
def read_case(tmp_path):
    """``read_case(body, overrides=None)``: a 4-robot line-to-line scenario with ``body`` (YAML)
    appended, read (with ``--set``-style ``overrides``)."""
    import textwrap

    from sim.scenario import read_scenario

    def read(body: str, overrides: dict | None = None):
        path = tmp_path / "case.yaml"
        path.write_text(textwrap.dedent(_CASE_HEAD) + textwrap.dedent(body), encoding="utf-8")
        return read_scenario(path, overrides=overrides)

    return read
