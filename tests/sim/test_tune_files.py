"""Which files ``tune -o`` appends to: its own results files only, never through a link.

Every refusal is exit 2 with one line, before any run (a hook in the run
leaves a marker file when a run starts; the negative control shows it
does), and leaves the file byte-identical with the same mtime.
"""

from __future__ import annotations

import json
import os
import threading
from pathlib import Path

import pytest

from sim.cli import main
from sim.scenario import read_scenario
from sim.tune import TuneError, grid, read_results, sweep

ROOT = Path(__file__).resolve().parents[2]
FIG2 = ROOT / "scenarios" / "paper" / "fig2-random-to-C.yaml"
ONE_RUN = ["--g", "1", "--q", "20", "--seeds", "1", "--workers", "1", "--no-progress"]




def _tune(argv, capsys) -> tuple[int, str, str]:
    try:
        code = main(["tune", str(FIG2), *ONE_RUN, *map(str, argv)])
    except SystemExit as exc:
        code = exc.code
    out, err = capsys.readouterr()
    return code, out, err


def _state(path: Path) -> tuple:
    st = os.lstat(path)
    return (path.read_bytes() if path.is_file() and not path.is_symlink() else None, st.st_mtime_ns, st.st_mode)


def _refused(code, err, marker, *words):
    assert code == 2, err
    assert len(err.splitlines()) == 1 and "Traceback" not in err
    assert err.startswith("swarmform: error: --output: ")
    for w in words:
        assert w in err
    assert not marker.exists(), "a run started before the output was checked"


def test_a_new_file_is_written_and_the_marker_sees_runs(tmp_path, marker, capsys):
    """Negative control: with a good -o, a run starts (the marker appears) and the file grows."""
    out = tmp_path / "results.jsonl"
    code, _, err = _tune(["-o", out], capsys)
    assert code == 0, err
    assert marker.exists()
    assert len(read_results(out)) == 1
    before = out.read_bytes()
    assert _tune(["-o", out, "--seeds", "2"], capsys)[0] == 0
    assert out.read_bytes() != before and out.read_bytes().startswith(before)


def test_a_notes_file_is_refused_and_untouched(tmp_path, marker, capsys):
    notes = tmp_path / "notes.txt"
    notes.write_bytes(b"meeting notes\nline two, no newline at the end")
    os.utime(notes, ns=(1_000_000_000, 1_000_000_000))
    before = _state(notes)
    code, out, err = _tune(["-o", notes], capsys)
    _refused(code, err, marker, "notes.txt", "not a results file", "line 1")
    assert _state(notes) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["notes.txt"]  # no notes.md, .html, .png
    assert "runs to compute" not in out + err


def test_a_file_of_rows_and_other_lines_is_refused(tmp_path, marker, capsys):
    path = tmp_path / "results.jsonl"
    assert _tune(["-o", path], capsys)[0] == 0
    marker.unlink()
    path.write_bytes(path.read_bytes() + b"# a comment\n")
    before = _state(path)
    code, _, err = _tune(["-o", path, "--seeds", "2"], capsys)
    _refused(code, err, marker, "line 2 is not a result row")
    assert _state(path) == before


def test_a_last_line_that_is_not_the_start_of_a_row_is_refused(tmp_path, marker, capsys):
    path = tmp_path / "results.jsonl"
    assert _tune(["-o", path], capsys)[0] == 0
    marker.unlink()
    path.write_bytes(path.read_bytes() + b"notes without a newline")
    before = _state(path)
    code, _, err = _tune(["-o", path, "--seeds", "2"], capsys)
    _refused(code, err, marker, "last line")
    assert _state(path) == before


