"""One run of a sweep (:class:`RunSpec`, :func:`run_one`) and the grids of runs.

A run is (scenario, settings, mode, g, q, seed, time limit, physics).  One
generator, seeded with the run's seed, builds the problem and plans, exactly
as ``swarmform run --seed SEED`` does, so a row depends only on its spec,
wherever it is computed, apart from the fields in :data:`VOLATILE_FIELDS`.
"""

from __future__ import annotations

import math
import os
import socket
import time
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from planner import NoPlanFound, plan

from ..errors import InputError
from ..scenario import Scenario, build_problem, read_scenario

__all__ = [
    "KEY_FIELDS",
    "PAPER_DIR",
    "VOLATILE_FIELDS",
    "RunSpec",
    "TuneError",
    "failure_row",
    "grid",
    "paper_grid",
    "read_variants",
    "run_one",
]

VOLATILE_FIELDS = ("planning_time_s", "wall_time_s", "host", "worker")
"""Row fields that depend on the machine and the moment, not on the run's spec."""

KEY_FIELDS = ("scenario", "mode", "g", "q", "seed", "time_limit", "simulate", "settings")
"""The row fields that identify a run: a rerun skips a spec whose key is in the file.

``settings`` (the ``--set`` values of the run) is missing from rows written
before settings existed; such a row has no settings.
"""

PAPER_DIR = Path(__file__).resolve().parents[2] / "scenarios" / "paper"
"""Where ``--paper`` finds the scenarios of the paper's Tables II and III (``table*.yaml``)."""


class TuneError(InputError):
    """Wrong input to a sweep (one line naming the file or option, and the reason)."""


Settings = tuple[tuple[str, Any], ...]


@dataclass(frozen=True)
class RunSpec:
    """One run of a sweep.

    scenario: the checked scenario, with the run's settings applied; it
        travels with the spec, so workers need no scenario files.
    mode: ``"fixed"`` (g and q given) or ``"auto"`` (g and q ``None``).
    seed: seeds the run's one generator (problem and planner).
    time_limit: planning time limit [s].
    simulate: also execute the plan in the physics world.
    settings: the ``--set`` values of the run, ``(("robots.margin", 0.2), ...)``
        in the order of the options.
    """

    scenario: Scenario
    mode: str
    g: int | None
    q: int | None
    seed: int
    time_limit: float
    simulate: bool = False
    settings: Settings = ()

    @property
    def key(self) -> tuple:
        """``(name, mode, g, q, seed, time_limit, simulate, sorted settings)``; names are unique in a sweep."""
        return (self.scenario.name, self.mode, self.g, self.q, self.seed, float(self.time_limit),
                self.simulate, tuple(sorted(self.settings)))

    def __post_init__(self):
        fixed = all(isinstance(v, int) and not isinstance(v, bool) and v >= 1 for v in (self.g, self.q))
        if not ((self.mode == "fixed" and fixed) or (self.mode == "auto" and self.g is None and self.q is None)):
            raise ValueError(f"mode {self.mode!r} with g={self.g!r}, q={self.q!r}: 'fixed' needs integers "
                             ">= 1, 'auto' needs None for both")
        for item in self.settings:
            if not (isinstance(item, tuple) and len(item) == 2 and isinstance(item[0], str)
                    and (item[1] is None or isinstance(item[1], (str, int, float, bool)))):
                raise ValueError(f"settings: expected (key, scalar) pairs, got {item!r}")


def _base_row(spec: RunSpec) -> dict:
    sc = spec.scenario
    return {
        "scenario": sc.name,
        "scenario_file": sc.path,
        "mode": spec.mode,
        "g": spec.g,
        "q": spec.q,
        "seed": spec.seed,
        "time_limit": float(spec.time_limit),
        "simulate": spec.simulate,
        "settings": dict(spec.settings),
        "robots": sc.count,
        "start": sc.start.describe(),
        "target": sc.target.describe(),
        "paper_table": sc.paper.table if sc.paper else None,
        "paper_row": sc.paper.row if sc.paper else None,
        "paper_time_s": sc.paper.time_s if sc.paper else None,
        "paper_g": sc.planner.g if sc.paper else None,
        "paper_q": sc.planner.q if sc.paper else None,
        "found": False,
        "planning_time_s": None,
        "g_used": None,
        "q_used": None,
        "graphs": None,
        "connections": None,
        "steps": None,
        "makespan_s": None,
        "path_length": None,
        "min_clearance": None,
        "makespan_lower_bound_s": None,
        "sim_ok": None,
        "sim_contacts": None,
        "sim_reached": None,
        "sim_min_clearance": None,
        "sim_max_tracking_error": None,
        "error_type": None,
        "error": None,
        "wall_time_s": None,
        "host": socket.gethostname(),
        "worker": None,
    }


