"""Results and plan files are judged as they are read, in bounded memory; a full disk leaves no torn row.

Big files are made sparse in ``tmp_path`` (``truncate``), so the tests are
fast.  Each refusal is exit 2 with one line naming the file, the line or
field and the reason, and leaves the file untouched; negative controls show
the same paths accept a good file.
"""

from __future__ import annotations

import errno
import json
import os
import sys
from pathlib import Path

import pytest

import sim.tune.results as results_mod
from planner.inputfile import JsonRefused, load_json
from sim.cli import main
from sim.tune import TuneError, read_results
from sim.tune.results import MAX_RESULTS_BYTES, MAX_ROW_BYTES, ResultsFile, check_output

ROOT = Path(__file__).resolve().parents[2]
FIG2 = ROOT / "scenarios" / "paper" / "fig2-random-to-C.yaml"
ONE_RUN = ["--g", "1", "--q", "20", "--seeds", "1", "--workers", "1", "--no-progress"]

ROW = {"scenario": "fig2", "mode": "fixed", "g": 1, "q": 20, "seed": 0, "time_limit": 60.0,
       "simulate": False, "found": True}


def _line(**changes) -> bytes:
    return (json.dumps({**ROW, **changes}) + "\n").encode()




def _tune(argv, capsys):
    try:
        code = main(["tune", *map(str, argv)])
    except SystemExit as exc:
        code = exc.code
    out, err = capsys.readouterr()
    return code, out, err


def _state(path: Path):
    st = os.stat(path)
    return st.st_size, st.st_mtime_ns


def _one_line_refusal(code, err, *words):
    assert code == 2, err
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    for w in words:
        assert w in err, err


def _count_reads(monkeypatch, path: Path) -> list[int]:
    """The sizes asked of ``os.read`` on descriptors open on ``path``."""
    reads = []
    real_read = os.read
    target = os.path.realpath(path)

    def read(fd, n):
        data = real_read(fd, n)
        try:
            if os.readlink(f"/proc/self/fd/{fd}") == target:
                reads.append(len(data))
        except OSError:
            pass
        return data

    monkeypatch.setattr(os, "read", read)
    return reads


# ---------------------------------------------------------------- results files: size and line caps

def test_a_sparse_file_over_the_cap_is_refused_without_reading(tmp_path, marker, capsys, monkeypatch):
    path = tmp_path / "big.jsonl"
    with open(path, "wb") as f:
        f.truncate(2 << 30)  # 2 GiB, sparse
    before = _state(path)
    reads = _count_reads(monkeypatch, path)
    for argv in (["-o", path, FIG2, *ONE_RUN], ["--summarize", path]):
        code, _, err = _tune(argv, capsys)
        _one_line_refusal(code, err, "big.jsonl", "2048 MiB", f"{MAX_RESULTS_BYTES >> 20} MiB")
    assert reads == []  # refused on its size, before a byte was read
    assert not marker.exists()
    assert _state(path) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["big.jsonl"]
    path.unlink()


def test_a_bad_first_line_is_refused_after_reading_one_chunk(tmp_path, marker, capsys, monkeypatch):
    path = tmp_path / "notes.jsonl"
    with open(path, "wb") as f:
        f.write(b"not a row\n" + _line())
        f.truncate(200 << 20)  # 200 MiB, under the cap: judged line by line
    before = _state(path)
    reads = _count_reads(monkeypatch, path)
    for flag in ("-o", "--summarize"):
        reads.clear()
        argv = ["-o", path, FIG2, *ONE_RUN] if flag == "-o" else ["--summarize", path]
        code, _, err = _tune(argv, capsys)
        _one_line_refusal(code, err, "--output: " if flag == "-o" else "--summarize: ", "notes.jsonl",
                          "line 1 is not a result row")
        assert 1 <= len(reads) <= 2 and sum(reads) <= 2 << 20  # a chunk or two, not 200 MiB
    assert not marker.exists()
    assert _state(path) == before
    path.unlink()


def test_a_bad_later_line_is_named(tmp_path):
    path = tmp_path / "r.jsonl"
    path.write_bytes(_line(seed=0) + _line(seed=1) + b"[1, 2]\n" + _line(seed=3))
    with pytest.raises(TuneError, match=r"r\.jsonl: is not a results file \(line 3 is not a result row\)"):
        check_output(path)


def test_an_overlong_line_is_refused(tmp_path):
    path = tmp_path / "r.jsonl"
    path.write_bytes(_line() + b'{"scenario": "' + b"x" * (MAX_ROW_BYTES + 10) + b'"}\n')
    with pytest.raises(TuneError, match=r"line 2 is longer than the 1 MiB"):
        check_output(path)
    path.write_bytes(_line() + b'{"scenario": "' + b"x" * (MAX_ROW_BYTES + 10))  # no newline: not a torn row
    with pytest.raises(TuneError, match=r"line 2 is longer than the 1 MiB"):
        check_output(path)


def test_negative_control_good_files_across_chunks_are_read(tmp_path, capsys):
    """Rows split across 1 MiB read chunks, a torn tail cut on open, and --summarize accepts it."""
    path = tmp_path / "r.jsonl"
    rows = [_line(seed=s, pad="p" * (s * 997 % 5000)) for s in range(800)]
    good = b"".join(rows)
    assert len(good) > 2 * (1 << 20)
    torn = _line(seed=9999)[:30]
    path.write_bytes(good + torn)
    assert [r["seed"] for r in read_results(path)] == list(range(800))
    check_output(path)
    log = []

    class Log:
        def write(self, s):
            log.append(s)

    f = ResultsFile(path, Log())
    try:
        assert len(f.rows) == 800
    finally:
        f.close()
    assert path.read_bytes() == good
    assert "cut off a torn last line (30 bytes)" in "".join(log)
    code, _, err = _tune(["--summarize", path], capsys)
    assert code == 0, err


