"""The run page: one self-contained HTML file per run, ``DIR/NAME.html``.

:func:`write_run_page` is a function over plain data: the run report (the
dict written as ``NAME.json``), the time series of the run (see
:mod:`sim.series`), the scenario picture and the path of the video.  The
page is rendered from the Jinja2 template ``sim/templates/run.html.j2``
with autoescaping; plots are drawn with matplotlib's object API (no pyplot,
no global backend change); the picture, the
plots and the video are embedded as data URIs, so the file opens offline,
alone.  It holds, top to bottom: the verdict in one line; the scenario
picture and the video; the smallest gap over time with the margin drawn,
and each robot's tracking error over time; the plan's numbers against the
lower bounds; the physics numbers; the contacts; disturbances and replans
where there are any; the raw report.

Keys the page reads and does not need (it says what is missing, or leaves
the part out): ``margin``; ``sim.first_contact``,
``sim.max_tracking_error_time``, ``sim.reached_robots``,
``sim.disturbances`` (``time``, ``robot``, ``kind``, ``impulse``),
``sim.replans`` (``time``, ``reason``, ``planning_time_s``, ``robots``,
``found``, ``steps``); ``video`` (see :meth:`sim.playback.Timing.to_dict`).

:func:`run_page` gathers those inputs from a run's objects and writes the
page (what ``swarmform run`` calls).
"""

from __future__ import annotations

import base64
import io
import json
import math
from pathlib import Path

import numpy as np

from .media import atomic_path
from .words import reached_phrase, run_notes

__all__ = ["EMBED_MAX_BYTES", "run_page", "verdict", "write_run_page"]

EMBED_MAX_BYTES = 24_000_000
"""A video larger than this [bytes] is linked, not embedded (the page stays a sane size)."""

_TITLE_CHARS = 120  # the longest title shown (the raw report keeps the whole name)
_SHOWN_CONTACTS = 12  # contacts in the table; the rest behind "more"
_ROBOT_LINES = 30  # up to this many robots, the tracking plot has one line per robot
_DPI = 100


# ----------------------------------------------------------------------------
# the verdict


def verdict(report: dict) -> tuple[bool, str]:
    """Whether the run is ok, and one line saying why."""
    plan = report.get("plan") or {}
    sim = report.get("sim") or {}
    ok = bool(report.get("ok"))
    if not plan.get("found"):
        why = plan.get("error") or "no plan within the limits"
        if plan.get("feasible") is False:
            return False, f"FAILED: {why}"
        return False, f"FAILED: no plan ({why})"
    reasons = []
    if plan.get("valid") is False:
        reasons.append(f"the plan comes closer than the margin (min clearance {_num(plan.get('min_clearance'))})")
    n = sim.get("contacts") or 0
    if n:
        first = sim.get("first_contact") or (sim.get("contact_list") or [None])[0]
        where = f", the first {_describe_contact(first)}" if first else ""
        reasons.append(f"{n} contact{'s' if n != 1 else ''} in the physics run{where}")
    if sim and sim.get("stopped"):
        reasons.append(f"stopped: {sim['stopped']}")
    if sim and sim.get("reached") is False and not sim.get("stopped"):
        got = _count(sim.get("reached_robots"))
        m = report.get("robots")
        count = f" ({got} of {m} did)" if got is not None and m is not None else ""
        reasons.append(f"not every robot reached a target{count}")
    if not sim and plan.get("found"):
        reasons.append("not executed in physics")
    notes = _physics_notes(sim, report.get("robots"))
    if reasons:
        return False, "FAILED: " + "; ".join(reasons + notes)
    if not ok:
        return False, "FAILED"
    who = reached_phrase(bool(sim.get("failed")), _parked(sim))
    return True, (f"ok: plan found and executed with zero contacts, {who} "
                  f"(min clearance {_num(sim.get('min_clearance'))}"
                  + (f", margin {_num(report.get('margin'))})" if report.get("margin") is not None else ")")
                  + "".join(f"; {n}" for n in notes))


def _parked(sim: dict) -> int:
    """Working robots parked by the last replan (failed robots block their targets)."""
    replans = sim.get("replans") or []
    last = replans[-1] if replans and isinstance(replans[-1], dict) else {}
    parked = last.get("parked") or []
    return len(parked) if isinstance(parked, list) else 0


def _physics_notes(sim: dict, m) -> list[str]:
    """What a realistic run adds to the verdict: failed robots, empty targets, replans, an unstable loop."""
    return run_notes(sim.get("failed"), _parked(sim), sim.get("targets_filled"), m,
                     len(sim.get("replans") or []), sim.get("phase_margin_deg"), list_max=10)


