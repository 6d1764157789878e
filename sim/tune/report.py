"""The files written beside a results file ``NAME.jsonl``, each replaced atomically.

- ``NAME.md``: the paper's tables (when the rows allow), the robustness
  tables and margins needed (sweeps with ``--set``), and the per-scenario
  tables;
- ``NAME-SCENARIO[-VARIANT].png``: heatmaps of success rate and median time
  over (g, q), for variants with at least two fixed settings;
- ``NAME-SCENARIO-contacts[-VARIANT].png``: contact rate against each swept
  value, for robustness sweeps with ``--simulate``;
- ``NAME.html``: one page with the same tables, the pictures (linked PNGs
  beside it) and a table of every run with the command that repeats it.
"""

from __future__ import annotations

import re
import shlex
from collections import defaultdict
from pathlib import Path

from ..output.media import atomic_path
from .blocks import Block, Heading, markdown
from .plots import contact_plot, heatmap
from .results import SUMMARY_MARK, read_results
from .robustness import robustness_blocks, robustness_cells
from .spec import TuneError
from .summary import (
    _groups,
    _info,
    _sort_key,
    latest,
    num_cell,
    paper_blocks,
    scenario_blocks,
    seeds_text,
    settings_of,
    settings_text,
    value_text,
)

__all__ = ["MAX_PAGE_RUNS", "write_summary"]

MAX_PAGE_RUNS = 5000
"""The runs table of the HTML page lists at most this many runs (the results file has them all)."""


def write_summary(results_path: str | Path, rows: list[dict] | None = None, *, key: str = "robots.margin",
                  bound: float = 0.01) -> tuple[str, list[Path]]:
    """Write ``NAME.md``, the PNGs and ``NAME.html`` beside ``NAME.jsonl``.

    Returns the Markdown and the paths written.  ``rows`` default to the
    file's rows; ``key`` and ``bound`` choose the margin-needed tables (see
    :mod:`sim.tune.robustness`).
    """
    results_path = Path(results_path)
    rows = read_results(results_path) if rows is None else rows
    if not rows:
        raise TuneError(f"{results_path}: holds no result rows")
    sections = []
    paper = paper_blocks(rows)
    if paper:
        sections.append(("paper", "The paper's Tables II and III, reproduced", paper))
    robust = robustness_blocks(rows, key=key, bound=bound)
    if robust:
        sections.append(("robustness", "Robustness", robust))
    sections.append(("scenarios", "Per scenario", scenario_blocks(rows)))
    blocks: list[Block] = [Heading(1, f"Tuning sweep: {results_path.name}")]
    for _, title, body in sections:
        blocks += [Heading(2, title), *body]
    text = markdown(blocks)
    md = results_path.with_suffix(".md")
    with atomic_path(md) as tmp:
        tmp.write_text(f"{SUMMARY_MARK}\n{text}", encoding="utf-8")
    images = _heatmaps(results_path, rows) + _contact_plots(results_path, rows)
    page = _write_page(results_path, rows, sections, images)
    return text, [md, *(p for p, _ in images), page]


def _name_part(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9._=+-]+", "_", text)


def _heatmaps(results_path: Path, rows: list[dict]) -> list[tuple[Path, str]]:
    info = _info(rows)
    groups = _groups(rows)
    variants = defaultdict(list)
    for v in groups:
        variants[v[0]].append(v)
    out = []
    for name, vs in variants.items():
        for v in vs:
            cells = groups[v]
            if sum(c.mode == "fixed" for c in cells) < 2:
                continue  # one setting: the table says it all
            _, settings, limit, physics = v
            suffix = "" if len(vs) == 1 else f"-t{limit:g}" + ("-physics" if physics else "") + "".join(
                f"-{_name_part(k)}={_name_part(value_text(x))}" for k, x in settings)
            png = results_path.with_name(f"{results_path.stem}-{name}{suffix}.png")
            d = info[name]
            seeds = {r["seed"] for r in rows if r["scenario"] == name}
            title = (f"{name}: {d['robots']} robots, {d['start']} -> {d['target']}\n"
                     f"{seeds_text(seeds)}, time limit {limit:g} s{', physics' if physics else ''}"
                     + (f"; {settings_text(settings)}" if settings else ""))
            heatmap(png, title, cells)
            out.append((png, f"{name}: success rate and median planning time over (g, q), time limit {limit:g} s"
                        + (", physics" if physics else "") + (f", {settings_text(settings)}" if settings else "")))
    return out


