"""The run: plan (or load a plan), validate, execute in pymunk, render, report.

``run_scenario`` is what ``swarmform run`` does; it returns the report and
the exit code (0: plan found and executed with zero contacts, every robot
on a target; 1: no plan, or a contact, or a missed target, or a plan below
the margin; the report is written in every one of these cases).  Bad input
raises :class:`InputError` (exit 2) before anything is written.
"""

from __future__ import annotations

import json
import sys
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from planner import NoPlanFound, Plan, PlanStats, min_clearance
from planner.bounds import lower_bounds

from .execute import SimReport, execute
from .legs import plan_legs
from .media import atomic_path, has_mp4, write_video
from .progress import ProgressBar
from .playback import MAX_VIDEO_SECONDS
from .render import render_frames
from .report import run_page
from .scenario import Scenario, build_legs, read_scenario
from .series import write_series
from .words import plural

__all__ = ["InputError", "RunResult", "plan_summary", "run_scenario", "sim_summary"]


class InputError(ValueError):
    """Wrong input found by the run (one line naming the file, the field, the reason)."""


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
    if valid is not None:
        out["valid"] = valid
    if "legs" in stats.extra:
        out["legs"] = stats.extra["legs"]
    return out


def sim_summary(report: SimReport) -> dict:
    """The ``sim`` block of a run report."""
    return report.to_dict()


def _load_plan(path: str) -> tuple[Plan, int | None]:
    """A plan file and the seed it was made with, when it records one."""
    p = Plan.load(path)
    raw = json.loads(Path(path).read_text(encoding="utf-8"))
    seed = raw.get("seed")
    ok = isinstance(seed, int) and not isinstance(seed, bool) and seed >= 0
    return p, seed if ok else None


def run_scenario(
    path: str | Path,
    *,
    seed: int | None = None,
    out_dir: str | Path = "media",
    render: bool = True,
    plan_path: str | Path | None = None,
    time_limit: float | None = None,
    progress: bool | None = None,
    out=sys.stdout,
    overrides: dict | None = None,
) -> RunResult:
    """Plan or load, validate, execute, render and write ``DIR/NAME.json``.

    With ``plan_path`` the plan is executed as it is, even when the exact
    validator finds it below the margin (that is how a regression test
    proves a collision is seen); its recorded seed rebuilds the same
    problem unless ``seed`` is given.  ``overrides`` set scenario fields
    (``{"robots.margin": 0.2}``, as ``--set``).
    """
    scenario = read_scenario(path, overrides=overrides)
    loaded = None
    if plan_path is not None:
        loaded, recorded = _load_plan(str(plan_path))
        seed = recorded if seed is None else seed
    seed = scenario.seed if seed is None else seed
    rng = np.random.default_rng(seed)
    problem, targets = build_legs(scenario, rng)
    leg_times = None
    out_dir = Path(out_dir)
    name = scenario.name
    say = (lambda *a: print(*a, file=out)) if out is not None else (lambda *a: None)
    say(f"{name} (seed {seed}): {problem.m} robots, {scenario.describe()}")

    report: dict = {"scenario": name, "seed": seed, "robots": problem.m, "radius": problem.radius,
                    "margin": problem.margin, "scenario_file": str(path)}
    if overrides:
        report["settings"] = dict(overrides)  # the --set values the scenario was read with
    if loaded is not None:
        result, stats = _check_loaded(loaded, problem, scenario, str(plan_path))
        report["plan_file"] = str(plan_path)
    else:
        params = scenario.planner if time_limit is None else replace(scenario.planner, time_limit=time_limit)
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
            say(f"  no plan in {exc.stats.planning_time_s:.2f} s: {exc}")
            report["page"] = str(run_page(out_dir / f"{name}.html", report, problem))
            say(f"  wrote {report['page']}")
            report_path = _write_report(out_dir / f"{name}.json", report)
            say(f"  wrote {report_path}")
            return RunResult(report, 1, report_path)
    valid = bool(stats.min_clearance >= problem.margin - 1e-9)
    report["plan"] = plan_summary(stats, valid=valid, auto=loaded is None and params.auto)
    made = f"planned in {stats.planning_time_s:.2f} s" if loaded is None else f"from {plan_path}"
    say(f"  plan: {plural(stats.steps, 'step')} ({made}), makespan {stats.makespan_s:.1f} s, "
        f"min clearance {stats.min_clearance:.4f} (margin {problem.margin:g}){'' if valid else '  BELOW THE MARGIN'}")

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
    series = out_dir / f"{name}-series.npz"
    with atomic_path(series) as tmp:
        write_series(tmp, sim)
    report["sim"]["series_file"] = series.name
    say(f"  physics: {plural(len(sim.contacts), 'contact')}, min clearance {sim.min_clearance:.4f}, "
        f"tracking error {sim.max_tracking_error:.2g}, reached {'yes' if sim.reached else 'no'}, "
        f"{sim.sim_time_s:.1f} s simulated in {sim.wall_time_s:.1f} s")
    say(f"  physics verdict: {sim.verdict}")

    media: list[Path] = []
    if render and "mp4" in scenario.render.formats and not has_mp4():
        say("  (no MP4: install imageio-ffmpeg, e.g. pip install -e '.[video]')")
    if render:
        legs = None if leg_times is None or len(targets) < 2 else list(zip(leg_times[:-1], targets))
        frames = render_frames(problem, sim.times, sim.positions, sim.contacts, scenario.render,
                               step_times=result.times, title=name, targets=legs)
        report["video"] = frames.timing.to_dict()
        if frames.timing.raised:
            say(f"  video: {frames.speedup:g}x speed, raised to keep it within {MAX_VIDEO_SECONDS:g} s")
        bar = ProgressBar("  video", enabled=progress)
        media = write_video(out_dir / name, frames, scenario.render.fps, scenario.render.formats, progress=bar)
        bar.close()
        for m in media:
            say(f"  wrote {m}")
    report["media"] = [str(m) for m in media]
    code = 0 if (sim.ok and valid) else 1
    report["ok"] = code == 0
    report["page"] = str(run_page(out_dir / f"{name}.html", report, problem, result, sim, media))
    say(f"  wrote {report['page']}")
    report_path = _write_report(out_dir / f"{name}.json", report)
    say(f"  wrote {report_path}")
    return RunResult(report, code, report_path, media, sim, result)


def _check_loaded(p: Plan, problem, scenario: Scenario, source: str) -> tuple[Plan, PlanStats]:
    """Check a loaded plan fits the scenario's problem; compute its exact stats."""
    if p.m != problem.m:
        raise InputError(f"{source}: waypoints: the plan moves {p.m} robots but "
                         f"{scenario.path} has {problem.m}")
    gap = np.linalg.norm(p.start - problem.start, axis=1)
    if gap.max() > 1e-6:
        i = int(np.argmax(gap))
        raise InputError(f"{source}: waypoints[0][{i}]: robot {i} does not start where {scenario.path} "
                         f"puts it (pass the --seed the plan was made with)")
    c = min_clearance(problem, p)
    stats = PlanStats(found=True, steps=p.steps, makespan_s=p.makespan, path_length=p.path_length,
                      min_clearance=c.value)
    if p.stats is not None:
        stats.planning_time_s, stats.g, stats.q = p.stats.planning_time_s, p.stats.g, p.stats.q
        stats.graphs, stats.connections = p.stats.graphs, p.stats.connections
    stats.makespan_lower_bound_s, stats.path_length_lower_bound = lower_bounds(problem)
    return p, stats


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