def _describe_contact(c: dict) -> str:
    kind, a, b = c.get("kind"), c.get("a"), c.get("b")
    if kind == "robot-robot":
        who = f"robots {a} and {b}"
    elif kind == "robot-wall":
        who = f"robot {a} and the wall"
    else:
        who = f"robot {a} and obstacle {b}"
    return f"{who} at t = {_num(c.get('time'), 3)} s"


# ----------------------------------------------------------------------------
# the page


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
        (see :mod:`sim.series`), or None: the page then has no plots.
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
        "contacts_total": int(sim.get("contacts") or 0),
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
    else computed from its recording and the plan (:func:`sim.series.run_series`);
    the video is the GIF when there is one (it plays everywhere), else the MP4.
    """
    from .render import draw_scenario
    from .series import run_series

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


def _count(v) -> int | None:
    """How many robots reached: ``reached_robots`` is a list of flags per robot (or a count)."""
    if isinstance(v, list):
        return sum(bool(x) for x in v)
    return v if isinstance(v, int) else None


def _num(v, digits: int = 4) -> str:
    if v is None or isinstance(v, bool):
        return "n/a" if v is None else ("yes" if v else "no")
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    if isinstance(v, (list, tuple)):  # a vector such as an impulse [N s, N s]
        return "[" + ", ".join(_num(x, digits) for x in v) + "]"
    try:
        x = float(v)
    except (TypeError, ValueError):
        return str(v)
    if not math.isfinite(x):
        return "n/a"
    return f"{x:.{digits}g}"


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
    rows = [("contacts", _num(s.get("contacts")),
             f"pymunk {_num(s.get('contacts_pymunk'))}, monitor {_num(s.get('contacts_monitor'))}")]
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


def _disturbance_list(sim: dict) -> list:
    """The disturbances applied: the physics report's ``{impulses, pushes, failures, list}`` or a plain list."""
    d = sim.get("disturbances")
    if isinstance(d, dict):
        d = d.get("list")
    return d if isinstance(d, list) else []


def _rows(items, keys: tuple[str, ...]) -> list[dict]:
    """Entries of a list of records as dicts holding every key (None where missing)."""
    out = []
    for item in items or []:
        if isinstance(item, dict):
            out.append({k: item.get(k) for k in keys})
    return out


def _contact_rows(sim: dict) -> list[dict]:
    rows = []
    first = sim.get("first_contact")
    keys = ("time", "kind", "a", "b", "depth", "witness")
    for n, c in enumerate(sim.get("contact_list") or []):
        if not isinstance(c, dict):
            continue
        row = {k: c.get(k) for k in keys}
        row["first"] = (first == c) if first else n == 0
        row["witness"] = _witness_text(c.get("witness"))
        rows.append(row)
    return rows


def _witness_text(w) -> str:
    if isinstance(w, (list, tuple)) and len(w) == 2:
        return f"({_num(w[0])}, {_num(w[1])})"
    return "" if w is None else str(w)


# ----------------------------------------------------------------------------
# pictures


def _png_uri(image: np.ndarray) -> str:
    import imageio.v3 as iio

    data = iio.imwrite("<bytes>", np.ascontiguousarray(image), extension=".png")
    return "data:image/png;base64," + base64.b64encode(data).decode("ascii")


def _video(video: str | Path | None) -> dict | None:
    if video is None:
        return None
    p = Path(video)
    if not p.is_file():
        return None
    size = p.stat().st_size
    kind = "gif" if p.suffix.lower() == ".gif" else "mp4"
    out = {"kind": kind, "name": p.name, "mb": f"{size / 1e6:.1f}", "uri": None, "width": None, "height": None}
    if kind == "gif":
        with open(p, "rb") as fh:
            head = fh.read(10)
        if len(head) == 10 and head[:3] == b"GIF":
            out["width"], out["height"] = int.from_bytes(head[6:8], "little"), int.from_bytes(head[8:10], "little")
    if size <= EMBED_MAX_BYTES:
        mime = "image/gif" if kind == "gif" else "video/mp4"
        out["uri"] = f"data:{mime};base64," + base64.b64encode(p.read_bytes()).decode("ascii")
    return out


def _plots(report: dict, series: dict) -> list[dict]:
    """The clearance and tracking plots as ``{id, title, uri, width, height}``."""
    t = np.asarray(series.get("times", ()), float).reshape(-1)
    out = []
    if len(t) == 0:
        return out
    gap = series.get("min_gap")
    if gap is not None:
        out.append(_plot_gap(report, t, np.asarray(gap, float).reshape(-1)))
    err = series.get("tracking_error")
    if err is not None:
        err = np.asarray(err, float)
        out.append(_plot_tracking(report, t, err.reshape(len(t), -1)))
    return out


