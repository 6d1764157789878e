"""The run: plan (or load a plan), validate, execute in pymunk, render, report.

``run_scenario`` is what ``swarmform run`` does; it returns the report and
the exit code (0: plan found and executed with zero contacts, every robot
on a target; 1: no plan, or a contact, or a missed target, or a plan below
the margin; the report is written in every one of these cases).  Bad input
raises :class:`InputError` (exit 2) before anything is written: the output
folder is checked first, then the scenario, the plan file (fully, against
the scenario: radius, margin, robots, start, workspace, speed and
acceleration limits) and, once the plan is known, the physics budget
(:mod:`sim.execute.budget`).  The run's files are written aside and replace the
old ones together at the end (:class:`sim.output.files.OutputSet`), so an
error or an interrupt leaves the previous run's files as they were.
"""

from __future__ import annotations

import json
import math
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from planner import NoPlanFound, Plan, PlanStats, min_clearance
from planner.bounds import lower_bounds
from planner.inputfile import echo_path
from planner.plan import note_ignored, read_plan_file
from planner.visible import Late

from .errors import InputError
from .execute.budget import check_physics_budget, check_validator_budget
from .execute.legs import plan_legs
from .execute.physics import SimReport, execute
from .execute.series import write_series
from .output.files import OutputSet, check_out_dir
from .output.media import atomic_path, has_mp4, write_video
from .output.playback import MAX_VIDEO_SECONDS
from .output.render import render_frames
from .output.report import run_page
from .output.settings import non_defaults
from .progress import ProgressBar
from .scenario.build import build_legs
from .scenario.model import Scenario
from .scenario.reader import read_scenario
from .words import plural

__all__ = ["InputError", "RunResult", "plan_summary", "run_scenario", "sim_summary"]


@dataclass
class RunResult:
    report: dict
    exit_code: int
    report_path: Path | None
    media: list[Path] = field(default_factory=list)
    sim: SimReport | None = None
    plan: Plan | None = None


def plan_summary(stats: PlanStats, *, valid: bool | None = None, auto: bool = False) -> dict:
    """The ``plan`` block of a run report (units: s and workspace units).

    In auto mode ``g`` and ``q`` are ``"auto"``; ``graphs`` is then the
    number of pebble graphs really sampled (0 when a direct try made the
    plan, which ``direct`` names).
    """
    d = stats.to_dict()
    keys = ("found", "planning_time_s", "g", "q", "graphs", "connections", "steps", "makespan_s",
            "path_length", "min_clearance", "makespan_lower_bound_s", "path_length_lower_bound")
    out = {k: d.get(k) for k in keys}
    if auto:
        out["g"] = out["q"] = "auto"
        if d.get("direct"):
            out["direct"] = d["direct"]
    if "feasible" in d:  # True: a plan exists (found); False: proven impossible; None: not known
        out["feasible"] = d["feasible"]
        if d.get("infeasible_reason"):
            out["infeasible_reason"] = d["infeasible_reason"]
    if valid is not None:
        out["valid"] = valid
    if "legs" in stats.extra:
        out["legs"] = stats.extra["legs"]
    return out


def sim_summary(report: SimReport) -> dict:
    """The ``sim`` block of a run report."""
    return report.to_dict()