def run_one(spec: RunSpec) -> dict:
    """Build the problem, plan (and with ``spec.simulate`` execute); return the result row.

    Never raises for a failing run (an ``Exception``): the row then has
    ``found`` false (unless planning succeeded before the error) and the
    error's type and text in ``error_type`` and ``error``.  Times in seconds,
    lengths in workspace units; ``None`` where a value does not exist.
    ``worker`` is left for the engine that ran it to fill in.
    """
    t0 = time.perf_counter()
    sc = spec.scenario
    row = _base_row(spec)
    try:
        rng = sc.generator(spec.seed)
        problem = build_problem(sc, rng)
        row["robots"] = problem.m
        params = replace(sc.planner, g=spec.g, q=spec.q, time_limit=float(spec.time_limit))
        try:
            result, stats = plan(problem, params, rng)
        except NoPlanFound as exc:
            row.update(_stats_fields(exc.stats))
            row["found"] = False
            row["error_type"], row["error"] = "NoPlanFound", one_line(exc)
        else:
            row.update(_stats_fields(stats))
            if spec.simulate:
                from ..execute.physics import execute

                sim = execute(problem, result, sc.sim, rng, planner_params=params)
                row["sim_ok"] = bool(sim.ok)
                row["sim_contacts"] = len(sim.events)  # contact events, as the verdict counts them
                row["sim_reached"] = bool(sim.reached)
                row["sim_min_clearance"] = _num(sim.min_clearance)
                row["sim_max_tracking_error"] = _num(sim.max_tracking_error)
                row["sim_replans"] = len(sim.replans)
                row["sim_verdict"] = sim.verdict
    except Exception as exc:  # noqa: BLE001 - a failing run is a row, not the end of the sweep
        row["error_type"], row["error"] = type(exc).__name__, one_line(exc)
    row["wall_time_s"] = time.perf_counter() - t0
    return row


def failure_row(spec: RunSpec, error_type: str, error: str, *, wall_time_s: float | None = None,
                worker: str | None = None) -> dict:
    """The row of a run that gave no result of its own (its watchdog fired, or its worker died)."""
    row = _base_row(spec)
    row.update(error_type=error_type, error=error, wall_time_s=wall_time_s, worker=worker)
    return row


def _stats_fields(stats) -> dict:
    return {
        "found": bool(stats.found),
        "planning_time_s": _num(stats.planning_time_s),
        "g_used": int(stats.g),
        "q_used": int(stats.q),
        "graphs": int(stats.graphs),
        "connections": int(stats.connections),
        "steps": int(stats.steps) if stats.found else None,
        "makespan_s": _num(stats.makespan_s) if stats.found else None,
        "path_length": _num(stats.path_length) if stats.found else None,
        "min_clearance": _num(stats.min_clearance) if stats.found else None,
        "makespan_lower_bound_s": _num(stats.makespan_lower_bound_s) if stats.found else None,
    }


def _num(v) -> float | None:
    v = float(v)
    return v if math.isfinite(v) else None


def one_line(exc: BaseException) -> str:
    """An exception's text on one line (its type's name when it has none)."""
    return " ".join(str(exc).split()) or type(exc).__name__


# ----------------------------------------------------------------------------
# the grids


def read_variants(paths: Sequence[str | Path], settings: Sequence[Mapping[str, Any]] = ({},)
                  ) -> list[tuple[Scenario, dict]]:
    """Each scenario file read once per settings combination: ``[(scenario, settings), ...]``.

    Every combination is checked here, before any run: a bad value is a
    :class:`sim.scenario.overrides.OverrideError` naming its ``--set`` option.
    """
    return [(read_scenario(p, overrides=dict(s) or None), dict(s)) for p in paths for s in settings]


