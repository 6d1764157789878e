"""What the command line says: --version, counted nouns, auto mode's g and q, progress bars."""

import io
import subprocess
import sys
from importlib.metadata import version
from pathlib import Path

from sim.progress import ProgressBar
from sim.words import plural

ROOT = Path(__file__).resolve().parents[2]
EXE = str(Path(sys.executable).parent / "swarmform")


def test_version_comes_from_the_package_metadata(capsys):
    import pytest

    from sim.cli import main

    with pytest.raises(SystemExit) as exc:
        main(["--version"])
    assert exc.value.code == 0
    assert capsys.readouterr().out.strip() == f"swarmform {version('swarmform')}"


def test_counted_nouns():
    assert [plural(n, "step") for n in (0, 1, 2)] == ["0 steps", "1 step", "2 steps"]
    assert plural(1, "contact") == "1 contact" and plural(3, "contact") == "3 contacts"
    assert plural(2, "body", "bodies") == "2 bodies"


def test_plan_in_auto_mode_says_auto_and_the_graphs_it_sampled(tmp_path):
    r = subprocess.run([EXE, "plan", "scenarios/letters/line-to-lambda.yaml", "-o", str(tmp_path / "p.json")],
                       capture_output=True, text=True, cwd=ROOT)
    assert r.returncode == 0, r.stdout + r.stderr
    rows = {line[:17].strip(): line[17:].strip() for line in r.stdout.splitlines() if line.startswith("  ")}
    assert rows["g, q"] == "auto, auto"
    assert rows["pebble graphs"].endswith(" sampled") and rows["pebble graphs"].split()[0].isdigit()
    from planner import PlanStats
    from sim.cli import _print_stats

    out = io.StringIO()
    _print_stats(PlanStats(found=False, g=3, q=150, graphs=3), 0.1, out)  # fixed g and q: their values
    assert "  g, q            3, 150\n" in out.getvalue()


class _Terminal(io.StringIO):
    def isatty(self):
        return True


def test_progress_bar_draws_on_a_terminal_only():
    term = _Terminal()
    bar = ProgressBar("  physics", stream=term)
    for f in (0.0, 0.5, 1.0):
        bar(f, "of 40 s")
    bar.close()
    out = term.getvalue()
    assert "  physics" in out and "100.0%" in out and "of 40 s" in out and out.endswith("\n")
    pipe = io.StringIO()
    quiet = ProgressBar("  physics", stream=pipe)
    quiet(0.5)
    quiet.close()
    assert pipe.getvalue() == ""
    forced = io.StringIO()
    loud = ProgressBar("  video", stream=forced, enabled=True)
    loud(1.0)
    loud.close()
    assert "100.0%" in forced.getvalue()


def test_plan_takes_set_like_run(tmp_path):
    """``swarmform plan --set`` changes the field before the scenario is checked; a bad one exits 2."""
    import json

    fig2 = "scenarios/paper/fig2-random-to-C.yaml"
    out = tmp_path / "p.json"
    r = subprocess.run([EXE, "plan", fig2, "-o", str(out), "--set", "robots.margin=0.25"],
                       capture_output=True, text=True, cwd=ROOT)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "(margin 0.25)" in r.stdout and json.loads(out.read_text())["margin"] == 0.25
    bad = subprocess.run([EXE, "plan", fig2, "-o", str(tmp_path / "q.json"), "--set", "robots.margin=-1"],
                         capture_output=True, text=True, cwd=ROOT)
    assert bad.returncode == 2 and bad.stderr.count("\n") == 1 and "--set robots.margin" in bad.stderr
    assert not (tmp_path / "q.json").exists()
