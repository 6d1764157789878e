"""Planner benchmark on MovingAI grid maps.

    python -m bench.maps [--maps room-32-32-4 ...] [--counts 20 50 100 200 400] [--seeds N]
                         [--time-limit S] [--no-lacam] [--scatter] [--map-dir DIR]

Each map of ``tests/data/maps/`` becomes a world of cells ``CELL = 2.4`` wide
(blocked cells merged into rectangle obstacles, :func:`sim.scenario.maps.cover`),
robots of radius 1 and margin 0.1 at cell centres.  Seed 0 takes the first
agents of the map's ``.scen`` file (distinct starts and goals; topped up with
random free cells when the file holds too few), other seeds random distinct
free cells of the largest 4-connected free region.  For each map, count and
seed: :func:`planner.plan` in auto mode (time limit 60 s), the planning time,
the process's peak resident memory so far (``ru_maxrss``), makespan over the straight-line bound and
over the obstacle-respecting bound (:mod:`planner.geobound`), and beside it
the LaCAM grid peer of :mod:`bench.peers` (pymapf, on its own grid of
``sqrt(2)`` separations) when it imports.  Prints a Markdown table.

``--scatter`` puts the starts and targets anywhere in the free space instead of at
cell centres (:func:`planner.scatter.scatter` over the largest connected part, as
``formation: scatter`` does in a scenario; drawn from ``default_rng([seed, m])``):
the grid stage then snaps them onto the cells.  LaCAM, which needs cells, is left
out there.  ``--map-dir`` reads the maps from another folder (any MovingAI ``.map``).
"""

from __future__ import annotations

import argparse
import math
import resource
import sys
import time
from pathlib import Path

import numpy as np

from planner import NoPlanFound, PlannerParams, Polygon, Problem, plan
from planner.plan import step_duration

__all__ = ["CELL", "COLUMNS", "DEFAULT_MAPS", "load_map", "main", "map_problem", "run_lacam_cells", "run_one",
           "scatter_problem"]

CELL = 2.4
RADIUS = 1.0
MARGIN = 0.1
MAP_DIR = Path(__file__).resolve().parents[1] / "tests" / "data" / "maps"
DEFAULT_MAPS = ["room-32-32-4", "maze-32-32-4", "random-32-32-20", "warehouse-10-20-10-2-1", "den312d",
                "warehouse-20-40-10-2-2"]


def _read_map(path: Path) -> np.ndarray:
    """Blocked cells ``(rows, cols)`` of a MovingAI ``.map`` (row 0 at the top)."""
    try:
        from sim.scenario.maps import read_grid

        return np.asarray(read_grid(path).blocked, bool)
    except ImportError:  # the reader of sim/ not there: the format is small
        lines = path.read_text().split("\n")
        h = int(lines[1].split()[1])
        rows = [ln.rstrip("\r") for ln in lines[4 : 4 + h]]
        return np.array([[ch in "@OTW" for ch in row] for row in rows], bool)


def _rectangles(blocked: np.ndarray, cell: float) -> list[Polygon]:
    """Blocked cells as rectangles: runs per row, merged with identical runs below."""
    rows, cols = blocked.shape
    out, open_ = [], {}
    for r in range(rows + 1):
        runs = set()
        if r < rows:
            c = 0
            while c < cols:
                if blocked[r, c]:
                    c0 = c
                    while c < cols and blocked[r, c]:
                        c += 1
                    runs.add((c0, c))
                else:
                    c += 1
        for key in [k for k in open_ if k not in runs]:
            top = open_.pop(key)
            x0, x1 = key[0] * cell, key[1] * cell
            y0, y1 = (rows - r) * cell, (rows - top) * cell
            out.append(Polygon(np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]])))
        for key in runs:
            open_.setdefault(key, r)
    return out


def load_map(name: str, map_dir: Path = MAP_DIR) -> tuple[np.ndarray, list[Polygon]]:
    """``(blocked cells, rectangle obstacles)`` of ``tests/data/maps/NAME.map``."""
    blocked = _read_map(Path(map_dir) / f"{name}.map")
    return blocked, _rectangles(blocked, CELL)


def scatter_problem(name: str, m: int, seed: int = 0, map_dir: Path = MAP_DIR) -> Problem:
    """The map world with ``m`` robots scattered over the largest connected part of its
    free space, starts and targets alike (see the module)."""
    from planner.problem import ProblemError
    from planner.scatter import largest_part, scatter

    blocked, obstacles = load_map(name, map_dir)
    rows, cols = blocked.shape
    shell = Problem(width=cols * CELL, height=rows * CELL, obstacles=tuple(obstacles), radius=RADIUS,
                    margin=MARGIN, start=np.zeros((0, 2)), target=np.zeros((0, 2)))
    rng = np.random.default_rng([seed, m])
    part = largest_part(shell)
    try:
        s, t = (scatter(shell.env, m, shell.separation, shell.clearance, rng, part=part, field=f)
                for f in ("start", "target"))
    except ProblemError as exc:
        raise ValueError(f"{name}: {exc.reason}") from exc
    return Problem(width=shell.width, height=shell.height, obstacles=shell.obstacles, radius=RADIUS,
                   margin=MARGIN, start=s, target=t)