# ---------------------------------------------------------------- a full disk leaves no torn row

@pytest.mark.parametrize("fail_on", [1, 2, 3])
def test_enospc_leaves_only_whole_rows(tmp_path, monkeypatch, fail_on):
    path = tmp_path / "r.jsonl"
    path.write_bytes(_line(seed=0))
    f = ResultsFile(path, None)
    real_write = os.write
    calls = []

    def write(fd, data):
        calls.append(len(data))
        if fd == f._fd and len(calls) == fail_on:
            # a full disk: part of the row may reach the file before the error
            real_write(fd, bytes(data)[: len(data) // 2])
            raise OSError(errno.ENOSPC, "No space left on device")
        return real_write(fd, data)

    monkeypatch.setattr(results_mod.os, "write", write)
    try:
        appended = 0
        with pytest.raises(TuneError) as info:
            for seed in range(1, 10):
                f.append({**ROW, "seed": seed, "pad": "z" * 500})
                appended += 1
        assert str(info.value) == f"{path}: no space left on device"
        assert appended == fail_on - 1
    finally:
        f.close()
    data = path.read_bytes()
    assert data.endswith(b"\n")
    lines = data.splitlines()
    assert len(lines) == fail_on  # the first row and those appended before the failure
    assert [json.loads(x)["seed"] for x in lines] == list(range(fail_on))
    assert all(n > 500 for n in calls)  # each write was the whole encoded line


def test_enospc_through_the_cli_is_exit_2_one_line(tmp_path, monkeypatch, capsys):
    path = tmp_path / "r.jsonl"

    real_write = os.write
    target = os.path.realpath(path)

    def write(fd, data):
        try:
            mine = os.readlink(f"/proc/self/fd/{fd}") == target
        except OSError:
            mine = False
        if mine:
            raise OSError(errno.ENOSPC, "No space left on device")
        return real_write(fd, data)

    monkeypatch.setattr(os, "write", write)
    code, _, err = _tune([FIG2, *ONE_RUN, "-o", path], capsys)
    assert code == 2, err
    assert "Traceback" not in err
    # the run had started (its progress line), then one error line
    assert err.splitlines()[-1] == f"swarmform: error: {path}: no space left on device"
    assert err.count("error:") == 1
    assert path.read_bytes() == b""


def test_negative_control_other_write_errors_are_not_called_a_full_disk(tmp_path, monkeypatch):
    path = tmp_path / "r.jsonl"
    f = ResultsFile(path, None)
    monkeypatch.setattr(results_mod.os, "write", lambda fd, d: (_ for _ in ()).throw(OSError(errno.EIO, "I/O")))
    try:
        with pytest.raises(OSError) as info:
            f.append(dict(ROW))
        assert not isinstance(info.value, TuneError) and info.value.errno == errno.EIO
    finally:
        f.close()
    assert path.read_bytes() == b""


# ---------------------------------------------------------------- bounded JSON (plan files)

def test_load_json_refuses_a_padded_document_before_parsing(monkeypatch):
    import json as json_mod

    called = []
    real = json_mod.loads
    monkeypatch.setattr(json_mod, "loads", lambda *a, **k: called.append(1) or real(*a, **k))
    text = '{"radius": 1, "waypoints": [' + ",".join(["[]"] * 50) + "]}"
    with pytest.raises(JsonRefused) as info:
        load_json(text, max_containers=50)
    assert info.value.where == "file" and "52 lists and objects" in info.value.reason
    assert called == []
    assert load_json(text, max_containers=52)["radius"] == 1  # negative control
    assert called == [1]


def test_load_json_refuses_a_repeated_key_naming_it():
    with pytest.raises(JsonRefused) as info:
        load_json('{"radius": 1, "stats": {"g": 1, "g": 2}}')
    assert info.value.where == "g" and "given twice" in info.value.reason
    with pytest.raises(JsonRefused) as info:
        load_json('{"radius": 1,\n "radius": 2}')
    assert info.value.where == "radius"
    assert load_json('{"radius": 1, "stats": {"g": 1}}') == {"radius": 1, "stats": {"g": 1}}  # negative control


# ----------------------------------------------------------------------------
# the summary beside the results: only files the sweep wrote are replaced


def test_tune_refuses_to_replace_a_users_own_notes(tmp_path):
    """``tune -o notes.jsonl`` beside the user's notes.md: exit 2 before any run, the file untouched."""
    import subprocess

    fig2 = Path(__file__).resolve().parents[2] / "scenarios" / "paper" / "fig2-random-to-C.yaml"
    mine = tmp_path / "notes.md"
    mine.write_text("# my notes\nkeep me\n")
    argv = [sys.executable, "-m", "sim.cli", "tune", str(fig2), "--g", "1", "--q", "20", "--seeds", "1",
            "-o", str(tmp_path / "notes.jsonl")]
    r = subprocess.run(argv, capture_output=True, text=True, timeout=300)
    assert r.returncode == 2, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "notes.md: not written by swarmform tune, so not replaced" in lines[0], lines
    assert mine.read_text() == "# my notes\nkeep me\n"
    assert not (tmp_path / "notes.jsonl").exists()
    # the negative control: without the user's file the sweep writes its own, and then may replace it
    mine.unlink()
    r = subprocess.run(argv, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "notes.md").read_text().startswith("<!-- swarmform tune summary")
    assert "<!-- swarmform tune summary" in (tmp_path / "notes.html").read_text()[:300]
    r = subprocess.run(argv, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
