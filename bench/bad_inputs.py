"""Every file of the bad-input corpus through the installed command, bounded: a table.

Run with ``python -m bench.bad_inputs [--as BYTES] [--timeout S]``.  Each
file of ``tests/data/bad/`` goes through ``swarmform run`` exactly as a user
would start it, under ``prlimit --as`` (address space 2 GiB by default) and
a timeout: a scenario file as ``run FILE``, a plan file (``.json``) as
``run tests/data/plan-base.yaml --plan FILE``, each with an empty output
folder of its own.  The table gives, per file, the exit code, the wall
time, the peak resident memory (from ``wait4``), the number of lines on
stderr and the length of the longest, whether a traceback appeared and
whether anything was written; the summary gives the largest of each.
A file passes when it exits 2 with one line of at most 200 characters, no
traceback and nothing written.  A second table runs the cases no file can
hold (:data:`SCRIPTED`: ``--set`` values with anchors or tags, a ``show -o``
suffix that is not ``.png``, a Dask scheduler that accepts and stays silent,
exit 4, a 50 MB results file whose first line is wrong, a sparse 2 GiB one, a plan
padded to 60 MB, and a full disk under ``run --out`` and ``show -o``) with the same
checks and their own exit codes.  The test suite checks the same things
(``tests/sim/test_cli_input.py``); this prints the measured figures.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import shutil
import socket
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

__all__ = ["main", "run_case"]

ROOT = Path(__file__).resolve().parents[1]
BAD = ROOT / "tests" / "data" / "bad"
PLAN_BASE = ROOT / "tests" / "data" / "plan-base.yaml"
LINE_MAX = 200


def _command() -> list[str]:
    script = Path(sys.executable).with_name("swarmform")
    return [str(script)] if script.exists() else [sys.executable, "-m", "sim.cli"]


def argv_for(path: Path, out_dir: Path) -> list[str]:
    """The ``swarmform`` arguments that feed ``path`` to the command."""
    if path.suffix == ".json":
        return ["run", str(PLAN_BASE.relative_to(ROOT)), "--plan", str(path.relative_to(ROOT)),
                "--out", str(out_dir), "--no-render"]
    return ["run", str(path.relative_to(ROOT)), "--out", str(out_dir), "--no-render"]


def run_case(argv: list[str], out_dir: Path, address_space: int, timeout: float) -> dict:
    """Run ``swarmform ARGV`` under prlimit; exit code, seconds, peak RSS [MiB], stderr, files."""
    env = dict(os.environ, SDL_VIDEODRIVER="dummy", SDL_AUDIODRIVER="dummy")
    cmd = ["prlimit", f"--as={address_space}", "--"] + _command() + argv
    with tempfile.TemporaryFile() as err, tempfile.TemporaryFile() as out:
        t0 = time.perf_counter()
        proc = subprocess.Popen(cmd, cwd=ROOT, env=env, stdout=out, stderr=err, stdin=subprocess.DEVNULL)
        deadline = t0 + timeout
        status = rusage = None
        while True:
            pid, status, rusage = os.wait4(proc.pid, os.WNOHANG)
            if pid:
                break
            if time.perf_counter() > deadline:
                proc.kill()
                _, status, rusage = os.wait4(proc.pid, 0)
                break
            time.sleep(0.005)
        seconds = time.perf_counter() - t0
        proc.returncode = os.waitstatus_to_exitcode(status)
        err.seek(0)
        stderr = err.read().decode("utf-8", "replace")
    lines = stderr.splitlines()
    return {
        "code": proc.returncode,
        "seconds": seconds,
        "rss_mib": rusage.ru_maxrss / 1024,
        "lines": len(lines),
        "longest": max((len(line) for line in lines), default=0),
        "traceback": "Traceback" in stderr,
        "written": sorted(p.name for p in out_dir.iterdir()) if out_dir.exists() else [],
        "stderr": stderr,
        "timed_out": seconds >= timeout,
    }


FIG1 = "scenarios/paper/fig1-line-to-phi.yaml"

#: Command-line cases no file can hold: name -> (argv with {d} for the case's
#: folder, the exit code expected).  ``silent-scheduler`` runs against a
#: loopback listener that accepts and never answers; ``full-disk`` writes into
#: a 256 KiB tmpfs (root only; skipped elsewhere).
SCRIPTED = {
    "set-anchor": (["run", FIG1, "--no-render", "--out", "{d}", "--set", "robots.margin=&a 0.1"], 2),
    "set-tag": (["run", FIG1, "--no-render", "--out", "{d}", "--set", "robots.margin=!!python/name:os.system"], 2),
    "show-jpg-suffix": (["show", FIG1, "-o", "{d}/x.jpg"], 2),
    "silent-scheduler": (["tune", FIG1, "--g", "2", "--q", "50", "--seeds", "1", "--scheduler", "tcp://{listener}",
                          "-o", "{d}/r.jsonl"], 4),
    "results-bad-first-line-50MB": (["tune", "--summarize", "{d}/bad.jsonl"], 2),
    "results-sparse-2GiB": (["tune", FIG1, "--g", "2", "--q", "50", "--seeds", "1", "-o", "{d}/big.jsonl"], 2),
    "plan-padded-60MB": (["run", "tests/data/plan-base.yaml", "--plan", "{d}/pad.json", "--no-render",
                          "--out", "{d}/o"], 2),
    "full-disk-run": (["run", FIG1, "--out", "{full}/o"], 2),
    "full-disk-show": (["show", FIG1, "-o", "{full}/s.png"], 2),
}


def _prepare(name: str, d: Path) -> None:
    """The input files a scripted case reads, made in its folder (they do not count as written)."""
    if name == "results-bad-first-line-50MB":
        with open(d / "bad.jsonl", "w") as f:
            f.write("this is not a result row\n")
            row = '{"scenario": "x"}\n'
            f.write(row * ((50 << 20) // len(row)))
    elif name == "results-sparse-2GiB":
        with open(d / "big.jsonl", "wb") as f:
            f.truncate(2 << 30)
    elif name == "plan-padded-60MB":
        with open(d / "pad.json", "w") as f:
            f.write('{"radius": 1.0, "margin": 0.1, "durations": [10.0], '
                    '"waypoints": [[[5, 5], [5, 35]], [[35, 5], [35, 35]]], "stats": {"pad": [')
            f.write("[]," * ((60 << 20) // 3))
            f.write("[]]}}")


@contextlib.contextmanager
def _silent_listener():
    """A loopback TCP listener that accepts connections and never sends a byte."""
    srv = socket.socket()
    srv.bind(("127.0.0.1", 0))
    srv.listen(8)
    srv.settimeout(0.2)
    held, stop = [], threading.Event()

    def serve():
        while not stop.is_set():
            try:
                held.append(srv.accept()[0])
            except OSError:
                pass

    t = threading.Thread(target=serve, daemon=True)
    t.start()
    try:
        yield "127.0.0.1:%d" % srv.getsockname()[1]
    finally:
        stop.set()
        t.join(2)
        for c in held:
            c.close()
        srv.close()


@contextlib.contextmanager
def _full_disk(tmp: Path):
    """A nearly full 256 KiB tmpfs, or None where it cannot be mounted."""
    mnt = tmp / "full"
    mnt.mkdir()
    if subprocess.run(["mount", "-t", "tmpfs", "-o", "size=256k", "tmpfs", str(mnt)],
                      capture_output=True).returncode != 0:
        yield None
        return
    try:
        (mnt / "filler").write_bytes(b"\0" * (252 << 10))
        yield mnt
    finally:
        subprocess.run(["umount", "-l", str(mnt)], capture_output=True)


def scripted_rows(tmp: Path, address_space: int, timeout: float) -> list[tuple[str, dict | None, bool]]:
    """Run :data:`SCRIPTED`; a row's result is None when its case cannot run on this machine."""
    rows = []
    with _silent_listener() as listener, _full_disk(tmp) as full:
        for name, (args, code) in SCRIPTED.items():
            if "{full}" in " ".join(args) and full is None:
                rows.append((name, None, True))
                continue
            out_dir = tmp / f"script-{name}"
            out_dir.mkdir()
            _prepare(name, out_dir)
            given = {p.name: p.stat().st_size for p in out_dir.iterdir()}
            argv = [a.format(d=out_dir, listener=listener, full=full) for a in args]
            r = run_case(argv, out_dir, address_space, timeout)
            kept = all((out_dir / n).exists() and (out_dir / n).stat().st_size == size for n, size in given.items())
            r["written"] = [n for n in r["written"] if n not in given] + ([] if kept else ["(an input changed)"])
            for n in given:
                (out_dir / n).unlink(missing_ok=True)
            if full is not None and "{full}" in " ".join(args):
                r["written"] = sorted(p.name for p in full.rglob("*") if p.name != "filler")
            ok = (r["code"] == code and r["lines"] == 1 and r["longest"] <= LINE_MAX and not r["traceback"]
                  and not r["written"])
            rows.append((name, r, ok))
    return rows


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--as", dest="address_space", type=int, default=2 << 30,
                    help="address-space limit per run [bytes] (default 2 GiB)")
    ap.add_argument("--timeout", type=float, default=60.0, help="seconds per run (default 60)")
    ap.add_argument("files", nargs="*", help="corpus files (default: all of tests/data/bad/)")
    args = ap.parse_args(argv)
    if shutil.which("prlimit") is None:
        print("prlimit (util-linux) is needed", file=sys.stderr)
        return 2
    files = [Path(f).resolve() for f in args.files] or sorted(BAD.iterdir())
    rows, bad = [], 0
    with tempfile.TemporaryDirectory() as tmp:
        for k, path in enumerate(files):
            out_dir = Path(tmp) / f"out{k}"
            out_dir.mkdir()
            r = run_case(argv_for(path, out_dir), out_dir, args.address_space, args.timeout)
            ok = (r["code"] == 2 and r["lines"] == 1 and r["longest"] <= LINE_MAX and not r["traceback"]
                  and not r["written"])
            bad += not ok
            rows.append((path.name, r, ok))
        scripted = [] if args.files else scripted_rows(Path(tmp), args.address_space, args.timeout)
    print("| file | exit | seconds | peak RSS [MiB] | stderr lines | longest line | ok |")
    print("| --- | ---: | ---: | ---: | ---: | ---: | --- |")
    for name, r, ok in rows:
        print(f"| {name} | {r['code']} | {r['seconds']:.2f} | {r['rss_mib']:.0f} | {r['lines']} | "
              f"{r['longest']} | {'yes' if ok else 'NO: ' + ' '.join(r['stderr'].split())[:120]} |")
    if scripted:
        print()
        print("| scripted case | exit | seconds | peak RSS [MiB] | stderr lines | longest line | ok |")
        print("| --- | ---: | ---: | ---: | ---: | ---: | --- |")
        for name, r, ok in scripted:
            if r is None:
                print(f"| {name} | - | - | - | - | - | skipped: needs root to mount a tmpfs |")
                continue
            bad += not ok
            print(f"| {name} | {r['code']} | {r['seconds']:.2f} | {r['rss_mib']:.0f} | {r['lines']} | "
                  f"{r['longest']} | {'yes' if ok else 'NO: ' + ' '.join(r['stderr'].split())[:120]} |")
        rows = rows + [row for row in scripted if row[1] is not None]
    rs = [r for _, r, _ in rows]
    print()
    print(f"{len(rows)} cases, {len(rows) - bad} pass; under prlimit --as={args.address_space}: "
          f"max {max(r['seconds'] for r in rs):.2f} s, max peak RSS {max(r['rss_mib'] for r in rs):.0f} MiB, "
          f"longest error line {max(r['longest'] for r in rs)} characters")
    return 0 if bad == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
