"""Pictures of a sweep (matplotlib, no display): (g, q) heatmaps and contact rates against settings."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ..output.media import atomic_path
from .robustness import RobustCell, is_number, setting_keys
from .summary import num_cell, pct, settings_text, value_text

if TYPE_CHECKING:
    from .summary import _Cell

__all__ = ["contact_plot", "heatmap"]


def heatmap(path: Path, title: str, cells: list[_Cell]) -> None:
    """Two panels over (g, q): success rate and median planning time; ``title`` above them."""
    from matplotlib import colormaps
    from matplotlib.colors import LogNorm, Normalize
    from matplotlib.figure import Figure

    fixed = [c for c in cells if c.mode == "fixed"]
    gs = sorted({c.g for c in fixed})
    qs = sorted({c.q for c in fixed})
    rate = np.full((len(gs), len(qs)), np.nan)
    med = np.full((len(gs), len(qs)), np.nan)
    for c in fixed:
        i, j = gs.index(c.g), qs.index(c.q)
        rate[i, j] = c.rate
        med[i, j] = np.nan if c.median_s is None else c.median_s
    fig = Figure(figsize=(4.2 + 1.6 * len(qs), 2.6 + 0.45 * len(gs)), layout="constrained")
    axes = fig.subplots(1, 2)
    finite = med[np.isfinite(med)]
    if finite.size and finite.min() > 0 and finite.max() / finite.min() > 10:
        time_norm = LogNorm(finite.min(), finite.max())
    else:
        time_norm = Normalize(*(finite.min(), finite.max()) if finite.size else (0, 1))
    panels = (
        (axes[0], rate, "RdYlGn", Normalize(0, 1), "success rate", lambda v: f"{100 * v:.0f}%"),
        (axes[1], med, "viridis", time_norm, "median planning time [s]", num_cell),
    )
    for ax, values, cmap_name, norm, name, fmt in panels:
        cmap = colormaps[cmap_name].with_extremes(bad="#d0d0d0")
        im = ax.imshow(np.ma.masked_invalid(values), cmap=cmap, norm=norm, origin="lower", aspect="auto")
        for i in range(len(gs)):
            for j in range(len(qs)):
                v = values[i, j]
                ax.text(j, i, fmt(v) if np.isfinite(v) else "no plan", ha="center", va="center", fontsize=9,
                        bbox={"boxstyle": "round,pad=0.15", "fc": "white", "alpha": 0.65, "lw": 0})
        ax.set_xticks(range(len(qs)), [str(q) for q in qs])
        ax.set_yticks(range(len(gs)), [str(g) for g in gs])
        ax.set_xlabel("q (connection attempts per pair of graphs)")
        ax.set_ylabel("g (pebble graphs)")
        ax.set_title(name, fontsize=10)
        fig.colorbar(im, ax=ax, shrink=0.9)
    auto = next((c for c in cells if c.mode == "auto"), None)
    auto_text = (f"; auto: {pct(auto.found, auto.runs)} found, median {num_cell(auto.median_s)} s"
                 if auto else "")
    fig.suptitle(title + auto_text, fontsize=10)
    _save(fig, path)


def contact_plot(path: Path, title: str, cells: list[RobustCell]) -> bool:
    """Contact rate against each swept value, one line per combination of the other settings.

    One panel per key with at least two values; error bars are the 95 %
    Wilson intervals.  Returns False (and writes nothing) when no key has
    two values.
    """
    from matplotlib.figure import Figure

    keys = [k for k in setting_keys(cells) if len({value_text(c.value(k)) for c in cells}) >= 2]
    if not keys:
        return False
    fig = Figure(figsize=(max(6.4, 5.2 * len(keys)), 4.1), layout="constrained")
    axes = np.atleast_1d(fig.subplots(1, len(keys)))
    for ax, key in zip(axes, keys):
        values = sorted({c.value(key) for c in cells}, key=lambda v: (not is_number(v), v if is_number(v) else 0,
                                                                      value_text(v)))
        numeric = all(is_number(v) for v in values)
        log = numeric and min(values) > 0 and max(values) / min(values) >= 20
        where = {value_text(v): (v if numeric else i) for i, v in enumerate(values)}
        lines: dict = {}
        for c in cells:
            others = tuple((k, v) for k, v in c.settings if k != key)
            lines.setdefault(others, []).append(c)
        for n, (others, line) in enumerate(sorted(lines.items(), key=lambda kv: settings_text(kv[0]))):
            line = [c for c in line if c.executed]
            line.sort(key=lambda c: where[value_text(c.value(key))])
            if not line:
                continue
            x = np.array([where[value_text(c.value(key))] for c in line], dtype=float)
            y = np.array([c.contacts / c.executed for c in line])
            lo = np.array([c.interval[0] for c in line])
            hi = np.array([c.interval[1] for c in line])
            x = _dodge(x, n - (len(lines) - 1) / 2, log)
            ax.errorbar(x, 100 * y, yerr=100 * np.clip(np.vstack([y - lo, hi - y]), 0, None), marker="o", capsize=3,
                        label=settings_text(others) or "all runs")
        if log:
            ax.set_xscale("log")
        ax.set_xlabel(key + (" (log scale)" if log else ""))
        ax.set_ylabel("contact rate [%] (95% Wilson interval)")
        ax.set_ylim(-3, 103)
        if not numeric:
            ax.set_xticks(range(len(values)), [value_text(v) for v in values])
        ax.grid(alpha=0.3)
        if len(lines) > 1:
            ax.legend(fontsize=8)
    fig.suptitle(title, fontsize=10)
    _save(fig, path)
    return True


def _dodge(x: np.ndarray, offset: float, log: bool) -> np.ndarray:
    """Shift a line a little sideways, so that error bars at one x do not hide each other."""
    if log:
        return x * 10 ** (0.006 * offset * max(np.log10(x.max() / x.min()), 1.0))
    span = float(np.ptp(x)) if x.size > 1 else 0.0
    return x + 0.006 * offset * (span or 1.0)


def _save(fig, path: Path) -> None:
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=110)