def grid(
    scenarios: Sequence[Scenario | tuple[Scenario, Mapping[str, Any]]],
    *,
    g: Sequence[int] | None = None,
    q: Sequence[int] | None = None,
    auto: bool = False,
    seeds: Iterable[int] = range(20),
    time_limit: float | None = None,
    simulate: bool = False,
) -> list[RunSpec]:
    """The runs of a sweep over ``g`` x ``q`` (plus auto) x ``seeds``, per scenario and settings.

    ``scenarios`` are scenarios, or ``(scenario, settings)`` pairs from
    :func:`read_variants` for a sweep over ``--set`` values.  Without ``g``
    and ``q`` each scenario runs its own planner g and q (only auto when its
    file says auto); with one of them, the other comes from the file.
    ``time_limit`` [s] overrides each scenario's ``planner.time_limit``.
    The runs are ordered seed by seed, so a sweep stopped early has covered
    every setting about equally.
    """
    variants = _unique(scenarios)
    seeds = _check_seeds(seeds)
    g = _check_counts(g, "--g")
    q = _check_counts(q, "--q")
    time_limit = _check_time_limit(time_limit)
    plans = []
    for sc, _settings in variants:
        own = sc.planner
        if g is None and q is None:
            plans.append(([] if own.auto else [(own.g, own.q)], auto or own.auto))
            continue
        for values, name in ((g, "g"), (q, "q")):
            if values is None and getattr(own, name) is None:
                raise TuneError(f"{sc.path}: planner.{name}: is auto, so the sweep needs --{name} values")
        plans.append(([(gi, qi) for gi in (g or [own.g]) for qi in (q or [own.q])], auto))
    return _specs(variants, plans, seeds, time_limit, simulate)


def paper_grid(
    scenarios: Sequence[Scenario | tuple[Scenario, Mapping[str, Any]]],
    *,
    seeds: Iterable[int] = range(20),
    time_limit: float | None = None,
    simulate: bool = False,
) -> list[RunSpec]:
    """The runs that reproduce the paper's tables: each scenario at its own g and q, and auto.

    Every scenario must carry a ``paper`` block (its table, row and time).
    """
    variants = _unique(scenarios)
    for sc, _ in variants:
        if sc.paper is None:
            raise TuneError(f"{sc.path}: paper: missing; --paper needs scenarios from the paper's "
                            "tables (with paper: {table, row, time_s})")
    plans = [([] if sc.planner.auto else [(sc.planner.g, sc.planner.q)], True) for sc, _ in variants]
    return _specs(variants, plans, _check_seeds(seeds), _check_time_limit(time_limit), simulate)


def _specs(variants, plans, seeds, time_limit, simulate) -> list[RunSpec]:
    out = []
    for seed in seeds:
        for (sc, settings), (fixed, auto) in zip(variants, plans):
            limit = float(sc.planner.time_limit if time_limit is None else time_limit)
            out += [RunSpec(sc, "fixed", gi, qi, seed, limit, simulate, settings) for gi, qi in fixed]
            if auto:
                out.append(RunSpec(sc, "auto", None, None, seed, limit, simulate, settings))
    return out


def _unique(scenarios) -> list[tuple[Scenario, tuple]]:
    """``(scenario, settings)`` without repeats; two different files may not share a name."""
    files: dict[str, Scenario] = {}
    out: dict[tuple, tuple[Scenario, tuple]] = {}
    for item in scenarios:
        sc, settings = item if isinstance(item, tuple) else (item, {})
        settings = tuple(dict(settings).items())
        seen = files.setdefault(sc.name, sc)
        if os.path.realpath(seen.path) != os.path.realpath(sc.path):
            raise TuneError(f"{sc.path}: name: {sc.name!r} is also the name of {seen.path}; "
                            "scenario names must be unique in a sweep")
        out.setdefault((sc.name, tuple(sorted(settings))), (sc, settings))
    if not out:
        raise TuneError("SCENARIO: give at least one scenario file")
    return list(out.values())


def _check_counts(values, option: str) -> list[int] | None:
    if values is None:
        return None
    values = list(dict.fromkeys(values))
    for v in values:
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 1:
            raise TuneError(f"{option}: must be integers >= 1, got {v!r}")
    if not values:
        raise TuneError(f"{option}: give at least one value")
    return [int(v) for v in values]


def _check_seeds(seeds) -> list[int]:
    seeds = list(dict.fromkeys(seeds))
    if not seeds:
        raise TuneError("--seeds: must be at least 1")
    for s in seeds:
        if isinstance(s, bool) or not isinstance(s, (int, np.integer)) or s < 0:
            raise TuneError(f"--seed-start: seeds must be integers >= 0, got {s!r}")
    return [int(s) for s in seeds]


def _check_time_limit(time_limit) -> float | None:
    if time_limit is None:
        return None
    if isinstance(time_limit, bool) or not isinstance(time_limit, (int, float)) \
            or not math.isfinite(time_limit) or time_limit <= 0:
        raise TuneError(f"--time-limit: must be a finite number of seconds > 0, got {time_limit!r}")
    return float(time_limit)