def _contact_plots(results_path: Path, rows: list[dict]) -> list[tuple[Path, str]]:
    groups = {g: cells for g, cells in robustness_cells(rows).items() if g[2]}
    per_scenario = defaultdict(int)
    for g in groups:
        per_scenario[g[0]] += 1
    out = []
    for (name, limit, _, mode, g, q), cells in groups.items():
        setting = "auto" if mode == "auto" else f"g={g}, q={q}"
        suffix = "" if per_scenario[name] == 1 else f"-t{limit:g}-" + ("auto" if mode == "auto" else f"g{g}-q{q}")
        png = results_path.with_name(f"{results_path.stem}-{name}-contacts{suffix}.png")
        runs = sorted({c.executed for c in cells})
        title = (f"{name}: runs with a contact\n{setting}, time limit {limit:g} s, "
                 f"{'/'.join(map(str, runs))} executed runs per point")
        if contact_plot(png, title, cells):
            out.append((png, f"{name}: contact rate against each swept value ({setting}, time limit {limit:g} s)"))
    return out


def _write_page(results_path: Path, rows: list[dict], sections, images) -> Path:
    from jinja2 import Environment, PackageLoader, select_autoescape
    from markupsafe import Markup

    env = Environment(loader=PackageLoader("sim.tune", "templates"), autoescape=select_autoescape(["j2", "html"]),
                      trim_blocks=True, lstrip_blocks=True)
    runs = sorted(latest(rows), key=lambda r: (r["scenario"], _sort_key(settings_of(r)), float(r["time_limit"]),
                                               r["simulate"], r["mode"] == "auto", r["g"] or 0, r["q"] or 0,
                                               r["seed"]))
    shown = runs[:MAX_PAGE_RUNS]
    scenarios = sorted({r["scenario"] for r in runs})
    seeds = {r["seed"] for r in runs}
    meta = (f"{len(runs)} runs of {len(scenarios)} scenario{'s' if len(scenarios) != 1 else ''} "
            f"({', '.join(scenarios[:6])}{', ...' if len(scenarios) > 6 else ''}), {seeds_text(seeds)}; "
            f"{sum(bool(r['found']) for r in runs)} found a plan.")
    html = env.get_template("index.html.j2").render(
        mark=Markup(SUMMARY_MARK),
        title=f"Tuning sweep: {results_path.name}",
        meta=meta,
        results_name=results_path.name,
        sections=[{"anchor": a, "title": t, "blocks": b} for a, t, b in sections],
        images=[{"src": p.name, "caption": caption} for p, caption in images],
        run_head=_RUN_HEAD,
        runs=[_run(r) for r in shown],
        runs_left_out=len(runs) - len(shown),
    )
    page = results_path.with_suffix(".html")
    with atomic_path(page) as tmp:
        tmp.write_text(html, encoding="utf-8")
    return page


_RUN_HEAD = ("scenario", "settings", "g", "q", "seed", "plan", "planning [s]", "steps", "contacts",
             "sim min clearance", "reached", "error", "worker")


def _run(r: dict) -> dict:
    def cell(text, num=False, error=False):
        return {"text": text, "num": num, "error": error}

    auto = r["mode"] == "auto"
    sim = r["simulate"] and r.get("sim_contacts") is not None
    cells = [
        cell(r["scenario"]), cell(settings_text(settings_of(r)) or "-"),
        cell("auto" if auto else str(r["g"])), cell("auto" if auto else str(r["q"])), cell(str(r["seed"]), True),
        cell("found" if r["found"] else "no plan"), cell(num_cell(r.get("planning_time_s")), True),
        cell("-" if r.get("steps") is None else str(r["steps"]), True),
        cell(str(r["sim_contacts"]) if sim else "-", True),
        cell(f"{r['sim_min_clearance']:.4f}" if sim and r.get("sim_min_clearance") is not None else "-", True),
        cell(("yes" if r.get("sim_reached") else "no") if sim else "-"),
        cell(f"{r['error_type']}: {r.get('error') or ''}"[:300] if r.get("error_type") else "", error=True),
        cell(r.get("worker") or r.get("host") or "-"),
    ]
    ok = bool(r["found"]) and (not sim or (r.get("sim_ok") is True))
    return {"cells": cells, "ok": ok, "command": _command(r)}


def _command(r: dict) -> str:
    """``swarmform run`` with the run's file, seed and settings (g, q and time limit as settings)."""
    sets = dict(settings_of(r))
    sets["planner.g"] = "auto" if r["mode"] == "auto" else r["g"]
    sets["planner.q"] = "auto" if r["mode"] == "auto" else r["q"]
    sets["planner.time_limit"] = r["time_limit"]
    parts = ["swarmform", "run", str(r.get("scenario_file") or r["scenario"]), "--seed", str(r["seed"])]
    for k, v in sets.items():
        parts += ["--set", f"{k}={value_text(v)}"]
    return shlex.join(parts)
