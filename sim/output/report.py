"""The run page: one self-contained HTML file per run, ``DIR/NAME.html``.

:func:`write_run_page` is a function over plain data: the run report (the
dict written as ``NAME.json``), the time series of the run (see
:mod:`sim.execute.series`), the scenario picture and the path of the video.  The
page is rendered from the Jinja2 template ``sim/output/templates/run.html.j2``
with autoescaping; plots are drawn with matplotlib's object API (no pyplot,
no global backend change); the picture, the
plots and the video are embedded as data URIs, so the file opens offline,
alone.  It holds, top to bottom: the verdict in one line; the scenario
picture and the video; the smallest gap over time with the margin drawn,
and each robot's tracking error over time; the plan's numbers against the
lower bounds; the settings (every ``--set`` value and every parameter not at
its default, :mod:`sim.output.settings`); the physics numbers; the contact
events with the witnesses that saw each (:mod:`sim.execute.events`);
disturbances and replans
where there are any; the raw report.

Keys the page reads and does not need (it says what is missing, or leaves
the part out): ``margin``; ``sim.first_contact``,
``sim.max_tracking_error_time``, ``sim.reached_robots``,
``sim.disturbances`` (``time``, ``robot``, ``kind``, ``impulse``),
``sim.replans`` (``time``, ``reason``, ``planning_time_s``, ``robots``,
``found``, ``steps``); ``video`` (see :meth:`sim.output.playback.Timing.to_dict`).

:func:`run_page` gathers those inputs from a run's objects and writes the
page (what ``swarmform run`` calls).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from ..words import reached_phrase
from .media import atomic_path
from .plots import EMBED_MAX_BYTES, _plots, _png_uri, _video
from .settings import settings_rows
from .verdict import _count, _disturbance_list, _num, _parked, contact_events, verdict

__all__ = ["EMBED_MAX_BYTES", "run_page", "verdict", "write_run_page"]


_TITLE_CHARS = 120  # the longest title shown (the raw report keeps the whole name)
_SHOWN_CONTACTS = 12  # contacts in the table; the rest behind "more"


def write_run_page(
    path: str | Path,
    report: dict,
    series: dict | None,
    scenario_png: np.ndarray | None,
    video: str | Path | None,
) -> Path:
    """Write the run page to ``path`` (atomically) and return the path.

    report: the run report (``NAME.json``'s content).
    series: ``times (T,)``, ``min_gap (T,)``, ``tracking_error (T, m)``
        (see :mod:`sim.execute.series`), or None: the page then has no plots.
    scenario_png: the scenario picture ``(H, W, 3) uint8``, or None.
    video: a GIF or MP4 file to embed, or None.  One larger than
        :data:`EMBED_MAX_BYTES` is linked by its file name instead (keep it
        beside the page).
    """
    path = Path(path)
    ok, line = verdict(report)
    sim = report.get("sim") or {}
    context = {
        "title": _cut(str(report.get("scenario", "run")), _TITLE_CHARS),
        "ok": ok,
        "verdict": line,
        "report": report,
        "plan_rows": _plan_rows(report),
        "sim_rows": _sim_rows(report),
        "video_rows": _video_rows(report.get("video")),
        "meta": _meta(report),
        "contacts": _contact_rows(sim),
        "contacts_total": contact_events(sim)[0],
        "settings_rows": settings_rows(report),
        "shown_contacts": _SHOWN_CONTACTS,
        "disturbances": _rows(_disturbance_list(sim), ("time", "robot", "kind", "impulse")),
        "replans": _rows(sim.get("replans"), ("time", "reason", "planning_time_s", "robots", "found", "steps")),
        "scenario_img": _png_uri(scenario_png) if scenario_png is not None else None,
        "scenario_size": None if scenario_png is None else (scenario_png.shape[1], scenario_png.shape[0]),
        "video": _video(video),
        "plots": _plots(report, series) if series is not None else [],
        "raw": json.dumps(report, indent=2, default=_json_default),
    }
    html = _template().render(**context)
    with atomic_path(path) as tmp:
        tmp.write_text(html, encoding="utf-8")
    return path


def run_page(path: str | Path, report: dict, problem, plan=None, sim=None, media=()) -> Path:
    """Write the run page of a run from its objects (what ``swarmform run`` does).

    The series are the physics run's own (``sim.series``) when it has them,
    else computed from its recording and the plan (:func:`sim.execute.series.run_series`);
    the video is the GIF when there is one (it plays everywhere), else the MP4.
    """
    from ..execute.series import run_series
    from .render import draw_scenario

    series = None
    if sim is not None:
        series = getattr(sim, "series", None)
        series = series() if callable(series) else series
        if series is None and plan is not None:
            series = run_series(problem, plan, sim.times, sim.positions)
    paths = [Path(p) for p in media]
    video = next((p for p in paths if p.suffix == ".gif"), None) or next(
        (p for p in paths if p.suffix == ".mp4"), None)
    title = f"{report.get('scenario', '')}  seed {report.get('seed', '')}"
    return write_run_page(path, report, series, draw_scenario(problem, title=title), video)


# ----------------------------------------------------------------------------
# tables


def _ratio(value, bound) -> str:
    try:
        v, b = float(value), float(bound)
    except (TypeError, ValueError):
        return ""
    if not (math.isfinite(v) and math.isfinite(b)) or b <= 0:
        return ""
    return f"{v / b:.2f}x the bound"


def _plan_rows(report: dict) -> list[tuple[str, str, str]]:
    """``(name, value, against what)`` rows of the plan block."""
    p = report.get("plan") or {}
    margin = report.get("margin")
    rows = [("found", _num(p.get("found")), "")]
    if report.get("plan_file"):
        rows.append(("plan", "loaded", str(report["plan_file"])))
    elif p.get("planning_time_s") is not None:
        rows.append(("planning time", f"{_num(p.get('planning_time_s'), 3)} s", ""))
    rows.append(("g, q", f"{p.get('g', 'n/a')}, {p.get('q', 'n/a')}", ""))
    rows.append(("pebble graphs sampled", _num(p.get("graphs")), ""))
    rows.append(("connections", _num(p.get("connections")), ""))
    if p.get("found"):
        rows.append(("steps", _num(p.get("steps")), ""))
        rows.append(("makespan", f"{_num(p.get('makespan_s'))} s",
                     f"lower bound {_num(p.get('makespan_lower_bound_s'))} s; "
                     + _ratio(p.get("makespan_s"), p.get("makespan_lower_bound_s"))))
        rows.append(("total path length", _num(p.get("path_length")),
                     f"lower bound {_num(p.get('path_length_lower_bound'))}; "
                     + _ratio(p.get("path_length"), p.get("path_length_lower_bound"))))
        against = f"margin {_num(margin)}" if margin is not None else ""
        if p.get("valid") is not None:
            against += ("; " if against else "") + ("valid" if p.get("valid") else "BELOW THE MARGIN")
        rows.append(("exact min clearance", _num(p.get("min_clearance")), against))
    if p.get("error"):
        rows.append(("why no plan", str(p["error"]), ""))
    return rows


def _sim_rows(report: dict) -> list[tuple[str, str, str]]:
    s = report.get("sim") or {}
    if not s:
        return []
    m = report.get("robots")
    n, events = contact_events(s)
    both = sum(len(e.get("witnesses") or ()) > 1 for e in events)
    seen = f"{both} seen by both witnesses; " if events else ""
    sightings = f"sightings: pymunk {_num(s.get('contacts_pymunk'))}, monitor {_num(s.get('contacts_monitor'))}"
    rows = [("contacts", _num(n), seen + sightings)]
    pair = s.get("min_clearance_pair") or []
    what = s.get("min_clearance_kind") or ""
    if what and len(pair) == 2:
        what = {"robot-robot": f"robots {pair[0]} and {pair[1]}", "robot-wall": f"robot {pair[0]} and the wall",
                "robot-obstacle": f"robot {pair[0]} and obstacle {pair[1]}"}.get(what, what)
    at = f"at t = {_num(s.get('min_clearance_time'))} s" if s.get("min_clearance_time") is not None else ""
    rows.append(("min clearance seen", _num(s.get("min_clearance")), ", ".join(x for x in (at, what) if x)))
    when = s.get("max_tracking_error_time")
    rows.append(("max tracking error", _num(s.get("max_tracking_error")),
                 f"at t = {_num(when)} s" if when is not None else ""))
    reached = _num(s.get("reached"))
    if s.get("reached_robots") is not None and m is not None:
        reached += f" ({_count(s['reached_robots'])} of {m} robots)"
    label = reached_phrase(bool(s.get("failed")), _parked(s))
    rows.append((label, reached, f"worst final distance {_num(s.get('final_error'))}"))
    rows.append(("simulated", f"{_num(s.get('sim_time_s'))} s",
                 f"in {_num(s.get('wall_time_s'), 3)} s wall-clock time"))
    if "phase_margin_deg" in s:
        pm = s.get("phase_margin_deg")
        note = "the controller with its delays (latency, half the hold)"
        if isinstance(pm, (int, float)) and not isinstance(pm, bool) and pm <= 0:
            note += ": UNSTABLE"
        rows.append(("phase margin", "n/a" if pm is None else f"{_num(pm, 3)}°", note))
    return rows


def _video_rows(video: dict | None) -> list[tuple[str, str, str]]:
    if not video:
        return []
    speed = f"{_num(video.get('speedup'))}x"
    note = ""
    if video.get("speedup_raised"):
        note = (f"raised from {_num(video.get('speedup_asked'))}x to keep the video within the longest "
                f"allowed length")
    return [("playback speed", speed, note),
            ("frames", _num(video.get("frames")), f"{_num(video.get('seconds'))} s at {_num(video.get('fps'))} fps")]


def _cut(text: str, n: int) -> str:
    return text if len(text) <= n else text[: n - 3] + "..."


def _meta(report: dict) -> list[str]:
    items = [f"seed {report.get('seed', 'n/a')}", f"{report.get('robots', '?')} robots"]
    if report.get("margin") is not None:
        items.append(f"radius {_num(report.get('radius'))}, margin {_num(report.get('margin'))}")
    for key, name in (("scenario_file", "scenario"), ("plan_file", "plan")):
        if report.get(key):
            items.append(f"{name} {report[key]}")
    items.append(f"swarmform {_version()}")
    return items


def _rows(items, keys: tuple[str, ...]) -> list[dict]:
    """Entries of a list of records as dicts holding every key (None where missing)."""
    out = []
    for item in items or []:
        if isinstance(item, dict):
            out.append({k: item.get(k) for k in keys})
    return out


def _contact_rows(sim: dict) -> list[dict]:
    """The contact events (grouped from an old report's sightings), the first marked."""
    rows = []
    for n, e in enumerate(contact_events(sim)[1]):
        rows.append({"time": e.get("start", e.get("time")), "end": e.get("end"), "kind": e.get("kind"),
                     "a": e.get("a"), "b": e.get("b"), "depth": e.get("depth"), "first": n == 0,
                     "witness": _witness_text(e.get("witnesses", e.get("witness")))})
    return rows


def _witness_text(w) -> str:
    if isinstance(w, (list, tuple)):
        return " and ".join(str(x) for x in w)
    return "" if w is None else str(w)


# ----------------------------------------------------------------------------
# pictures


def _template():
    import jinja2

    env = jinja2.Environment(
        loader=jinja2.PackageLoader("sim.output", "templates"),
        autoescape=jinja2.select_autoescape(("html", "j2")),
        undefined=jinja2.StrictUndefined,
        trim_blocks=True,
        lstrip_blocks=True,
    )
    env.filters["num"] = _num
    return env.get_template("run.html.j2")


def _version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("swarmform")
    except PackageNotFoundError:
        return "unknown"


def _json_default(v):
    if isinstance(v, np.integer):
        return int(v)
    if isinstance(v, np.floating):
        return float(v)
    if isinstance(v, np.ndarray):
        return v.tolist()
    return str(v)
