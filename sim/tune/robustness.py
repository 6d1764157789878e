"""Robustness sweeps (``--set KEY=V1,V2,...``): contact rates with Wilson intervals, and margins needed.

A cell is one scenario under one combination of settings (at one g, q,
time limit and physics flag).  Its contact rate is the share of the runs
executed in physics (a plan was found and run) that saw at least one
contact, with a 95 % Wilson score interval; a cell with no executed run
has the interval [0, 1].  The "margin needed" for a combination of the
other settings is the smallest swept value of the margin key (by default
``robots.margin``) whose contact rate's upper bound is at most the bound
(1 % by default).  With n executed runs and no contact that upper bound
is 3.84 / (n + 3.84), so 1 % needs at least 381 runs per cell.
"""

from __future__ import annotations

import math
from collections import defaultdict
from dataclasses import dataclass
from statistics import median

from .blocks import Block, Bullets, Heading, Para, Table
from .summary import latest, num_cell, pct, settings_of, value_text

__all__ = ["Z95", "RobustCell", "margin_needed", "robustness_blocks", "robustness_cells", "wilson_interval"]

Z95 = 1.959963984540054
"""The standard normal quantile of a two-sided 95 % interval."""


def wilson_interval(k: int, n: int, z: float = Z95) -> tuple[float, float]:
    """The Wilson score interval of ``k`` successes in ``n`` trials; ``(0, 1)`` when ``n == 0``."""
    if isinstance(k, bool) or isinstance(n, bool) or not (0 <= k <= n):
        raise ValueError(f"need 0 <= k <= n, got k={k!r}, n={n!r}")
    if n == 0:
        return 0.0, 1.0
    p, z2 = k / n, z * z
    denom = 1 + z2 / n
    centre = (p + z2 / (2 * n)) / denom
    half = z * math.sqrt(p * (1 - p) / n + z2 / (4 * n * n)) / denom
    # rounding must not put the estimate itself outside (k = 0 and k = n touch the ends)
    return max(0.0, min(p, centre - half)), min(1.0, max(p, centre + half))


@dataclass(frozen=True)
class RobustCell:
    """The runs of one scenario under one combination of settings.

    executed: runs whose plan was executed in physics; contacts: of those,
    runs with at least one contact; low, high: the 95 % Wilson interval of
    contacts / executed; clearance: median of the physics runs' min
    clearance [units]; reached: runs where every robot reached a target.
    """

    settings: tuple[tuple[str, object], ...]
    runs: int
    found: int
    errors: int
    median_plan_s: float | None
    executed: int
    contacts: int
    reached: int
    clearance: float | None

    @property
    def interval(self) -> tuple[float, float]:
        return wilson_interval(self.contacts, self.executed)

    @property
    def rate(self) -> float | None:
        return self.contacts / self.executed if self.executed else None

    def value(self, key: str):
        return dict(self.settings).get(key)


def _robust_cell(settings, rows: list[dict]) -> RobustCell:
    executed = [r for r in rows if r["simulate"] and r.get("sim_contacts") is not None]
    times = [r["planning_time_s"] for r in rows if r["found"] and r.get("planning_time_s") is not None]
    clear = [r["sim_min_clearance"] for r in executed if r.get("sim_min_clearance") is not None]
    return RobustCell(
        settings=settings,
        runs=len(rows),
        found=sum(bool(r["found"]) for r in rows),
        errors=sum(r.get("error_type") not in (None, "NoPlanFound") for r in rows),
        median_plan_s=median(times) if times else None,
        executed=len(executed),
        contacts=sum(r["sim_contacts"] > 0 for r in executed),
        reached=sum(r.get("sim_reached") is True for r in executed),
        clearance=median(clear) if clear else None,
    )


def robustness_cells(rows: list[dict]) -> dict[tuple, list[RobustCell]]:
    """Per (scenario, time limit, physics, mode, g, q) with settings: one cell per combination.

    Combinations are in a stable order: each key's numbers ascending.
    """
    by: dict = defaultdict(lambda: defaultdict(list))
    for r in latest(rows):
        s = settings_of(r)
        if s:
            by[(r["scenario"], float(r["time_limit"]), r["simulate"], r["mode"], r["g"], r["q"])][s].append(r)
    out = {}
    for group in sorted(by, key=lambda g: (g[0], g[1], g[2], g[3] == "auto", g[4] or 0, g[5] or 0)):
        combos = by[group]
        out[group] = [_robust_cell(s, combos[s]) for s in sorted(combos, key=_order)]
    return out


def _order(settings) -> tuple:
    return tuple((0, v, "") if is_number(v) else (1, 0, value_text(v)) for _, v in settings)


def is_number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def setting_keys(cells: list[RobustCell]) -> list[str]:
    """The keys set in any of ``cells``, in the order of the options."""
    return list(dict.fromkeys(k for c in cells for k, _ in c.settings))


