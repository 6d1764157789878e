"""Start-up time of the command line: ``swarmform --help``, ``--version`` and each subcommand's help.

Run with ``python -m bench.startup [--repeats N]``.  Each command runs N
times (default 10) in a fresh process, interleaved with ``python -c pass``
(the interpreter's own start), and the table gives the median and the
slowest wall time of each and the median's ratio to ``python -c pass``.
The bar is 0.3 s for every row: building the parser imports neither the
planner, numpy, pygame nor Dask (``tests/sim/test_startup.py`` checks the
imports; this prints the times).
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import time
from pathlib import Path

__all__ = ["COMMANDS", "main", "measure"]

ROOT = Path(__file__).resolve().parents[1]
BAR_S = 0.3

COMMANDS = {
    "python -c pass": [sys.executable, "-c", "pass"],
    "swarmform --help": ["--help"],
    "swarmform --version": ["--version"],
    **{f"swarmform {c} --help": [c, "--help"] for c in ("formations", "show", "plan", "run", "check", "export", "tune")},
}


def _argv(args: list[str]) -> list[str]:
    if args and args[0] == sys.executable:
        return args
    script = Path(sys.executable).with_name("swarmform")
    return ([str(script)] if script.exists() else [sys.executable, "-m", "sim.cli"]) + args


def measure(repeats: int) -> dict[str, list[float]]:
    """Wall times [s] of each command, ``repeats`` fresh processes each, interleaved."""
    times: dict[str, list[float]] = {name: [] for name in COMMANDS}
    for _ in range(repeats):
        for name, args in COMMANDS.items():
            t0 = time.perf_counter()
            subprocess.run(_argv(args), cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=True)
            times[name].append(time.perf_counter() - t0)
    return times


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench.startup", description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=10, help="fresh processes per command (default 10)")
    args = ap.parse_args(argv)
    times = measure(max(1, args.repeats))
    base = statistics.median(times["python -c pass"])
    print(f"| command | median [s] | slowest [s] | x python -c pass | within {BAR_S} s |")
    print("| --- | --- | --- | --- | --- |")
    ok = True
    for name, ts in times.items():
        med = statistics.median(ts)
        within = med <= BAR_S
        ok &= within
        print(f"| `{name}` | {med:.3f} | {max(ts):.3f} | {med / base:.1f} | {'yes' if within else 'NO'} |")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
