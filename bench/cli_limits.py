"""Time limits of the whole command: ``swarmform plan`` on map scenarios with crowds.

Run ``python -m bench.cli_limits`` (``--help`` for the options).  Each row runs
``swarmform plan SCENARIO --time-limit L --set robots.count=M`` in a fresh
process and reports its wall time against ``1.1 L + 0.5 s``: the limit counts
from the command's start, so reading the map, placing the robots and the
imports are inside it (:mod:`bench.frontier`'s time-limit table times the
``plan`` call alone, on problems built outside it).  Cases: the scenarios in
``scenarios/maps`` with their own counts and with crowds of them (a scatter
of thousands of robots over a map takes seconds by itself).
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from ._common import machine_info, markdown_table

__all__ = ["CASES", "main", "run_case"]

ROOT = Path(__file__).resolve().parents[1]
#: (scenario under scenarios/maps, robot count): their own counts, then crowds
CASES = (("room-32-32-4-100.yaml", 100), ("den312d-scatter-200.yaml", 200), ("office-ros-50.yaml", 50),
         ("den312d-scatter-200.yaml", 1500), ("office-ros-50.yaml", 250))
LIMITS = (1.0, 2.0, 5.0)
COLUMNS = ["scenario", "m", "time limit [s]", "exit", "wall [s]", "bar [s]", "within bar"]


def run_case(scenario: str, m: int, limit: float) -> dict:
    """One row: the command's exit code and wall time (a fresh process, the plan to a temp file)."""
    with tempfile.TemporaryDirectory() as tmp:
        cmd = [sys.executable, "-m", "sim.cli", "plan", str(ROOT / "scenarios" / "maps" / scenario),
               "--time-limit", f"{limit:g}", "--set", f"robots.count={m}", "-o", str(Path(tmp) / "plan.json")]
        t0 = time.perf_counter()
        done = subprocess.run(cmd, capture_output=True, text=True, cwd=tmp)
        wall = time.perf_counter() - t0
    bar = 1.1 * limit + 0.5
    return {"scenario": scenario, "m": m, "time limit [s]": limit, "exit": done.returncode,
            "wall [s]": wall, "bar [s]": bar, "within bar": "yes" if wall <= bar else "no"}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench.cli_limits", description=__doc__.splitlines()[0])
    ap.add_argument("--limits", type=float, nargs="+", default=list(LIMITS), help="time limits [s]")
    ap.add_argument("--only", nargs="+", metavar="SCENARIO:M", help="cases instead of the defaults")
    args = ap.parse_args(argv)
    cases = CASES if not args.only else [(c.rsplit(":", 1)[0], int(c.rsplit(":", 1)[1])) for c in args.only]
    rows = []
    for scenario, m in cases:
        for limit in args.limits:
            rows.append(run_case(scenario, m, limit))
            r = rows[-1]
            print(f"  {scenario} m={m} limit {limit:g} s: exit {r['exit']}, {r['wall [s]']:.2f} s", file=sys.stderr,
                  flush=True)
    print(machine_info())
    print(markdown_table(COLUMNS, rows))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