def _figure():
    from matplotlib.figure import Figure

    fig = Figure(figsize=(9.6, 3.4), dpi=_DPI, layout="constrained")
    return fig, fig.add_subplot()


def _events(ax, report: dict) -> None:
    """Plan end and replans as vertical lines; contacts (bottom) and disturbances (top) as ticks."""
    plan = report.get("plan") or {}
    sim = report.get("sim") or {}
    if _finite(plan.get("makespan_s")):
        ax.axvline(plan["makespan_s"], color="0.45", lw=1, ls=":", label="plan ends")

    def times(key):
        return [x.get("time") for x in sim.get(key) or [] if isinstance(x, dict) and _finite(x.get("time"))]

    axis = ax.get_xaxis_transform()  # x in data, y in axes fractions
    contacts = times("contact_list")
    if contacts:
        ax.plot(contacts, [0.0] * len(contacts), "|", transform=axis, color="#e61414", ms=16, mew=1.6,
                clip_on=False, label="contact")
    pushes = [d["time"] for d in _disturbance_list(sim) if isinstance(d, dict) and _finite(d.get("time"))]
    if pushes:
        ax.plot(pushes, [1.0] * len(pushes), "v", transform=axis, color="#8a4fd0", ms=7, clip_on=False,
                label="disturbance")
    for n, t in enumerate(times("replans")):
        ax.axvline(t, color="#1f8a4c", lw=1, ls="-.", label="replan" if n == 0 else None)


def _finite(v) -> bool:
    return isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool) and math.isfinite(v)


def _plot_gap(report: dict, t: np.ndarray, gap: np.ndarray) -> dict:
    fig, ax = _figure()
    ax.plot(t, gap, color="#2857c8", lw=1.4, label="smallest gap")
    margin = report.get("margin")
    if margin is not None:
        ax.axhline(margin, color="#ec7828", lw=1.4, ls="--", label=f"margin {margin:g}")
    ax.axhline(0.0, color="#e61414", lw=1, label="touching")
    sim = report.get("sim") or {}
    if _finite(sim.get("min_clearance")) and _finite(sim.get("min_clearance_time")):
        ax.plot([sim["min_clearance_time"]], [sim["min_clearance"]], "o", color="#2857c8", ms=5,
                label=f"minimum {sim['min_clearance']:.4g}")
    _events(ax, report)
    ax.set_xlabel("time [s]")
    ax.set_ylabel("gap [units]")
    ax.set_title("Smallest gap between robots, obstacles and walls")
    top = float(np.nanmax(gap)) if np.isfinite(gap).any() else 1.0
    ax.set_ylim(min(-0.05 * max(top, 1e-9), float(np.nanmin(gap)) if np.isfinite(gap).any() else 0.0),
                max(top, margin or 0.0) * 1.08 + 1e-9)
    ax.grid(alpha=0.3)
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8, frameon=False)
    return _plot_dict("plot-clearance", "Smallest gap over time", fig)


def _plot_tracking(report: dict, t: np.ndarray, err: np.ndarray) -> dict:
    from .canvas import robot_colors

    fig, ax = _figure()
    m = err.shape[1]
    if m <= _ROBOT_LINES:
        for i, c in enumerate(robot_colors(m)):
            ax.plot(t, err[:, i], color=np.array(c) / 255.0, lw=1.1, label=f"robot {i}" if m <= 12 else None)
    else:
        ax.fill_between(t, err.min(axis=1), err.max(axis=1), color="#9fb3e0", alpha=0.5, lw=0,
                        label=f"all {m} robots (min to max)")
        ax.plot(t, np.median(err, axis=1), color="#2857c8", lw=1.2, label="median")
        worst = int(np.argmax(err.max(axis=0)))
        ax.plot(t, err[:, worst], color="0.15", lw=1.0, label=f"robot {worst} (largest)")
    _events(ax, report)
    ax.set_xlabel("time [s]")
    ax.set_ylabel("distance from the plan [units]")
    ax.set_title("Tracking error per robot")
    ax.set_ylim(bottom=0.0)
    ax.grid(alpha=0.3)
    _, labels = ax.get_legend_handles_labels()
    if labels:
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8, frameon=False,
                  ncols=1 if len(labels) <= 10 else 2)
    return _plot_dict("plot-tracking", "Tracking error per robot over time", fig)


def _plot_dict(ident: str, title: str, fig) -> dict:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=_DPI)
    w, h = (int(round(v)) for v in fig.get_size_inches() * _DPI)
    return {"id": ident, "title": title, "width": w, "height": h,
            "uri": "data:image/png;base64," + base64.b64encode(buf.getvalue()).decode("ascii")}


# ----------------------------------------------------------------------------
# the template


def _template():
    import jinja2

    env = jinja2.Environment(
        loader=jinja2.PackageLoader("sim", "templates"),
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
