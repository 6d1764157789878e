"""Tables of a sweep: per scenario and setting, and the paper's Tables II and III.

Per scenario, time limit, physics and ``--set`` settings, one table of the
(g, q) settings: runs, success rate, median and 90th percentile planning
time of the successful runs (physics ok with ``--simulate``), and errors
(runs that raised, hit their watchdog or lost their worker); whether auto
beats the best fixed setting; and the comparison with the paper's tables
when the rows allow it.
"""

from __future__ import annotations

import math
from collections import Counter, defaultdict
from dataclasses import dataclass

import numpy as np

from .blocks import Block, Bullets, Heading, Para, Table, markdown

__all__ = ["paper_blocks", "paper_table", "scenario_blocks", "settings_text", "summarize", "value_text"]


@dataclass(frozen=True)
class _Cell:
    """The runs of one (g, q) setting of one scenario variant."""

    mode: str
    g: int | None
    q: int | None
    runs: int
    found: int
    errors: int
    sim_ok: int | None
    median_s: float | None
    p90_s: float | None
    reasons: tuple[tuple[str, int], ...]

    @property
    def rate(self) -> float:
        return self.found / self.runs if self.runs else 0.0

    @property
    def label(self) -> str:
        return "auto" if self.mode == "auto" else f"g={self.g}, q={self.q}"


def _cell(rows: list[dict]) -> _Cell:
    times = [r["planning_time_s"] for r in rows if r["found"] and r.get("planning_time_s") is not None]
    reasons = Counter(f"{r['error_type']}: {r.get('error') or ''}" for r in rows
                      if r.get("error_type") not in (None, "NoPlanFound"))
    simulated = [r for r in rows if r["simulate"]]
    first = rows[0]
    return _Cell(
        mode=first["mode"],
        g=first["g"],
        q=first["q"],
        runs=len(rows),
        found=sum(bool(r["found"]) for r in rows),
        errors=sum(reasons.values()),
        sim_ok=sum(r.get("sim_ok") is True for r in simulated) if simulated else None,
        median_s=float(np.median(times)) if times else None,
        p90_s=float(np.percentile(times, 90)) if times else None,
        reasons=tuple(reasons.most_common()),
    )


def settings_of(row: dict) -> tuple:
    """A row's settings as ``((key, value), ...)`` in the order of the options."""
    return tuple((row.get("settings") or {}).items())


def _variant(row: dict) -> tuple:
    return (row["scenario"], tuple(sorted(settings_of(row), key=lambda kv: kv[0])), float(row["time_limit"]),
            row["simulate"])


def latest(rows: list[dict]) -> list[dict]:
    """One row per run (a later row of the same run replaces an earlier one), in first-seen order."""
    by: dict = {}
    for r in rows:
        by[(_variant(r), r["mode"], r["g"], r["q"], r["seed"])] = r
    return list(by.values())


def _groups(rows: list[dict]) -> dict[tuple, list[_Cell]]:
    """Per (scenario, settings, time limit, physics): one cell per (g, q), fixed first, then auto."""
    by: dict = defaultdict(lambda: defaultdict(list))
    for r in latest(rows):
        by[_variant(r)][(r["mode"], r["g"], r["q"])].append(r)
    out = {}
    for variant in sorted(by, key=lambda v: (v[0], _sort_key(v[1]), v[2], v[3])):
        cells = by[variant]
        order = sorted(cells, key=lambda s: (s[0] == "auto", s[1] or 0, s[2] or 0))
        out[variant] = [_cell(cells[s]) for s in order]
    return out


def _info(rows: list[dict]) -> dict[str, dict]:
    """Per scenario: robots, formations, file, seeds and paper reference (from its last row)."""
    out: dict[str, dict] = {}
    for r in rows:
        d = out.setdefault(r["scenario"], {"seeds": set()})
        d.update({k: r.get(k) for k in ("robots", "start", "target", "scenario_file", "paper_table",
                                        "paper_row", "paper_time_s", "paper_g", "paper_q")})
        d["seeds"].add(r["seed"])
    return out


