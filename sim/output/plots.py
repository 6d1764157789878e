"""The run page's pictures: the smallest gap and the tracking errors over time (matplotlib's object API), as data URIs."""

from __future__ import annotations

import base64
import io
import math
from pathlib import Path

import numpy as np

from .verdict import _disturbance_list, contact_events

__all__ = ["EMBED_MAX_BYTES"]

EMBED_MAX_BYTES = 24_000_000
"""A video larger than this [bytes] is linked, not embedded (the page stays a sane size)."""
_ROBOT_LINES = 10  # up to this many robots, the tracking plot has one line per robot
_BAND = (10, 90)  # beyond that: the median, this quantile band [%] and the worst robot
_DPI = 100




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
    contacts = [e.get("start", e.get("time")) for e in contact_events(sim)[1]]
    contacts = [x for x in contacts if _finite(x)]
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


def worst_robot(err: np.ndarray) -> int:
    """The robot with the largest tracking error at any time (NaN, a failed robot, ignored); -1 if none."""
    peak = np.where(np.isfinite(err), err, -np.inf).max(axis=0, initial=-np.inf)
    return int(np.argmax(peak)) if np.isfinite(peak).any() else -1


def _plot_tracking(report: dict, t: np.ndarray, err: np.ndarray) -> dict:
    return _plot_dict("plot-tracking", "Tracking error per robot over time", _tracking_figure(report, t, err))


def _tracking_figure(report: dict, t: np.ndarray, err: np.ndarray):
    """One line per robot up to 10 robots; beyond, the median, the 10-90 % band and the worst robot."""
    import warnings

    from .canvas import robot_colors

    fig, ax = _figure()
    m = err.shape[1]
    if m <= _ROBOT_LINES:
        for i, c in enumerate(robot_colors(m)):
            ax.plot(t, err[:, i], color=np.array(c) / 255.0, lw=1.1, label=f"robot {i}")
    else:
        with warnings.catch_warnings():  # a sample where every robot failed is all NaN
            warnings.simplefilter("ignore", RuntimeWarning)
            lo, mid, hi = np.nanpercentile(err, [_BAND[0], 50, _BAND[1]], axis=1)
        ax.fill_between(t, lo, hi, color="#9fb3e0", alpha=0.6, lw=0,
                        label=f"{_BAND[0]}-{_BAND[1]} % of the {m} robots")
        ax.plot(t, mid, color="#2857c8", lw=1.3, label="median robot")
        worst = worst_robot(err)
        if worst >= 0:
            ax.plot(t, err[:, worst], color="#b4460f", lw=1.0, label=f"robot {worst} (the worst)")
    _events(ax, report)
    ax.set_xlabel("time [s]")
    ax.set_ylabel("distance from the plan [units]")
    ax.set_title("Tracking error per robot" if m <= _ROBOT_LINES else
                 f"Tracking error of {m} robots: median, {_BAND[0]}-{_BAND[1]} % band, worst robot")
    ax.set_ylim(bottom=0.0)
    ax.grid(alpha=0.3)
    _, labels = ax.get_legend_handles_labels()
    if labels:
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8, frameon=False,
                  ncols=1 if len(labels) <= 10 else 2)
    return fig


def _plot_dict(ident: str, title: str, fig) -> dict:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=_DPI)
    w, h = (int(round(v)) for v in fig.get_size_inches() * _DPI)
    return {"id": ident, "title": title, "width": w, "height": h,
            "uri": "data:image/png;base64," + base64.b64encode(buf.getvalue()).decode("ascii")}


# ----------------------------------------------------------------------------
# the template
