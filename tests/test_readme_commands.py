"""Every command the README shows still runs.

Commands come from the README's shell blocks (```sh, or ``` without a language). A
synopsis line with placeholders (SCENARIO, PLAN.json, [--seed N]) is not a command and is
left out. Quick commands must finish with exit 0 within their time; long ones (sweeps,
benchmarks, mutation testing) must start: still running after a few seconds, or done
with exit 0. The set-up and test commands are what CI itself runs, so they are left out
here. Commands run in a scratch folder that links the repository's data, so their
outputs (media/...) land there.
"""

import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
FENCE = re.compile(r"^```(\w*)\n(.*?)^```", re.S | re.M)
PLACEHOLDER = re.compile(r"\b[A-Z][A-Z_]{2,}\b|\.\.\.|\[-|\]\s*$")
LONG = ("swarmform tune", "python -m bench", ".venv/bin/python -m bench", "prlimit", "python tests/mutation",
        ".venv/bin/python tests/mutation", "swarmform check scenarios/paper")
SKIP = ("python3 -m venv", ".venv/bin/pip", "python -m pytest", ".venv/bin/python -m pytest", "source ")
START_S = 3.0  # a long command must still be running (or be done, exit 0) after this long
QUICK_S = 240.0


def readme_commands(text: str) -> list[str]:
    """The README's runnable shell commands, in order (continuation lines joined)."""
    out = []
    for lang, body in ((m.group(1), m.group(2)) for m in FENCE.finditer(text)):
        if lang not in ("", "sh", "bash", "shell"):
            continue
        body = re.sub(r"\\\n\s*", " ", body)
        for line in body.splitlines():
            cmd = line.split(" #", 1)[0].strip() if not line.lstrip().startswith("#") else ""
            if not cmd or cmd.startswith(SKIP) or "&&" in cmd and cmd.startswith("python3 -m venv"):
                continue
            if PLACEHOLDER.search(cmd):
                continue
            out.append(cmd)
    return out


def _scratch(tmp_path: Path) -> Path:
    for name in ("scenarios", "tests", "docs", "bench", "media"):
        if name == "media":
            (tmp_path / "media").mkdir()
        else:
            (tmp_path / name).symlink_to(ROOT / name)
    return tmp_path


def _env() -> dict:
    env = dict(os.environ)
    bin_dir = str(Path(sys.executable).parent)
    env["PATH"] = bin_dir + os.pathsep + env.get("PATH", "")
    env["PYTHONPATH"] = str(ROOT) + os.pathsep + env.get("PYTHONPATH", "")
    return env


def _shell(cmd: str) -> str:
    """The command as this interpreter runs it (``.venv/bin/`` prefixes and ``python`` mapped to it)."""
    cmd = re.sub(r"(^|\s)\.venv/bin/", r"\1", cmd)
    return re.sub(r"(^|;\s*|do\s+)python(?=\s)", lambda m: m.group(1) + sys.executable, cmd)


def _run(cmd: str, cwd: Path, long: bool) -> tuple[int | None, str]:
    p = subprocess.Popen(["bash", "-c", _shell(cmd)], cwd=cwd, env=_env(), stdout=subprocess.DEVNULL,
                         stderr=subprocess.PIPE, text=True, start_new_session=True)
    try:
        _, err = p.communicate(timeout=START_S if long else QUICK_S)
        return p.returncode, err
    except subprocess.TimeoutExpired:
        os.killpg(p.pid, signal.SIGKILL)
        _, err = p.communicate()
        return None, err  # still running


def test_the_readme_has_commands():
    cmds = readme_commands((ROOT / "README.md").read_text(encoding="utf-8"))
    assert len(cmds) >= 10, cmds
    assert any(c.startswith("swarmform check") for c in cmds) and any(c.startswith("swarmform export") for c in cmds)


def test_every_readme_command_runs(tmp_path):
    cwd = _scratch(tmp_path)
    failed = []
    t0 = time.perf_counter()
    for cmd in readme_commands((ROOT / "README.md").read_text(encoding="utf-8")):
        long = cmd.startswith(LONG) or cmd.startswith("for ")
        code, err = _run(cmd, cwd, long)
        if not (code == 0 or (long and code is None)):
            failed.append(f"{cmd!r}: exit {code}: {err.strip().splitlines()[-1:] if err.strip() else ''}")
    assert failed == [], failed
    assert time.perf_counter() - t0 < 600


@pytest.mark.parametrize("cmd", ["swarmform run scenarios/paper/no-such-file.yaml", "swarmform frobnicate"])
def test_a_command_that_does_not_run_is_caught(tmp_path, cmd):
    # negative control: a broken command fails the check
    code, _ = _run(cmd, _scratch(tmp_path), long=False)
    assert code not in (0, None)