def _best_fixed(cells: list[_Cell]) -> _Cell | None:
    fixed = [c for c in cells if c.mode == "fixed"]
    if not fixed:
        return None
    return max(fixed, key=lambda c: (c.rate, -(c.median_s if c.median_s is not None else math.inf)))


def _auto_verdict(cells: list[_Cell]) -> str | None:
    """Whether auto beats the best fixed setting: success rate first, then median time."""
    auto = next((c for c in cells if c.mode == "auto"), None)
    best = _best_fixed(cells)
    if auto is None or best is None:
        return None
    a = f"auto {pct(auto.found, auto.runs)} found, median {_sec(auto.median_s)}"
    b = f"best fixed ({best.label}) {pct(best.found, best.runs)} found, median {_sec(best.median_s)}"
    if auto.rate != best.rate:
        winner = "auto beats the best fixed setting" if auto.rate > best.rate else \
            "the best fixed setting beats auto"
        return f"{winner} on success rate: {a}; {b}."
    if auto.median_s is None and best.median_s is None:
        return f"neither auto nor any fixed setting found a plan: {a}; {b}."
    if auto.median_s == best.median_s:
        return f"auto ties with the best fixed setting: {a}; {b}."
    winner = "auto beats the best fixed setting" if auto.median_s < best.median_s else \
        "the best fixed setting beats auto"
    return f"{winner} on median time (same success rate): {a}; {b}."


def pct(k: int, n: int) -> str:
    return f"{100 * k / n:.0f}% ({k}/{n})" if n else "-"


def _sec(v: float | None) -> str:
    if v is None:
        return "-"
    return f"{v:.3f} s" if v < 10 else f"{v:.1f} s"


def num_cell(v: float | None) -> str:
    if v is None:
        return "-"
    return f"{v:.3f}" if v < 10 else f"{v:.1f}"


def seeds_text(seeds: set[int]) -> str:
    s = sorted(seeds)
    if s == list(range(s[0], s[-1] + 1)):
        return f"seeds {s[0]}..{s[-1]} ({len(s)})" if len(s) > 1 else f"seed {s[0]}"
    return f"{len(s)} seeds"


def value_text(v) -> str:
    """A setting's value as it would be written after ``--set KEY=``."""
    if v is None:
        return "null"
    if isinstance(v, bool):
        return "true" if v else "false"
    return repr(v) if isinstance(v, float) else str(v)


def settings_text(settings) -> str:
    items = settings.items() if isinstance(settings, dict) else settings
    return ", ".join(f"{k}={value_text(v)}" for k, v in items)


def _sort_key(settings) -> tuple:
    """Settings in a stable order: numbers ascending, then text."""
    return tuple((k, (0, v, "") if isinstance(v, (int, float)) and not isinstance(v, bool)
                  else (1, 0, value_text(v))) for k, v in settings)


def scenario_blocks(rows: list[dict]) -> list[Block]:
    """Per scenario, one table of its (g, q) settings per variant, and auto against the best fixed one.

    A variant with ``--set`` settings and a single (g, q) setting is left to
    the robustness tables, which hold the same numbers per setting.
    """
    info = _info(rows)
    groups = _groups(rows)
    blocks: list[Block] = [Para(
        "Planning times are wall-clock seconds of the successful runs, on the machines that ran them; "
        "each seed draws its own obstacles and placements where the scenario leaves them random.")]
    for name in dict.fromkeys(v[0] for v in groups):
        d = info[name]
        blocks += [Heading(3, name), Para(f"{d['robots']} robots, {d['start']} -> {d['target']} "
                                          f"({d['scenario_file']}).")]
        shown = 0
        for variant, cells in groups.items():
            scen, settings, limit, physics = variant
            if scen != name or (settings and len(cells) < 2):
                continue
            shown += 1
            seeds = {r["seed"] for r in rows if _variant(r) == variant}
            where = f"; settings {settings_text(settings)}" if settings else ""
            blocks.append(Para(f"{seeds_text(seeds)}, time limit {limit:g} s{where}"
                               + (", plans executed in the physics world." if physics else ".")))
            head = ["g", "q", "runs", "found", "median [s]", "p90 [s]"] + (["physics ok"] if physics else [])
            table = []
            for c in cells:
                cols = ["auto" if c.mode == "auto" else str(c.g), "auto" if c.mode == "auto" else str(c.q),
                        str(c.runs), pct(c.found, c.runs), num_cell(c.median_s), num_cell(c.p90_s)]
                if physics:
                    cols.append(pct(c.sim_ok or 0, c.runs))
                table.append([*cols, str(c.errors)])
            blocks.append(Table.of([*head, "errors"], table))
            verdict = _auto_verdict(cells)
            if verdict:
                blocks.append(Para(f"Auto vs fixed: {verdict}"))
            reasons = Counter()
            for c in cells:
                reasons.update(dict(c.reasons))
            if reasons:
                blocks.append(Bullets(tuple(f"error in {n} run(s): {text}" for text, n in reasons.most_common(3))))
        if not shown:
            blocks.append(Para("One (g, q) setting per combination of settings: see the robustness tables."))
    return blocks