def _scen_cells(name: str, map_dir: Path = MAP_DIR) -> list[tuple[int, int, int, int]]:
    files = sorted(Path(map_dir).glob(f"{name}-*.scen"))
    if not files:
        return []
    out = []
    for line in files[0].read_text().split("\n")[1:]:
        parts = line.split("\t") if "\t" in line else line.split()
        if len(parts) == 9:
            out.append(tuple(int(p) for p in parts[4:8]))
    return out


def _largest_region(blocked: np.ndarray) -> np.ndarray:
    from scipy import ndimage

    labels, _ = ndimage.label(~blocked)
    big = np.argmax(np.bincount(labels.ravel())[1:]) + 1
    return np.argwhere(labels == big)  # (row, col)


def map_problem(name: str, m: int, seed: int = 0, map_dir: Path = MAP_DIR) -> Problem:
    """The map world with ``m`` robots (see the module)."""
    blocked, obstacles = load_map(name, map_dir)
    rows, cols = blocked.shape
    region = _largest_region(blocked)
    inside = {(int(r), int(c)) for r, c in region}
    starts, goals = [], []
    if seed == 0:
        used_s, used_g = set(), set()
        for sx, sy, gx, gy in _scen_cells(name, map_dir):
            if len(starts) == m:
                break
            if (sy, sx) in used_s or (gy, gx) in used_g or (sy, sx) not in inside or (gy, gx) not in inside:
                continue
            used_s.add((sy, sx))
            used_g.add((gy, gx))
            starts.append((sy, sx))
            goals.append((gy, gx))
    rng = np.random.default_rng(seed)
    for chosen in (starts, goals):
        have = set(chosen)
        pool = [tuple(int(v) for v in rc) for rc in region[rng.permutation(len(region))] if tuple(rc) not in have]
        chosen += pool[: m - len(chosen)]
    if len(starts) < m or len(goals) < m:
        raise ValueError(f"{name}: only {len(region)} free cells in the largest region, fewer than {m}")

    def centres(cells):
        a = np.asarray(cells, float)
        return np.stack([(a[:, 1] + 0.5) * CELL, (rows - a[:, 0] - 0.5) * CELL], axis=1)

    return Problem(width=cols * CELL, height=rows * CELL, obstacles=tuple(obstacles), radius=RADIUS,
                   margin=MARGIN, start=centres(starts), target=centres(goals))


def _cells_of(problem: Problem, pts: np.ndarray, rows: int) -> np.ndarray:
    """``(m, 2)`` ``(row, col)`` cells of cell-centre points."""
    col = np.floor(pts[:, 0] / CELL).astype(int)
    row = rows - 1 - np.floor(pts[:, 1] / CELL).astype(int)
    return np.stack([row, col], axis=1)


def run_lacam_cells(name: str, problem: Problem, time_limit: float, seed: int, map_dir: Path = MAP_DIR) -> dict:
    """pymapf's LaCAM on the map's own cell graph (4-neighbours, following allowed):
    starts assigned to targets by the minimum sum of squared cell distances, then the
    labeled problem.  Returns its time steps and wall time; its makespan is the time
    steps times ``step_duration(CELL)``.  Not a plan for discs of this size: LaCAM's
    grid lets a robot follow another round a corner (``CELL / sqrt(2)`` apart)."""
    from pymapf.algorithms.lacam import LaCAM
    from pymapf.core.grid import GridMap
    from pymapf.core.solver import Agent, MAPFProblem
    from scipy.optimize import linear_sum_assignment
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import shortest_path

    blocked, _ = load_map(name, map_dir)
    rows, cols = blocked.shape
    t0 = time.perf_counter()
    sc, tc = _cells_of(problem, problem.start, rows), _cells_of(problem, problem.target, rows)
    idx = np.full(blocked.shape, -1)
    idx[~blocked] = np.arange(int((~blocked).sum()))
    a, b = [], []
    for dr, dc in ((0, 1), (1, 0)):
        u, v = idx[: rows - dr, : cols - dc], idx[dr:, dc:]
        ok = (u >= 0) & (v >= 0)
        a.append(u[ok])
        b.append(v[ok])
    a, b = np.concatenate(a), np.concatenate(b)
    n = int((~blocked).sum())
    g = coo_matrix((np.ones(len(a)), (a, b)), shape=(n, n)).tocsr()
    dist = shortest_path(g, directed=False, unweighted=True, indices=idx[tc[:, 0], tc[:, 1]])
    cost = dist[:, idx[sc[:, 0], sc[:, 1]]].T  # (robot, target)
    _, goal = linear_sum_assignment(np.where(np.isfinite(cost), cost, 1e6) ** 2)
    agents = [Agent(f"r{i}", (int(sc[i, 0]), int(sc[i, 1])), (int(tc[goal[i], 0]), int(tc[goal[i], 1])))
              for i in range(problem.m)]
    sol = LaCAM(time_limit=time_limit, seed=seed).solve(MAPFProblem(GridMap(blocked.astype(int).tolist()), agents))
    elapsed = time.perf_counter() - t0
    if sol is None:
        return {"lacam_ok": False, "lacam_time_s": elapsed}
    steps = max(len(sol.paths[f"r{i}"]) for i in range(problem.m)) - 1
    return {"lacam_ok": True, "lacam_time_s": elapsed, "lacam_steps": steps,
            "lacam_makespan_s": steps * step_duration(CELL, problem.max_speed, problem.max_accel)}


