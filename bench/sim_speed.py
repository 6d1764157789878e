"""Physics execution speed: simulated seconds per wall-clock second.

Run with ``python -m bench.sim_speed``.  For 11, 50 and 100 robots it
builds a valid plan without the planner (every robot owns one cell of a
grid and moves on straight lines inside it, so no two robots ever come
closer than the separation; a U-shaped polygon and a circle sit in spare
cells), checks it exactly with :func:`planner.validate.check_plan`,
executes it with contact monitoring and prints a Markdown table.  Sparse
cells (side 4) give long moves at full speed; dense cells (side 1.6) keep
every robot within 0.1 to 0.5 of its neighbours, the hard case for the
contact monitor.  The realtime factor is from wall-clock time; the CPU
time column and the simulated seconds per CPU second show what other load
on the machine took away.

Each grid runs twice: with ideal robots (``ideal``) and with every realism
knob on (``disturbed``: :data:`DISTURBED`, i.e. a 20 N force limit, 50 Hz
control, 40 ms latency, measurement noise 0.02, mass error 10 %, floor
friction 0.2, random pushes of 0.5 N s at 0.05 per robot per second and
robot 0 failing halfway; gains lowered to kp = 50, kd = 14 so that the
loop stays stable with the latency).  Recovery stays off: replanning
measures the planner, not the simulator.

The disturbed robots' noise turns the state estimator on (the controller sees a
Kalman filter's estimate, :mod:`sim.execute.estimate`).  Then, at ``--drive-robots``
(100 and 1000), the drive models (:mod:`sim.execute.drive`) run with their default
settings and nothing else realistic: ``differential`` (wheels, no lateral slip) and
``velocity`` (first-order velocity tracking); and ``estimated`` (:data:`ESTIMATED`):
estimated state alone.  All use the realistic loop.
"""

from __future__ import annotations

import argparse
import math
import os
import platform
import sys
import time

import numpy as np

from planner.plan import Plan
from planner.problem import Circle, Polygon, Problem
from planner.validate import check_plan
from sim.execute.physics import execute
from sim.scenario.params import DriveParams, Failure, Noise, Pushes, Sensing, SimParams

__all__ = ["DISTURBED", "ESTIMATED", "cell_problem", "disturbed_params", "main"]

DISTURBED = dict(kp=50.0, kd=14.0, force_limit=20.0, control_rate=50.0, latency=0.04,
                 noise=Noise(0.02, 0.02), mass_error=0.1, friction=0.2, pushes=Pushes(0.05, 0.5))


ESTIMATED = SimParams(noise=Noise(0.02, 0.0), sensing=Sensing(dropout=0.05, latency_jitter=0.005, bias_drift=0.001))
"""Estimated state alone: the controller sees a constant-velocity Kalman filter's estimate of
position measurements with noise 0.02, 5 % dropped, 5 ms jitter and a slowly drifting bias."""


def disturbed_params(makespan: float) -> SimParams:
    """:data:`DISTURBED` with robot 0 failing halfway through a plan of ``makespan`` seconds."""
    return SimParams(**DISTURBED, failures=(Failure(0, 0.5 * makespan),))

_RADIUS = 0.5
_MARGIN = 0.1


