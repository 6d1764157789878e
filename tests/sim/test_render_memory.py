"""Videos at the largest ``render.size`` fit a bounded address space.

A run is a subprocess under ``prlimit --as=BYTES`` (the limit is inherited
by ffmpeg): at ``MAX_RENDER_SIZE`` a short GIF + MP4 is written within the
3 GB budget the cap was measured against (see ``sim.params``); under an
800 MB budget the same run works with small frames and fails at the cap,
which shows the limit really applies; one pixel over the cap is an input error (exit 2, one line).
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from sim.scenario.params import MAX_RENDER_SIZE

ROOT = Path(__file__).resolve().parents[2]
SCENARIO = ROOT / "scenarios" / "paper" / "fig1-line-to-phi.yaml"
BUDGET = 3_000_000_000  # address space [bytes] every allowed render.size must fit in
TOO_SMALL = 800_000_000  # enough to start, not for frames of MAX_RENDER_SIZE
SWARMFORM = [sys.executable, "-c", "import sys; from sim.cli import main; sys.exit(main())"]

pytestmark = pytest.mark.skipif(shutil.which("prlimit") is None, reason="needs prlimit (util-linux)")


def _run(tmp_path: Path, size: int, budget: int, name: str):
    out = tmp_path / name
    argv = ["prlimit", f"--as={budget}", *SWARMFORM, "run", str(SCENARIO), "--out", str(out),
            "--set", f"render.size={size}", "--set", "render.video_seconds=1", "--set", "render.fps=10"]
    with open(tmp_path / f"{name}.err", "w+") as err:
        p = subprocess.Popen(argv, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=err,
                             env={**os.environ, "PYTHONPATH": str(ROOT)})
        try:
            _, status, usage = os.wait4(p.pid, 0)
        except BaseException:
            p.kill()
            raise
        p.returncode = os.waitstatus_to_exitcode(status)
        err.seek(0)
        return p.returncode, err.read(), usage.ru_maxrss * 1024, out


@pytest.mark.slow  # renders 3072-pixel frames under prlimit: about 8 s
def test_largest_size_renders_within_the_budget(tmp_path):
    code, err, peak, out = _run(tmp_path, MAX_RENDER_SIZE, BUDGET, "cap")
    assert code == 0, err[-2000:]
    assert (out / "fig1-line-to-phi.gif").stat().st_size > 0
    assert peak < BUDGET, peak


def test_too_small_a_budget_fails_at_the_cap_only(tmp_path):
    code, err, _, _ = _run(tmp_path, 256, TOO_SMALL, "small-256")
    assert code == 0, err[-2000:]  # the budget is enough to plan, simulate and render small frames
    code, err, _, out = _run(tmp_path, MAX_RENDER_SIZE, TOO_SMALL, "small-cap")
    assert code == 3, "the address-space limit did not apply"  # out of memory: an internal error
    assert not (out / "fig1-line-to-phi.gif").exists() and not (out / "fig1-line-to-phi.mp4").exists()


def test_one_pixel_over_the_cap_is_an_input_error(tmp_path):
    code, err, _, out = _run(tmp_path, MAX_RENDER_SIZE + 1, BUDGET, "over")
    lines = err.strip().splitlines()
    assert code == 2, err[-2000:]
    assert len(lines) == 1, lines
    assert "render.size" in lines[0] and f"[64, {MAX_RENDER_SIZE}]" in lines[0], lines[0]
    assert f"got {MAX_RENDER_SIZE + 1}" in lines[0], lines[0]
    assert not out.exists() or not any(out.iterdir())