def run_one(name: str, m: int, seed: int, time_limit: float, lacam: bool, lacam_limit: float = 10.0,
            scattered: bool = False, map_dir: Path = MAP_DIR, geo: bool = True) -> dict:
    """One map, count and seed: our plan (checked exactly), the bounds, LaCAM beside."""
    from planner import check_plan
    from planner.bounds import lower_bounds
    from planner.geobound import geo_lower_bound

    if scattered:
        problem, lacam = scatter_problem(name, m, seed, map_dir), False
    else:
        problem = map_problem(name, m, seed, map_dir)
    row = {"map": name, "m": m, "seed": seed}
    t0 = time.perf_counter()
    stats = None
    try:
        result, stats = plan(problem, PlannerParams(time_limit=time_limit), np.random.default_rng(seed))
        row.update(ok=True, time_s=stats.planning_time_s, stage=stats.extra.get("direct", "roadmap"),
                   makespan_s=result.makespan)
        check_plan(problem, result)
    except NoPlanFound as exc:
        row.update(ok=False, time_s=time.perf_counter() - t0, stage=str(exc)[:40])
    row["wall_s"] = time.perf_counter() - t0
    row["peak_mb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024  # process peak so far
    row["straight_s"] = lower_bounds(problem)[0]
    t1 = time.perf_counter()
    if geo:
        row["geo_s"] = geo_lower_bound(problem)
        row["geo_time_s"] = time.perf_counter() - t1
    else:  # only what the planner computed within its own budget (NaN elsewhere)
        row["geo_s"] = math.nan if stats is None else stats.makespan_lower_bound_geo_s
    if row["ok"]:
        row["x_straight"] = row["makespan_s"] / row["straight_s"]
        row["x_geo"] = row["makespan_s"] / row["geo_s"]
    if lacam:
        row.update(run_lacam_cells(name, problem, lacam_limit, seed, map_dir))
        if row.get("lacam_ok"):
            row["lacam_x_geo"] = row["lacam_makespan_s"] / row["geo_s"]
    return row


COLUMNS = ["map", "m", "seed", "ok", "stage", "time_s", "peak_mb", "makespan_s", "straight_s", "geo_s",
           "x_straight", "x_geo", "geo_time_s", "lacam_ok", "lacam_time_s", "lacam_steps", "lacam_makespan_s",
           "lacam_x_geo"]


def main(argv=None) -> int:
    from ._common import markdown_table

    ap = argparse.ArgumentParser(prog="python -m bench.maps", description=__doc__.split("\n\n")[0])
    ap.add_argument("--maps", nargs="+", default=DEFAULT_MAPS)
    ap.add_argument("--counts", nargs="+", type=int, default=[20, 50, 100, 200, 400])
    ap.add_argument("--seeds", type=int, default=1)
    ap.add_argument("--time-limit", type=float, default=60.0)
    ap.add_argument("--no-lacam", action="store_true")
    ap.add_argument("--lacam-limit", type=float, default=10.0, help="LaCAM's time limit [s]")
    ap.add_argument("--scatter", action="store_true",
                    help="starts and targets anywhere in the free space (not at cell centres; no LaCAM)")
    ap.add_argument("--map-dir", type=Path, default=MAP_DIR, help="folder of the .map (and .scen) files")
    ap.add_argument("--no-geo", action="store_true",
                    help="no separate geo bound (it can take 30 s on a 128 x 128 maze): the planner's own, if any")
    args = ap.parse_args(argv)
    lacam = not args.no_lacam
    if lacam:
        try:
            import pymapf.algorithms.lacam  # noqa: F401
        except ImportError:
            lacam = False
    from ._common import warm_up_planner

    warm_up_planner(args.time_limit)
    rows = []
    for name in args.maps:
        if not (args.map_dir / f"{name}.map").exists():
            print(f"# {name}: no map file, skipped", file=sys.stderr)
            continue
        for m in args.counts:
            for seed in range(args.seeds):
                try:
                    row = run_one(name, m, seed, args.time_limit, lacam, args.lacam_limit,
                                  scattered=args.scatter, map_dir=args.map_dir, geo=not args.no_geo)
                except ValueError as exc:
                    print(f"# {name} m={m}: {exc}", file=sys.stderr)
                    continue
                rows.append(row)
                print(markdown_table(COLUMNS, [row]).split("\n")[-1], file=sys.stderr, flush=True)
    print(markdown_table(COLUMNS, rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