def summarize(rows: list[dict]) -> str:
    """Markdown: per scenario, one table of its settings, and auto against the best fixed setting."""
    return markdown(scenario_blocks(rows))


def paper_blocks(rows: list[dict]) -> list[Block] | None:
    """The paper's Tables II and III against this implementation (fixed and auto), as blocks.

    ``None`` when no row is from a paper scenario at the paper's g and q or
    in auto mode.  Rows with ``--set`` settings are left out.
    """
    info = _info(rows)
    entries = []
    for (name, settings, limit, physics), cells in _groups(rows).items():
        d = info[name]
        if d["paper_table"] is None or settings:
            continue
        fixed = next((c for c in cells if c.mode == "fixed" and (c.g, c.q) == (d["paper_g"], d["paper_q"])),
                     None)
        auto = next((c for c in cells if c.mode == "auto"), None)
        if fixed is None and auto is None:
            continue
        entries.append((d, limit, physics, fixed, auto))
    if not entries:
        return None
    entries.sort(key=lambda e: ({"II": 2, "III": 3}.get(e[0]["paper_table"], 9), e[0]["paper_row"], e[1], e[2]))
    limits = sorted({e[1] for e in entries})
    several = len({(e[1], e[2]) for e in entries}) > 1
    seeds = set().union(*(e[0]["seeds"] for e in entries))
    head = ["table", "row", "m", "start -> target", "paper (g, q)", "paper time [s]",
            "fixed: success", "fixed: median [s]", "fixed: paper/ours",
            "auto: success", "auto: median [s]", "auto: paper/ours"]
    if several:
        head[6:6] = ["time limit [s]", "physics"]
    table = []
    for d, limit, physics, fixed, auto in entries:
        cols = [str(d["paper_table"]), str(d["paper_row"]), str(d["robots"]), f"{d['start']} -> {d['target']}",
                f"({d['paper_g']}, {d['paper_q']})", f"{d['paper_time_s']:.3f}"]
        if several:
            cols += [f"{limit:g}", "yes" if physics else "no"]
        for c in (fixed, auto):
            if c is None:
                cols += ["not run", "-", "-"]
            else:
                ratio = d["paper_time_s"] / c.median_s if c.median_s else None
                cols += [pct(c.found, c.runs), num_cell(c.median_s), f"{ratio:.1f}" if ratio else "-"]
        table.append(cols)
    limit_text = ", ".join(f"{v:g}" for v in limits)
    return [
        Table.of(head, table),
        Para(f"Ours: {seeds_text(seeds)} per row and mode, planning time limit {limit_text} s; median "
             "planning time of the successful runs.  Fixed runs use the paper's g and q for the row; auto "
             "runs choose g and q themselves.  The paper reports one time per row; each of our seeds draws "
             "its own random obstacles and placements, so each is another instance of the row's scenario."),
        Para("The paper's hardware is unknown, so the ratios (paper time / our median; above 1 means ours "
             "is faster) compare implementations on different machines and are rough."),
    ]


def paper_table(rows: list[dict]) -> str | None:
    """Markdown: the paper's Tables II and III against this implementation (fixed and auto)."""
    blocks = paper_blocks(rows)
    return None if blocks is None else markdown(blocks).rstrip()
