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
traceback and nothing written.  The test suite checks the same things
(``tests/sim/test_cli_input.py``); this prints the measured figures.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
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
    print(f"| file | exit | seconds | peak RSS [MiB] | stderr lines | longest line | ok |")
    print("| --- | ---: | ---: | ---: | ---: | ---: | --- |")
    for name, r, ok in rows:
        print(f"| {name} | {r['code']} | {r['seconds']:.2f} | {r['rss_mib']:.0f} | {r['lines']} | "
              f"{r['longest']} | {'yes' if ok else 'NO: ' + ' '.join(r['stderr'].split())[:120]} |")
    rs = [r for _, r, _ in rows]
    print()
    print(f"{len(rows)} files, {len(rows) - bad} pass; under prlimit --as={args.address_space}: "
          f"max {max(r['seconds'] for r in rs):.2f} s, max peak RSS {max(r['rss_mib'] for r in rs):.0f} MiB, "
          f"longest error line {max(r['longest'] for r in rs)} characters")
    return 0 if bad == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