def run_scenario(
    path: str | Path,
    *,
    seed: int | None = None,
    out_dir: str | Path = "media",
    render: bool = True,
    plan_path: str | Path | None = None,
    time_limit: float | None = None,
    progress: bool | None = None,
    out="stdout",
    overrides: dict | None = None,
    started: float | None = None,
) -> RunResult:
    """Plan or load, validate, execute, render and write ``DIR/NAME.json``.

    With ``plan_path`` the plan is executed as it is, even when the exact
    validator finds it below the margin (that is how a regression test
    proves a collision is seen); its recorded seed rebuilds the same
    problem unless ``seed`` is given.  ``overrides`` set scenario fields
    (``{"robots.margin": 0.2}``, as ``--set``).  ``started``: when the run
    began (``time.perf_counter``; default now), from which the planner's time
    limit counts, the placing of the robots included.
    """
    out_dir = check_out_dir(out_dir)
    out = sys.stdout if out == "stdout" else out  # the stream of the call, not of the import
    t0 = time.perf_counter() if started is None else started
    scenario = read_scenario(path, overrides=overrides)
    loaded = None
    if plan_path is not None:
        loaded, recorded = read_plan_file(plan_path)
        note_ignored(plan_path, recorded)
        seed = recorded.get("seed") if seed is None else seed
    seed = scenario.seed if seed is None else seed
    rng = scenario.generator(seed)
    name = scenario.name
    outs = OutputSet(out_dir, name)
    outs.check()
    limit = scenario.planner_params(time_limit).time_limit
    try:
        problem, targets = build_legs(scenario, rng, deadline=t0 + limit if loaded is None else math.inf)
    except Late:
        return _late(scenario, seed, limit, outs, out)
    leg_times = None
    if loaded is not None:
        loaded = _check_loaded(loaded, problem, scenario, str(plan_path))
    say = (lambda *a: print(*a, file=out)) if out is not None else (lambda *a: None)
    say(f"{name} (seed {seed}): {problem.m} robots, {scenario.describe()}")

    report: dict = {"scenario": name, "seed": seed, "robots": problem.m, "radius": problem.radius,
                    "margin": problem.margin, "scenario_file": str(path)}
    if overrides:
        report["settings"] = dict(overrides)  # the --set values the scenario was read with
    report["non_defaults"] = non_defaults(scenario)  # parameters that differ from their defaults
    json_name, page_name, series_name = f"{name}.json", f"{name}.html", f"{name}-series.npz"
    with outs:
        if loaded is not None:
            result, stats = loaded, _loaded_stats(loaded, problem)
            report["plan_file"] = str(plan_path)
        else:
            params = scenario.planner_params(time_limit, spent=time.perf_counter() - t0)
            try:
                result, stats, leg_times = plan_legs(problem, targets, params, rng,
                                                     holds=[t.hold for t in scenario.legs],
                                                     labels=[t.describe() for t in scenario.legs])
            except NoPlanFound as exc:
                report["plan"] = plan_summary(exc.stats, auto=params.auto)
                report["plan"]["error"] = str(exc)
                report["sim"] = None
                report["media"] = []
                report["ok"] = False
                if exc.stats.extra.get("feasible") is False:
                    say(f"  {exc} (proven in {exc.stats.planning_time_s:.3f} s)")
                else:
                    say(f"  no plan in {exc.stats.planning_time_s:.2f} s: {exc}")
                report["page"] = str(outs.final(page_name))
                run_page(outs.path(page_name), report, problem)
                _write_report(outs.path(json_name), report)
                outs.commit()
                say(f"  wrote {outs.final(page_name)}")
                say(f"  wrote {outs.final(json_name)}")
                return RunResult(report, 1, outs.final(json_name))
            check_physics_budget(problem.m, result.makespan, scenario.sim, scenario.path)
        valid = bool(stats.min_clearance >= problem.margin - 1e-9)
        report["plan"] = plan_summary(stats, valid=valid, auto=loaded is None and params.auto)
        made = f"planned in {stats.planning_time_s:.2f} s" if loaded is None else f"from {plan_path}"
        say(f"  plan: {plural(stats.steps, 'step')} ({made}), makespan {stats.makespan_s:.1f} s, "
            f"min clearance {stats.min_clearance:.4f} (margin {problem.margin:g})"
            f"{'' if valid else '  BELOW THE MARGIN'}")
        report["plan"]["margin"] = problem.margin
        if loaded is None:
            report["plan"]["margin_extra"] = scenario.planner.margin_extra
        else:  # what the plan file says it was planned with
            report["plan"]["margin_extra"] = (loaded.stats.extra.get("margin_extra", 0.0) if loaded.stats else 0.0)

        bar = ProgressBar("  physics", enabled=progress)
        sim = execute(problem, result, scenario.sim, rng, planner_params=scenario.planner,
                      progress=lambda f: bar(f, f"of {result.makespan + scenario.sim.settle_time:.0f} s"))
        bar.close()
        report["sim"] = sim_summary(sim)
        write_series(outs.path(series_name), sim)
        report["sim"]["series_file"] = series_name
        say(f"  physics: {plural(len(sim.events), 'contact')}, min clearance {sim.min_clearance:.4f}, "
            f"tracking error {sim.max_tracking_error:.2g}, reached {'yes' if sim.reached else 'no'}, "
            f"{sim.sim_time_s:.1f} s simulated in {sim.wall_time_s:.1f} s")
        say(f"  physics verdict: {sim.verdict}")

        media: list[Path] = []
        if render and "mp4" in scenario.render.formats and not has_mp4():
            say("  (no MP4: install imageio-ffmpeg, e.g. pip install -e '.[video]')")
        if render:
            legs = None if leg_times is None or len(targets) < 2 else list(zip(leg_times[:-1], targets))
            frames = render_frames(problem, sim.times, sim.positions, sim.contacts, scenario.render,
                                   step_times=result.times, title=name, targets=legs, replans=sim.replans,
                                   failures=[(d.robot, d.time) for d in sim.disturbances if d.kind == "failure"],
                                   headings=sim.headings)
            report["video"] = frames.timing.to_dict()
            if frames.timing.raised:
                say(f"  video: {frames.speedup:g}x speed, raised to keep it within {MAX_VIDEO_SECONDS:g} s")
            bar = ProgressBar("  video", enabled=progress)
            written = write_video(outs.stem, frames, scenario.render.fps, scenario.render.formats, progress=bar)
            bar.close()
            media = [outs.final(p.name) for p in written]
            staged = list(written)
        else:
            staged = []
        report["media"] = [str(m) for m in media]
        code = 0 if (sim.ok and valid) else 1
        report["ok"] = code == 0
        report["page"] = str(outs.final(page_name))
        run_page(outs.path(page_name), report, problem, result, sim, staged)
        _write_report(outs.path(json_name), report)
        outs.commit()
    for f in (*media, outs.final(series_name), outs.final(page_name)):
        say(f"  wrote {f}")
    report_path = outs.final(json_name)
    say(f"  wrote {report_path}")
    return RunResult(report, code, report_path, media, sim, result)


