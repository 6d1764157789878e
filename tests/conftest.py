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
