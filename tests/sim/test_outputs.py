"""Output files: paths checked before any work, a run's files replaced as a set, stale temporaries.

A run writes ``NAME.json``, ``NAME.gif`` and ``NAME.mp4`` into a staging
folder ``DIR/.NAME.tmp-PID/`` and moves them into place only at the end.
These tests interrupt runs where it hurts (in the MP4 encoder, by an
exception and by a real SIGINT) and check that the previous run's files are
byte for byte as they were, with nothing left beside them; they kill a run
with SIGKILL and check that its staging folder, which must then be left
behind (the negative control), is removed by the next run.  Unwritable
output paths (a read-only folder, for a user who is not root) are refused
with exit 2 before anything is read or planned.
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from sim.cli import main
from sim.output import files as outputs
from sim.output import media
from sim.output.files import RUN_OUTPUTS, OutputPathError, OutputSet, check_out_dir, check_out_file, remove_stale
from sim.output.media import atomic_path, has_mp4
from sim.runner import run_scenario

ROOT = Path(__file__).resolve().parents[2]
_SCRIPT = Path(sys.executable).with_name("swarmform")
SWARMFORM = [str(_SCRIPT)] if _SCRIPT.exists() else [sys.executable, "-m", "sim.cli"]

# Two robots cross a small room; a tiny, short video so that a rendered run takes a second.
SMALL = """\
name: small
workspace: [20, 20]
robots: {radius: 1.0, margin: 0.1}
start: {points: [[3, 3], [3, 17]]}
target: {points: [[17, 3], [17, 17]]}
sim: {settle_time: 0.5}
render: {size: 64, fps: 10, video_seconds: 2, formats: [gif, mp4]}
"""

needs_mp4 = pytest.mark.skipif(not has_mp4(), reason="imageio-ffmpeg is not installed")


def _scenario(tmp_path: Path, text: str = SMALL) -> Path:
    path = tmp_path / "small.yaml"
    path.write_text(text)
    return path


def _snapshot(folder: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir()) if p.is_file()}


def _dead_pid() -> int:
    p = subprocess.Popen([sys.executable, "-c", "pass"])
    p.wait()
    return p.pid


# ----------------------------------------------------------------------------
# the set


def test_run_outputs_are_listed_once():
    names = [m.format(name="x") for m in RUN_OUTPUTS]
    assert names[:3] == ["x.json", "x.gif", "x.mp4"]
    assert len(set(names)) == len(names)


def test_commit_replaces_the_set_and_removes_members_not_made(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    for name in ("run.json", "run.gif", "run.mp4", "other.txt"):
        (out / name).write_text("old " + name)
    with OutputSet(out, "run") as outs:
        assert outs.staging.parent == out and outs.staging.name == f".run.tmp-{os.getpid()}"
        outs.path("run.json").write_text("new json")
        outs.path("run.gif").write_text("new gif")
        assert (out / "run.json").read_text() == "old run.json"  # nothing moves before the commit
        done = outs.commit()
    assert done == [out / "run.json", out / "run.gif"]
    assert _snapshot(out) == {"other.txt": b"old other.txt", "run.gif": b"new gif", "run.json": b"new json"}
    with pytest.raises(ValueError):
        with OutputSet(out, "run") as outs:
            outs.path("run.txt")  # not a member


def test_an_error_before_the_commit_leaves_the_old_set(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "run.json").write_text("old")
    with pytest.raises(RuntimeError):
        with OutputSet(out, "run") as outs:
            outs.path("run.json").write_text("new")
            raise RuntimeError("physics failed")
    assert _snapshot(out) == {"run.json": b"old"}
    assert sorted(p.name for p in out.iterdir()) == ["run.json"]


def test_a_set_makes_its_folder_and_removes_it_again_on_error(tmp_path):
    out = tmp_path / "a" / "b"
    with pytest.raises(KeyboardInterrupt):
        with OutputSet(out, "run"):
            assert out.is_dir()
            raise KeyboardInterrupt
    assert not (tmp_path / "a").exists()  # nothing written, not even the folders


def test_stale_temporaries_of_dead_processes_are_removed(tmp_path):
    dead, alive = _dead_pid(), os.getppid()
    stale_dir = tmp_path / f".run.tmp-{dead}"
    stale_dir.mkdir()
    (stale_dir / "run.gif").write_text("half")
    stale_file = tmp_path / f".run.json.tmp-{dead}-ab12cd34.json"
    stale_file.write_text("half")
    live = tmp_path / f".run.json.tmp-{alive}-ab12cd34.json"
    live.write_text("being written")
    other = tmp_path / f".other.tmp-{dead}"
    other.mkdir()
    with OutputSet(tmp_path, "run") as outs:
        outs.path("run.json").write_text("{}")
        outs.commit()
    assert not stale_dir.exists() and not stale_file.exists()
    assert live.exists()  # its process still runs
    assert other.exists()  # not this run's name
    # atomic writes clean up after their own dead predecessors too
    (tmp_path / f".pic.png.tmp-{dead}-00ff00ff.png").write_text("half")
    with atomic_path(tmp_path / "pic.png") as tmp:
        assert tmp.name.startswith(f".pic.png.tmp-{os.getpid()}-") and tmp.suffix == ".png"
        tmp.write_text("png")
    assert sorted(p.name for p in tmp_path.iterdir() if p.name.startswith(".pic")) == []
    assert remove_stale(tmp_path, ["nothing"]) == []


# ----------------------------------------------------------------------------
# runs interrupted where it hurts


@needs_mp4
@pytest.mark.parametrize("failure", [KeyboardInterrupt, OSError])
def test_interrupt_in_the_mp4_encoder_keeps_the_previous_run(tmp_path, monkeypatch, failure):
    scen = _scenario(tmp_path)
    out = tmp_path / "media"
    first = run_scenario(scen, out_dir=out, out=None, progress=False)
    assert first.exit_code == 0
    old = _snapshot(out)
    assert set(old) == {"small.json", "small.gif", "small.mp4", "small.html", "small-series.npz"}

    real = media._Mp4Writer.close

    def broken(self, check=True):
        real(self, check)  # the MP4 is complete in the staging folder ...
        raise failure("encoder stopped")  # ... and then the run is interrupted

    monkeypatch.setattr(media._Mp4Writer, "close", broken)
    with pytest.raises(failure):
        run_scenario(scen, seed=5, out_dir=out, out=None, progress=False)
    assert _snapshot(out) == old
    assert sorted(p.name for p in out.iterdir()) == sorted(old)  # no staging folder, no temporary


@needs_mp4
@pytest.mark.parametrize("sig, code, line", [
    (signal.SIGINT, 130, "swarmform: interrupted"),
    (signal.SIGTERM, 143, "swarmform: stopped by SIGTERM"),
    (signal.SIGHUP, 129, "swarmform: stopped by SIGHUP"),
    (signal.SIGQUIT, 131, "swarmform: stopped by SIGQUIT"),
])
def test_a_stop_signal_during_a_run_keeps_the_previous_run(tmp_path, sig, code, line):
    """A real signal once the staging folder exists: its exit code, one line, the old set as it was."""
    scen = _scenario(tmp_path)
    out = tmp_path / "media"
    r = subprocess.run(SWARMFORM + ["run", str(scen), "--out", str(out)], capture_output=True, text=True, cwd=ROOT)
    assert r.returncode == 0, r.stderr
    old = _snapshot(out)
    # The interrupted run has a long video to draw (about 20 s of work after its staging
    # folder appears), so that the signal lands before its outputs are committed even
    # when this process wakes late on a loaded machine.
    _scenario(tmp_path, SMALL.replace("size: 64", "size: 480").replace("video_seconds: 2", "video_seconds: 120")
              .replace("fps: 10", "fps: 20"))
    p = subprocess.Popen(SWARMFORM + ["run", str(scen), "--seed", "3", "--out", str(out)],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=ROOT)
    staging = out / f".small.tmp-{p.pid}"
    deadline = time.monotonic() + 60
    while not staging.exists() and p.poll() is None and time.monotonic() < deadline:
        time.sleep(0.01)
    assert staging.exists(), "the run never made its staging folder"
    time.sleep(0.5)  # into the physics or the rendering
    p.send_signal(sig)
    _, err = p.communicate(timeout=60)
    assert p.returncode == code, err
    assert err.strip().splitlines() == [line]
    assert _snapshot(out) == old
    assert sorted(p.name for p in out.iterdir()) == sorted(old)


def test_sigkill_leaves_a_stale_folder_that_the_next_run_removes(tmp_path):
    scen = _scenario(tmp_path, SMALL.replace("settle_time: 0.5", "settle_time: 600"))
    out = tmp_path / "media"
    p = subprocess.Popen(SWARMFORM + ["run", str(scen), "--out", str(out), "--no-render"],
                         stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, cwd=ROOT)
    staging = out / f".small.tmp-{p.pid}"
    deadline = time.monotonic() + 60
    while not staging.exists() and p.poll() is None and time.monotonic() < deadline:
        time.sleep(0.01)
    p.kill()
    p.wait()
    assert staging.exists()  # the negative control: a killed run leaves it behind
    assert not (out / "small.json").exists()
    result = run_scenario(_scenario(tmp_path), out_dir=out, render=False, out=None, progress=False)
    assert result.exit_code == 0
    assert sorted(p.name for p in out.iterdir()) == ["small-series.npz", "small.html", "small.json"]


def test_the_report_lists_the_final_paths(tmp_path):
    out = tmp_path / "media"
    result = run_scenario(_scenario(tmp_path), out_dir=out, out=None, progress=False)
    report = json.loads((out / "small.json").read_text())
    assert report["media"] == [str(p) for p in result.media]
    assert all(Path(p).parent == out and Path(p).exists() for p in report["media"])


def test_a_run_without_video_removes_the_old_video(tmp_path):
    """The folder never mixes two runs: a report without video does not sit beside an old video."""
    out = tmp_path / "media"
    run_scenario(_scenario(tmp_path), out_dir=out, out=None, progress=False)
    assert (out / "small.gif").exists()
    run_scenario(_scenario(tmp_path), seed=4, out_dir=out, render=False, out=None, progress=False)
    assert sorted(p.name for p in out.iterdir()) == ["small-series.npz", "small.html", "small.json"]
    assert json.loads((out / "small.json").read_text())["media"] == []


# ----------------------------------------------------------------------------
# checks before any work


def test_path_checks(tmp_path):
    (tmp_path / "file").write_text("x")
    (tmp_path / "dir").mkdir()
    assert check_out_dir(tmp_path / "new" / "deeper") == tmp_path / "new" / "deeper"
    assert not (tmp_path / "new").exists()  # a check writes nothing
    assert check_out_file(tmp_path / "dir" / "p.json", "-o") == tmp_path / "dir" / "p.json"
    for bad, option, says in [
        (tmp_path / "file", "--out", "is a file, not a folder"),
        (tmp_path / "file" / "sub", "--out", "is a file"),
        ("", "--out", "is empty"),
    ]:
        with pytest.raises(OutputPathError) as info:
            check_out_dir(bad, option)
        assert says in str(info.value) and str(info.value).startswith(option)
    for bad, says in [
        (tmp_path / "dir", "is a folder"),
        (str(tmp_path / "dir") + "/", "names a folder"),
        (tmp_path / "file" / "p.json", "is a file"),
        (tmp_path / ("n" * 300), "longer than"),
    ]:
        with pytest.raises(OutputPathError) as info:
            check_out_file(bad, "-o")
        assert says in str(info.value)


def test_read_only_file_system_is_refused(tmp_path, monkeypatch):
    class _Vfs:
        f_flag = os.ST_RDONLY

    monkeypatch.setattr(outputs.os, "statvfs", lambda p: _Vfs())
    with pytest.raises(OutputPathError, match="read-only file system"):
        check_out_dir(tmp_path)


def _as_nobody() -> tuple[list[str] | None, str]:
    """A prefix that runs swarmform as an unprivileged user, or None and why not."""
    if os.geteuid() != 0:
        return [], ""
    if not shutil.which("setpriv"):
        return None, "running as root without setpriv: permissions cannot be tested"
    prefix = ["setpriv", "--reuid=65534", "--regid=65534", "--clear-groups"]
    probe = subprocess.run(prefix + SWARMFORM + ["--version"], capture_output=True, text=True, cwd="/")
    if probe.returncode != 0:  # e.g. a checkout inside a folder only root may enter
        return None, f"the unprivileged user cannot run swarmform here: {probe.stderr.strip()[:120]}"
    return prefix, ""


@pytest.mark.parametrize("argv", [
    ["run", "scenarios/paper/fig1-line-to-phi.yaml", "--out", "{ro}"],
    ["run", "scenarios/paper/fig1-line-to-phi.yaml", "--out", "{ro}/sub"],
    ["plan", "scenarios/paper/fig1-line-to-phi.yaml", "-o", "{ro}/p.json"],
    ["show", "scenarios/paper/fig1-line-to-phi.yaml", "-o", "{ro}/s.png"],
], ids=["run", "run-sub", "plan", "show"])
def test_read_only_folder_is_refused_before_any_work(tmp_path, argv):
    prefix, why = _as_nobody()
    if prefix is None:
        pytest.skip(why)
    import tempfile

    home = Path(tempfile.mkdtemp(prefix="swarmform-ro-"))  # reachable by the unprivileged user
    try:
        home.chmod(0o755)
        ro = home / "ro"
        ro.mkdir()
        ro.chmod(0o555)
        env = dict(os.environ, SDL_VIDEODRIVER="dummy", MPLCONFIGDIR=str(home / "mpl"), HOME=str(home))
        t0 = time.monotonic()
        r = subprocess.run(prefix + SWARMFORM + [a.replace("{ro}", str(ro)) for a in argv],
                           capture_output=True, text=True, cwd=ROOT, env=env)
        assert r.returncode == 2, r.stderr
        assert r.stderr.count("\n") == 1 and "is not writable" in r.stderr
        assert r.stdout == ""  # nothing was read, planned or drawn
        assert time.monotonic() - t0 < 30
        assert list(ro.iterdir()) == []
    finally:
        shutil.rmtree(home, ignore_errors=True)


def test_internal_errors_are_exit_3_with_one_line(tmp_path, monkeypatch, capsys):
    """An unexpected exception is exit 3 and one line; --debug adds the traceback."""
    import sim.runner

    def boom(*a, **k):
        raise ZeroDivisionError("something went wrong " + "x" * 500)

    monkeypatch.setattr(sim.runner, "execute", boom)
    scen = _scenario(tmp_path)
    assert main(["run", str(scen), "--out", str(tmp_path / "o"), "--no-render"]) == 3
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 1 and len(err.splitlines()[0]) <= 200
    assert "internal error: ZeroDivisionError" in err and "--debug" in err
    assert not (tmp_path / "o").exists()
    for argv in (["--debug", "run"], ["run", "--debug"]):  # before or after the subcommand
        assert main(argv + [str(scen), "--out", str(tmp_path / "o"), "--no-render"]) == 3
        err = capsys.readouterr().err
        assert "Traceback" in err and "ZeroDivisionError" in err


def test_signals_held_defer_an_interrupt_to_the_end_of_the_block():
    import threading

    from sim.output.files import signals_held

    steps = []
    with pytest.raises(KeyboardInterrupt):
        with signals_held():
            signal.raise_signal(signal.SIGINT)
            steps.append("after the signal")  # the block goes on
    assert steps == ["after the signal"]
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
    # Negative control: without the block the interrupt cuts in at once.
    with pytest.raises(KeyboardInterrupt):
        signal.raise_signal(signal.SIGINT)
        steps.append("never")
    assert steps == ["after the signal"]
    # A signal the system delivers while another thread runs is held as well.
    t = threading.Thread(target=lambda: None)
    t.start()
    with pytest.raises(KeyboardInterrupt):
        with signals_held():
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(0.05)
            steps.append("held")
    t.join()
    assert steps[-1] == "held"


def test_a_closed_standard_output_is_one_line_and_exit_141(tmp_path):
    """``swarmform formations | head -c 1``: the pipe closes early; one line on stderr, exit 141."""
    p = subprocess.Popen(SWARMFORM + ["formations"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, cwd=ROOT)
    p.stdout.close()  # the reader went away before the first byte
    err = p.stderr.read().decode()
    p.wait(timeout=60)
    assert p.returncode == 141, err
    assert err.strip().splitlines() == ["swarmform: standard output was closed (broken pipe); stopped"]


def test_a_full_disk_is_exit_2_naming_the_path(tmp_path, monkeypatch, capsys):
    """ENOSPC while writing an output: one line naming the path, exit 2, nothing left behind."""
    import errno

    fig1 = ROOT / "scenarios" / "paper" / "fig1-line-to-phi.yaml"
    target = tmp_path / "x.png"

    def full(path, image):
        raise OSError(errno.ENOSPC, "No space left on device", str(path))

    monkeypatch.setattr(media, "write_png", full)
    assert main(["show", str(fig1), "-o", str(target)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"swarmform: error: {target}: no space left on device"]
    assert list(tmp_path.iterdir()) == []
    # the negative control: another OSError is still an internal error (exit 3)
    def broken(path, image):
        raise OSError(errno.EIO, "Input/output error", str(path))

    monkeypatch.setattr(media, "write_png", broken)
    assert main(["show", str(fig1), "-o", str(target)]) == 3