def _check_loaded(p: Plan, problem, scenario: Scenario, source: str) -> Plan:
    """Check a loaded plan against the scenario's problem; raise :class:`InputError` naming the field.

    The plan must move the scenario's robots from their start, with the
    scenario's radius and margin, inside its workspace, and within its
    speed and acceleration limits (each step's peak under minimum jerk);
    its physics and exact validation must fit their budgets.
    """
    src, scn = echo_path(source, 70), echo_path(scenario.path, 50)
    if p.m != problem.m:
        raise InputError(f"{src}: waypoints: the plan moves {p.m} robot{'s' * (p.m != 1)} but {scn} "
                         f"has {problem.m}")
    for key, mine in (("radius", problem.radius), ("margin", problem.margin)):
        theirs = getattr(p, key)
        if not np.isclose(theirs, mine, rtol=1e-9, atol=1e-12):
            raise InputError(f"{src}: {key}: is {theirs:.6g} but {scn} has robots.{key} {mine:.6g}")
    gap = np.linalg.norm(p.start - problem.start, axis=1)
    if gap.max() > 1e-6:
        i = int(np.argmax(gap))
        raise InputError(f"{src}: waypoints[0][{i}]: robot {i} does not start where {scn} "
                         f"puts it (pass the --seed the plan was made with)")
    w = p.waypoints
    out = (w[..., 0] < 0) | (w[..., 0] > problem.width) | (w[..., 1] < 0) | (w[..., 1] > problem.height)
    if out.any():
        k, i = (int(v) for v in np.argwhere(out)[0])
        raise InputError(f"{src}: waypoints[{k}][{i}]: ({w[k, i, 0]:.6g}, {w[k, i, 1]:.6g}) lies outside "
                         f"the {problem.width:g} x {problem.height:g} workspace")
    bad = p.limit_violation(problem.max_speed, problem.max_accel)
    if bad is not None:
        k, i, kind, need, limit = bad
        key = "max_speed" if kind == "speed" else "max_accel"
        raise InputError(f"{src}: durations[{k}]: step {k} moves robot {i} at a peak {kind} of {need:.4g}, "
                         f"over robots.{key} = {limit:g} (raise the duration)")
    check_physics_budget(p.m, p.makespan, scenario.sim, source)
    check_validator_budget(p, source)
    return p


def _loaded_stats(p: Plan, problem) -> PlanStats:
    """The exact stats of a loaded plan (its own recorded planning stats kept)."""
    c = min_clearance(problem, p)
    stats = PlanStats(found=True, steps=p.steps, makespan_s=p.makespan, path_length=p.path_length,
                      min_clearance=c.value)
    if p.stats is not None:
        stats.planning_time_s, stats.g, stats.q = p.stats.planning_time_s, p.stats.g, p.stats.q
        stats.graphs, stats.connections = p.stats.graphs, p.stats.connections
    stats.makespan_lower_bound_s, stats.path_length_lower_bound = lower_bounds(problem)
    return stats


def _late(scenario, seed: int, limit: float, outs: OutputSet, out) -> RunResult:
    """A run whose time limit ran out while its robots were being placed: exit 1, and a
    report that says so (no plan, no physics, no media)."""
    error = f"the time limit of {limit:g} s ran out while the robots were being placed"
    report = {"scenario": scenario.name, "seed": seed, "robots": scenario.count, "scenario_file": str(scenario.path),
              "plan": {"found": False, "error": error}, "sim": None, "media": [], "ok": False}
    with outs:
        _write_report(outs.path(f"{scenario.name}.json"), report)
        outs.commit()
    if out is not None:
        print(f"{scenario.name} (seed {seed}): no plan: {error}", file=out)
        print(f"  wrote {outs.final(scenario.name + '.json')}", file=out)
    return RunResult(report, 1, outs.final(f"{scenario.name}.json"))


def _write_report(path: Path, report: dict) -> Path:
    with atomic_path(path) as tmp:
        tmp.write_text(json.dumps(report, indent=2, allow_nan=False, default=_json_default) + "\n",
                       encoding="utf-8")
    return path


def _json_default(v):
    if isinstance(v, (np.integer,)):
        return int(v)
    if isinstance(v, (np.floating,)):
        return float(v)
    if isinstance(v, np.ndarray):
        return v.tolist()
    raise TypeError(f"not JSON-serialisable: {type(v).__name__}")