def cell_problem(m: int, steps: int, rng: np.random.Generator, cell: float = 4.0) -> tuple[Problem, Plan]:
    """A problem and a valid plan of ``steps`` steps for ``m`` robots on a grid of cells.

    Cells are squares of side ``cell`` (at least ``2 (radius + margin)``).
    Robot ``i`` stays inside the box of its cell shrunk by ``radius +
    margin``; the boxes of two cells are at least ``2 radius + 2 margin``
    apart, the walls ``radius + margin`` away, and each box is convex, so
    every straight move keeps the separation and the clearance.  In each
    step a random half of the robots moves.
    """
    cols = math.ceil(math.sqrt(m + 2))
    rows = math.ceil((m + 2) / cols)
    width, height = cols * cell, rows * cell
    centres = np.array([((c + 0.5) * cell, (r + 0.5) * cell) for r in range(rows) for c in range(cols)])
    home, spare = centres[:m], centres[m:]
    half = cell / 2 - _RADIUS - _MARGIN - 1e-6
    # A U-shaped polygon and a circle fill the two spare cells, clear of
    # their neighbours.
    k = cell / 2 - _RADIUS - 2 * _MARGIN
    unit_u = [(-1, -1), (1, -1), (1, 1), (0.5, 1), (0.5, -0.4), (-0.5, -0.4), (-0.5, 1), (-1, 1)]
    u = Polygon(k * np.array(unit_u, float) + spare[0])
    circle = Circle(tuple(spare[1]), k)
    w = [home.copy()]
    for _ in range(steps):
        nxt = w[-1].copy()
        movers = rng.random(m) < 0.5
        nxt[movers] = home[movers] + rng.uniform(-half, half, size=(int(movers.sum()), 2))
        w.append(nxt)
    w = np.array(w)
    problem = Problem(width, height, (u, circle), _RADIUS, _MARGIN, w[0], w[-1])
    plan = Plan.from_waypoints(w, _RADIUS, _MARGIN, problem.max_speed, problem.max_accel)
    check_plan(problem, plan)
    return problem, plan


def _machine() -> str:
    cpu = platform.processor() or "?"
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as f:
            for line in f:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    import pymunk
    import scipy

    return (
        f"- platform: {platform.platform()}\n"
        f"- cpu: {cpu} ({os.cpu_count()} logical cores)\n"
        f"- python: {sys.version.split()[0]} ({platform.python_implementation()})\n"
        f"- pymunk: {pymunk.version} (chipmunk {pymunk.chipmunk_version})\n"
        f"- numpy: {np.__version__}, scipy: {scipy.__version__}"
    )


def _factor(x: float) -> str:
    """A realtime factor: whole numbers from 10 on, two digits below."""
    return f"{x:.0f}x" if x >= 10 else f"{x:.2g}x"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench.sim_speed", description=__doc__.split("\n")[0])
    ap.add_argument("--robots", type=int, nargs="+", default=[11, 50, 100])
    ap.add_argument("--steps", type=int, default=20, help="plan steps per run")
    ap.add_argument("--cells", type=float, nargs="+", default=[4.0, 1.6],
                    help="cell sides: 4 is sparse, 1.6 packs robots 0.1 apart")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--drive-robots", type=int, nargs="*", default=[100, 1000],
                    help="robot counts of the differential and velocity drive rows (none: skip them)")
    args = ap.parse_args(argv)

    params = SimParams()
    rng = np.random.default_rng(args.seed)
    print(_machine())
    print(
        f"- sim: dt = {params.dt:.4g} s, substeps = {params.substeps}, kp = {params.kp:g}, "
        f"kd = {params.kd:g}, settle = {params.settle_time:g} s\n"
    )
    print(
        "| robots | cell | robots model | sim time [s] | wall time [s] | CPU time [s] | realtime factor "
        "| per CPU second | contacts | min clearance | max tracking error | space.step share |"
    )
    print("| ---: | ---: | :--- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |")
    runs = [(m, cell, None) for cell in args.cells for m in args.robots]
    runs += [(m, cell, "drives") for cell in args.cells for m in args.drive_robots]
    for m, cell, kind in runs:
        problem, plan = cell_problem(m, args.steps, rng, cell)
        if kind is None:
            labelled = (("ideal", params), ("disturbed", disturbed_params(plan.makespan)))
        else:
            labelled = tuple((model, SimParams(drive=DriveParams(model=model)))
                             for model in ("differential", "velocity"))
            labelled += (("estimated", ESTIMATED),)
        for label, run_params in labelled:
            cpu0 = time.process_time()
            report = execute(problem, plan, run_params, np.random.default_rng(args.seed))
            cpu = time.process_time() - cpu0
            print(
                f"| {m} | {cell:g} | {label} | {report.sim_time_s:.1f} | {report.wall_time_s:.2f} | "
                f"{cpu:.2f} | {_factor(report.realtime_factor)} | {report.sim_time_s / max(cpu, 1e-9):.0f}x | "
                f"{len(report.contacts)} | "
                f"{report.min_clearance:.3f} | {report.max_tracking_error:.1e} | "
                f"{report.step_time_s / report.wall_time_s:.0%} |",
                flush=True,
            )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