def margin_needed(cells: list[RobustCell], key: str = "robots.margin", bound: float = 0.01
                  ) -> list[dict] | None:
    """Per combination of the other settings, the smallest swept ``key`` whose upper bound is <= ``bound``.

    Returns ``None`` when ``key`` is not swept with numbers in ``cells``;
    else one entry per combination of the other keys: ``others`` (their
    settings), ``needed`` (the value, or ``None``: none of the swept values),
    ``high`` (the upper bound there), ``no_contact`` (the smallest value
    with no contact seen in its executed runs, or ``None``) and ``executed``
    (the fewest executed runs of a cell of the combination).
    """
    swept = [c for c in cells if is_number(c.value(key))]
    if not swept:
        return None
    by: dict = defaultdict(list)
    for c in swept:
        by[tuple((k, v) for k, v in c.settings if k != key)].append(c)
    out = []
    for others in sorted(by, key=_order):
        line = sorted(by[others], key=lambda c: c.value(key))
        ok = next((c for c in line if c.interval[1] <= bound), None)
        clean = next((c for c in line if c.executed and c.contacts == 0), None)
        out.append({"others": others, "needed": None if ok is None else ok.value(key),
                    "high": None if ok is None else ok.interval[1],
                    "no_contact": None if clean is None else clean.value(key),
                    "executed": min(c.executed for c in line)})
    return out


def _rate_text(c: RobustCell) -> str:
    if not c.executed:
        return "- (none executed)"
    low, high = c.interval
    return f"{100 * c.contacts / c.executed:.1f}% [{100 * low:.1f}%, {100 * high:.1f}%]"


def robustness_blocks(rows: list[dict], *, key: str = "robots.margin", bound: float = 0.01) -> list[Block]:
    """Markdown/HTML blocks of every robustness cell, and the margin-needed tables (``[]`` without settings)."""
    groups = robustness_cells(rows)
    if not groups:
        return []
    blocks: list[Block] = [Para(
        "One row per combination of settings.  The contact rate is the share of the runs executed in physics "
        "(a plan found and run) with at least one contact, with its 95 % Wilson score interval; min clearance "
        "is the physics run's gap between disc boundaries (negative: overlap).")]
    for (name, limit, physics, mode, g, q), cells in groups.items():
        keys = setting_keys(cells)
        setting = "auto" if mode == "auto" else f"g={g}, q={q}"
        seeds = {c.runs for c in cells}
        blocks += [Heading(3, f"{name}: {', '.join(keys)}"),
                   Para(f"{setting}, time limit {limit:g} s, {'/'.join(map(str, sorted(seeds)))} runs per cell"
                        + (", plans executed in the physics world." if physics else
                           " (planning only: sweep with --simulate for contact rates)."))]
        head = [*keys, "runs", "plan found", "median plan [s]", "errors"]
        if physics:
            head += ["executed", "contact rate [95% CI]", "median min clearance", "reached"]
        table = []
        for c in cells:
            values = dict(c.settings)
            cols = [value_text(values[k]) if k in values else "-" for k in keys]
            cols += [str(c.runs), pct(c.found, c.runs), num_cell(c.median_plan_s), str(c.errors)]
            if physics:
                cols += [str(c.executed), _rate_text(c),
                         "-" if c.clearance is None else f"{c.clearance:.4f}", pct(c.reached, c.executed)]
            table.append(cols)
        blocks.append(Table.of(head, table))
        needed = margin_needed(cells, key, bound) if physics else None
        if needed:
            blocks += _needed_blocks(needed, key, bound, [k for k in keys if k != key])
    return blocks


def _needed_blocks(needed: list[dict], key: str, bound: float, others: list[str]) -> list[Block]:
    head = [*others, f"{key} needed", "upper bound there", "smallest with no contact seen", "executed runs"]
    table = []
    for e in needed:
        values = dict(e["others"])
        cols = [value_text(values[k]) if k in values else "-" for k in others]
        cols += ["none of the swept values" if e["needed"] is None else value_text(e["needed"]),
                 "-" if e["high"] is None else f"{100 * e['high']:.2f}%",
                 "none" if e["no_contact"] is None else value_text(e["no_contact"]),
                 str(e["executed"])]
        table.append(cols)
    n_min = math.ceil(Z95 ** 2 * (1 - bound) / bound)
    return [
        Heading(4, f"{key} needed: the smallest swept value whose contact rate's 95 % upper bound is at most "
                   f"{100 * bound:g} %"),
        Table.of(head, table),
        Bullets((f"With n executed runs and no contact the upper bound is 3.84 / (n + 3.84): at most "
                 f"{100 * bound:g} % needs n >= {n_min} per cell.",)),
    ]