def test_a_symlink_is_refused_and_its_target_untouched(tmp_path, marker, capsys):
    """Even a link to a real results file: the sweep never writes through a link."""
    target = tmp_path / "real.jsonl"
    assert _tune(["-o", target], capsys)[0] == 0
    marker.unlink()
    os.utime(target, ns=(2_000_000_000, 2_000_000_000))
    before = _state(target)
    link = tmp_path / "link.jsonl"
    link.symlink_to(target)
    code, _, err = _tune(["-o", link, "--seeds", "2"], capsys)
    _refused(code, err, marker, "symbolic link")
    assert _state(target) == before and link.is_symlink()
    with pytest.raises(TuneError, match="symbolic link"):
        sweep(grid([read_scenario(FIG2)], g=[1], q=[20], seeds=[5]), link, workers=1)
    assert _state(target) == before


def test_a_dangling_symlink_is_refused_and_nothing_created(tmp_path, marker, capsys):
    link = tmp_path / "link.jsonl"
    link.symlink_to(tmp_path / "elsewhere.jsonl")
    code, _, err = _tune(["-o", link], capsys)
    _refused(code, err, marker, "symbolic link")
    assert not (tmp_path / "elsewhere.jsonl").exists()


@pytest.mark.parametrize("kind", ["directory", "fifo", "device", "parent-is-a-file", "summary-is-a-directory"])
def test_other_kinds_of_files_are_refused(kind, tmp_path, marker, capsys):
    out = tmp_path / "results.jsonl"
    words = {"directory": "is a directory", "fifo": "is a FIFO", "device": "is a device",
             "parent-is-a-file": "is not a folder", "summary-is-a-directory": "results.md: is a directory"}[kind]
    if kind == "directory":
        out.mkdir()
    elif kind == "fifo":
        os.mkfifo(out)
    elif kind == "device":
        out = Path(os.devnull)
    elif kind == "parent-is-a-file":
        (tmp_path / "plain").write_text("x")
        out = tmp_path / "plain" / "results.jsonl"
    else:
        (tmp_path / "results.md").mkdir()
    result = {}
    # a FIFO opened the wrong way would block for ever: run in a thread and give up after a while
    thread = threading.Thread(target=lambda: result.update(r=_tune(["-o", out], capsys)), daemon=True)
    thread.start()
    thread.join(60)
    assert not thread.is_alive(), "tune -o blocked"
    code, _, err = result["r"]
    _refused(code, err, marker, words)
    if kind == "summary-is-a-directory":
        assert not out.exists()


def test_an_empty_file_is_a_results_file(tmp_path, capsys):
    path = tmp_path / "results.jsonl"
    path.write_bytes(b"")
    assert _tune(["-o", path], capsys)[0] == 0
    assert len(read_results(path)) == 1


def test_a_file_of_the_previous_format_resumes(tmp_path, capsys):
    """Rows without ``settings`` and ``worker`` (written before they existed) count as runs without settings."""
    path = tmp_path / "results.jsonl"
    assert _tune(["-o", path, "--seeds", "2"], capsys)[0] == 0
    old = []
    for row in read_results(path):
        del row["settings"], row["worker"]
        old.append(json.dumps(row) + "\n")
    path.write_text("".join(old))
    before = path.read_bytes()
    code, out, _ = _tune(["-o", path, "--seeds", "2"], capsys)
    assert code == 0 and "0 runs computed" in out and "2 were already in" in out
    assert path.read_bytes() == before
    code, out, _ = _tune(["-o", path, "--seeds", "3"], capsys)
    assert code == 0 and "1 runs computed" in out
    assert path.read_bytes().startswith(before) and len(read_results(path)) == 3


def test_a_link_that_appears_after_the_check_is_still_refused(tmp_path, monkeypatch):
    """The open itself refuses a link (O_NOFOLLOW), for a link put in place between check and open."""
    import sim.tune.results as results

    target = tmp_path / "real.jsonl"
    target.write_bytes(b"")
    link = tmp_path / "link.jsonl"
    link.symlink_to(target)
    monkeypatch.setattr(results, "check_output", lambda path: path)
    with pytest.raises(TuneError, match="symbolic link"):
        results.ResultsFile(link, log=None)
    assert target.read_bytes() == b""
