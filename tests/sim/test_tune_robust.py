"""Robustness sweeps: --set parsing and applying, Wilson intervals, margins needed, plots and the page."""

from __future__ import annotations

import doctest
import importlib.resources
import json
import math
from pathlib import Path

import pytest

import sim.scenario.overrides
from sim.cli import main
from sim.scenario import ScenarioError, read_scenario
from sim.scenario.overrides import OverrideError, apply_overrides, combinations, parse_set
from sim.tune import (
    grid,
    margin_needed,
    read_results,
    read_variants,
    robustness_blocks,
    robustness_cells,
    sweep,
    wilson_interval,
    write_summary,
)
from sim.tune.blocks import markdown
from sim.tune.plots import contact_plot
from sim.tune.results import SUMMARY_MARK

ROOT = Path(__file__).resolve().parents[2]
FIG2 = ROOT / "scenarios" / "paper" / "fig2-random-to-C.yaml"


def _cli(argv, capsys) -> tuple[int, str, str]:
    try:
        code = main([str(a) for a in argv])
    except SystemExit as exc:
        code = exc.code
    out, err = capsys.readouterr()
    return code, out, err


# ----------------------------------------------------------------------------
# --set: parsing and applying


def test_the_module_examples_run():
    assert doctest.testmod(sim.scenario.overrides).failed == 0


@pytest.mark.parametrize(("text", "values"), [
    ("robots.margin=0.1,0.2,0.4", (0.1, 0.2, 0.4)),
    ("sim.noise.position=0,0.02,0.05", (0, 0.02, 0.05)),
    ("sim.kp=1e-3, 2E2", (0.001, 200.0)),          # YAML 1.1 reads 1e-3 as text; here it is a number
    ("planner.g=auto,2", ("auto", 2)),
    ("planner.concurrent=true,false", (True, False)),
    ("render.speedup=null,4", (None, 4)),
    ("obstacles.0.circle.radius=3", (3,)),
])
def test_set_values_are_yaml_scalars(text, values):
    o = parse_set(text)
    assert o.key == text.split("=")[0] and o.values == values
    assert [type(v) for v in o.values] == [type(v) for v in values]


@pytest.mark.parametrize(("text", "words"), [
    ("robots.margin", "must be KEY=VALUE"),
    ("robots..margin=1", "dotted path"),
    ("=1", "dotted path"),
    ("robots.margin=0.1,,0.2", "a value is empty"),
    ("robots.margin=0.1,0.1", "given twice"),
    ("robots.margin=[1,2]", "YAML scalars"),
    ("robots.margin={a: 1}", "YAML scalars"),
    ("robots.margin=.inf", "not finite"),
    ("robots.margin='open", "robots.margin"),
])
def test_bad_set_options_name_the_option(text, words):
    with pytest.raises(OverrideError) as info:
        parse_set(text)
    message = str(info.value)
    assert message.startswith("--set") and words in message and "\n" not in message


def test_combinations_make_a_grid_and_refuse_a_key_twice():
    combos = combinations([parse_set("a.x=1,2"), parse_set("b=p,q,r")])
    assert combos == [{"a.x": 1, "b": "p"}, {"a.x": 1, "b": "q"}, {"a.x": 1, "b": "r"},
                      {"a.x": 2, "b": "p"}, {"a.x": 2, "b": "q"}, {"a.x": 2, "b": "r"}]
    assert combinations([]) == [{}]
    with pytest.raises(OverrideError, match="--set a.x: is given twice"):
        combinations([parse_set("a.x=1"), parse_set("a.x=2")])


def test_apply_overrides_sets_paths_and_keeps_the_document():
    doc = {"robots": {"margin": 0.1}, "sim": None, "obstacles": [{"circle": {"radius": 2}}], "seed": 3}
    out = apply_overrides(doc, {"robots.margin": 0.3, "sim.kp": 50, "planner.g": 2, "obstacles.0.circle.radius": 1})
    assert out == {"robots": {"margin": 0.3}, "sim": {"kp": 50}, "obstacles": [{"circle": {"radius": 1}}],
                   "seed": 3, "planner": {"g": 2}}
    assert doc["robots"]["margin"] == 0.1 and doc["sim"] is None  # the original is not changed
    with pytest.raises(OverrideError, match="--set seed.x: seed is the number 3, not a mapping"):
        apply_overrides(doc, {"seed.x": 1})
    with pytest.raises(OverrideError, match="--set obstacles.5.circle: obstacles is a list of 1"):
        apply_overrides(doc, {"obstacles.5.circle": 1})


def test_read_scenario_applies_overrides_and_blames_the_option():
    sc = read_scenario(FIG2, overrides={"robots.margin": 0.3, "sim.kp": 50, "planner.time_limit": 5})
    assert (sc.margin, sc.sim.kp, sc.planner.time_limit) == (0.3, 50, 5)
    assert read_scenario(FIG2).margin == 0.1
    with pytest.raises(ScenarioError) as info:
        read_scenario(FIG2, overrides={"sim.nosie.position": 0.1})
    assert str(info.value).startswith("--set sim.nosie.position: unknown key 'nosie' in sim; allowed here: mass, kp")
    with pytest.raises(ScenarioError, match=r"^--set robots.margin: must be a number in \[0, 100\], got -1$"):
        read_scenario(FIG2, overrides={"robots.margin": -1})
    with pytest.raises(ScenarioError, match=r"^--set robots: must be a mapping"):
        read_scenario(FIG2, overrides={"robots": 1})
    with pytest.raises(ScenarioError, match=r"^--set colour: unknown key 'colour'; allowed here"):
        read_scenario(FIG2, overrides={"colour": "red"})


def test_run_takes_set_options(tmp_path, capsys):
    code, out, err = _cli(["run", FIG2, "--no-render", "--out", tmp_path, "--set", "robots.margin=0.3",
                           "--set", "planner.g=1", "--set", "planner.q=20"], capsys)
    assert code == 0, err
    report = json.loads((tmp_path / "fig2-random-to-C.json").read_text())
    assert report["settings"] == {"robots.margin": 0.3, "planner.g": 1, "planner.q": 20}
    assert report["plan"]["min_clearance"] >= 0.3 and (report["plan"]["g"], report["plan"]["q"]) == (1, 20)
    for argv, words in ((["--set", "sim.nosie.position=0.1"], "--set sim.nosie.position: unknown key 'nosie'"),
                        (["--set", "robots.margin=0.1,0.2"], "--set robots.margin: must be a number"),
                        (["--set", "robots.margin"], "--set robots.margin: must be KEY=VALUE")):
        code, _, err = _cli(["run", FIG2, "--no-render", "--out", tmp_path / "bad", *argv], capsys)
        assert code == 2 and len(err.splitlines()) == 1 and words in err, err
        assert not (tmp_path / "bad").exists()


def test_tune_refuses_a_bad_set_before_running(tmp_path, capsys):
    out = tmp_path / "r.jsonl"
    code, _, err = _cli(["tune", FIG2, "--set", "robots.margin=0.1,-1", "-o", out], capsys)
    assert code == 2 and err.strip() == "swarmform: error: --set robots.margin: must be a number in [0, 100], got -1"
    assert not out.exists()


# ----------------------------------------------------------------------------
# a robustness sweep end to end (physics with today's fields)


def test_a_set_sweep_with_physics_records_settings_and_summarises(tmp_path, capsys):
    """force_limit 0.2 (per unit mass) makes the robots lag and collide; 200 (the default) does not."""
    out = tmp_path / "rob.jsonl"
    argv = ["tune", FIG2, "--g", "1", "--q", "20", "--set", "sim.force_limit=0.2,200", "--set",
            "robots.margin=0.1,0.3", "--seeds", "1", "--simulate", "--workers", "2", "-o", out]
    code, printed, err = _cli(argv, capsys)
    assert code == 0, err
    rows = read_results(out)
    assert len(rows) == 4
    assert {(r["settings"]["sim.force_limit"], r["settings"]["robots.margin"]) for r in rows} == {
        (f, m) for f in (0.2, 200) for m in (0.1, 0.3)}
    assert all(list(r["settings"]) == ["sim.force_limit", "robots.margin"] for r in rows)
    assert all(r["min_clearance"] >= r["settings"]["robots.margin"] - 1e-9 for r in rows)
    weak = [r for r in rows if r["settings"]["sim.force_limit"] == 0.2]
    assert all(r["sim_contacts"] > 0 and r["sim_ok"] is False for r in weak)
    assert all(r["sim_contacts"] == 0 for r in rows if r["settings"]["sim.force_limit"] == 200)
    assert all(r["worker"].startswith("local:") for r in rows)
    md = out.with_suffix(".md").read_text()
    assert md.startswith(SUMMARY_MARK + "\n")  # the mark that lets a later summary replace it
    md = md.removeprefix(SUMMARY_MARK + "\n")
    assert md.rstrip() in printed
    assert "## Robustness" in md and "### fig2-random-to-C: sim.force_limit, robots.margin" in md
    assert "| 200 | 0.1 | 1 | 100% (1/1) |" in md and "| 0.0% [0.0%, 79.3%] |" in md
    assert "| 0.2 | 0.1 | 1 | 100% (1/1) |" in md and "| 100.0% [20.7%, 100.0%] |" in md
    assert "robots.margin needed: the smallest swept value" in md
    assert "| 200 | none of the swept values | - | 0.1 | 1 |" in md
    assert "| 0.2 | none of the swept values | - | none | 1 |" in md
    png = tmp_path / "rob-fig2-random-to-C-contacts.png"
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    html = out.with_suffix(".html").read_text()
    assert 'src="rob-fig2-random-to-C-contacts.png"' in html and "sim.force_limit=0.2, robots.margin=0.3" in html
    # the settings are part of each run's key: the same command computes nothing, a new value only its runs
    before = out.read_bytes()
    code, printed, _ = _cli(argv, capsys)
    assert code == 0 and "0 runs computed" in printed and out.read_bytes() == before
    variants = read_variants([FIG2], combinations([parse_set("sim.force_limit=0.2,200"),
                                                   parse_set("robots.margin=0.1,0.3,0.5")]))
    result = sweep(grid(variants, g=[1], q=[20], seeds=[0], simulate=True), out, workers=2)
    assert (result.skipped, result.computed) == (4, 2) and out.read_bytes().startswith(before)


# ----------------------------------------------------------------------------
# statistics on synthetic rows


@pytest.mark.parametrize(("k", "n", "low", "high"), [
    # Newcombe (1998), Statistics in Medicine 17:857-872, Table I, method 3 (Wilson score)
    (81, 263, 0.2553, 0.3662),
    (15, 148, 0.0624, 0.1605),
    (0, 20, 0.0, 0.1611),
    (1, 29, 0.0061, 0.1718),
])
def test_wilson_interval_matches_published_values(k, n, low, high):
    lo, hi = wilson_interval(k, n)
    assert lo == pytest.approx(low, abs=5e-5) and hi == pytest.approx(high, abs=5e-5)


def test_wilson_interval_edges():
    assert wilson_interval(0, 0) == (0.0, 1.0)
    lo, hi = wilson_interval(5, 5)
    assert hi == 1.0 and lo == pytest.approx(1 - 1.959963984540054 ** 2 / (5 + 1.959963984540054 ** 2))
    assert wilson_interval(0, 381)[1] <= 0.01 < wilson_interval(0, 380)[1]
    with pytest.raises(ValueError):
        wilson_interval(3, 2)
    for n in range(1, 400):
        for k in (0, 1, n // 2, n - 1, n):
            lo, hi = wilson_interval(k, n)
            assert 0 <= lo <= k / n <= hi <= 1, (k, n)


def _rows(noise, margin, runs, contacts, *, found=None, scenario="s"):
    """``runs`` simulated rows of one cell, the first ``contacts`` of them with a contact."""
    found = runs if found is None else found
    out = []
    for seed in range(runs):
        ok = seed < found
        out.append({
            "scenario": scenario, "scenario_file": f"{scenario}.yaml", "mode": "fixed", "g": 2, "q": 500,
            "seed": seed, "time_limit": 60.0, "simulate": True,
            "settings": {"sim.noise.position": noise, "robots.margin": margin},
            "robots": 11, "start": "line", "target": "phi", "paper_table": None, "found": ok,
            "planning_time_s": 0.5 if ok else None, "error_type": None if ok else "NoPlanFound",
            "error": None if ok else "no plan", "sim_contacts": (2 if seed < contacts else 0) if ok else None,
            "sim_reached": ok and seed >= contacts, "sim_ok": ok and seed >= contacts,
            "sim_min_clearance": (-0.01 if seed < contacts else margin) if ok else None,
        })
    return out


def test_margin_needed_on_synthetic_rows():
    rows = (_rows(0, 0.1, 381, 0) + _rows(0, 0.2, 381, 0)           # no noise: 0.1 suffices (0/381 < 1 %)
            + _rows(0.02, 0.1, 400, 12) + _rows(0.02, 0.2, 381, 0)  # noise 0.02: needs 0.2
            + _rows(0.05, 0.1, 400, 40) + _rows(0.05, 0.2, 380, 0))  # 0/380: upper bound 1.0005 %: not enough
    (group, cells), = robustness_cells(rows).items()
    assert group == ("s", 60.0, True, "fixed", 2, 500)
    needed = margin_needed(cells)
    assert [(e["others"], e["needed"], e["no_contact"], e["executed"]) for e in needed] == [
        ((("sim.noise.position", 0),), 0.1, 0.1, 381),
        ((("sim.noise.position", 0.02),), 0.2, 0.2, 381),
        ((("sim.noise.position", 0.05),), None, 0.2, 380)]
    assert needed[0]["high"] == pytest.approx(wilson_interval(0, 381)[1])
    text = markdown(robustness_blocks(rows))
    assert "| 0.05 | none of the swept values | - | 0.2 | 380 |" in text
    assert "| 0.02 | 0.2 | 1.00% | 0.2 | 381 |" in text
    assert "| 0.02 | 0.1 | 400 | 100% (400/400) | 0.500 | 0 | 400 | 3.0% [1.7%, 5.2%] | 0.1000 | 97% (388/400) |" \
        in text
    assert "needs n >= 381 per cell" in text
    # a looser bound: 5 % of the contact rate's upper bound
    assert [e["needed"] for e in margin_needed(cells, bound=0.05)] == [0.1, 0.2, 0.2]
    assert margin_needed(cells, key="sim.kp") is None


def test_runs_without_a_plan_are_not_executed_runs():
    rows = _rows(0, 0.4, 10, 0, found=0) + _rows(0, 0.1, 10, 3)
    cells = next(iter(robustness_cells(rows).values()))
    wide = next(c for c in cells if c.value("robots.margin") == 0.4)
    assert (wide.runs, wide.found, wide.executed, wide.interval) == (10, 0, 0, (0.0, 1.0))
    text = markdown(robustness_blocks(rows))
    assert "| 0 | 0.4 | 10 | 0% (0/10) | - | 0 | 0 | - (none executed) | - | - |" in text


def test_contact_plot_has_one_panel_per_swept_key(tmp_path):
    rows = [r for noise in (0, 0.02, 0.05) for m, k in ((0.1, 5), (0.2, 1), (0.4, 0))
            for r in _rows(noise, m, 20, min(20, k * (1 + int(noise * 100))))]
    cells = next(iter(robustness_cells(rows).values()))
    png = tmp_path / "contacts.png"
    assert contact_plot(png, "synthetic", cells)
    from matplotlib.image import imread

    height, width = imread(str(png)).shape[:2]
    assert width > 1.8 * height  # two panels side by side
    assert not contact_plot(tmp_path / "none.png", "one value", [c for c in cells if c.value("robots.margin") == 0.1
                                                                 and c.value("sim.noise.position") == 0])
    assert not (tmp_path / "none.png").exists()


# ----------------------------------------------------------------------------
# the page


def test_the_page_template_is_package_data():
    template = importlib.resources.files("sim.tune") / "templates" / "index.html.j2"
    assert template.is_file() and "run.command" in template.read_text()


def test_the_page_holds_tables_pictures_and_runs(tmp_path):
    rows = _rows(0, 0.1, 5, 1) + _rows(0, 0.2, 5, 0)
    rows[0]["error_type"], rows[0]["error"] = "RuntimeError", "<script>alert(1)</script>"
    path = tmp_path / "synthetic.jsonl"
    path.write_text("".join(json.dumps(r) + "\n" for r in rows))
    text, written = write_summary(path)
    assert [p.name for p in written] == ["synthetic.md", "synthetic-s-contacts.png", "synthetic.html"]
    html = (tmp_path / "synthetic.html").read_text()
    assert html.startswith("<!DOCTYPE html>") and html.count("<table") == 3  # robustness, margin needed, runs
    assert '<img src="synthetic-s-contacts.png"' in html
    assert html.count('<tr id="run-') == 10
    assert "&lt;script&gt;alert(1)&lt;/script&gt;" in html and "<script>" not in html
    assert ("swarmform run s.yaml --seed 0 --set sim.noise.position=0 --set robots.margin=0.1 --set planner.g=2 "
            "--set planner.q=500 --set planner.time_limit=60.0") in html
    assert "robots.margin needed" in html and "robots.margin needed" in text


def test_read_variants_and_grid_keep_settings_apart():
    variants = read_variants([FIG2], combinations([parse_set("robots.margin=0.1,0.3")]))
    specs = grid(variants, g=[1], q=[20], seeds=[0, 1])
    assert [(s.settings, s.seed, s.scenario.margin) for s in specs] == [
        ((("robots.margin", 0.1),), 0, 0.1), ((("robots.margin", 0.3),), 0, 0.3),
        ((("robots.margin", 0.1),), 1, 0.1), ((("robots.margin", 0.3),), 1, 0.3)]
    assert len({s.key for s in specs}) == 4
    assert math.isclose(specs[1].scenario.margin, 0.3)


def test_sweep_library_call_with_settings(tmp_path):
    variants = read_variants([FIG2], [{"planner.time_limit": 7}])
    path = tmp_path / "r.jsonl"
    result = sweep(grid(variants, g=[1], q=[20], seeds=[0]), path, workers=1)
    (row,) = read_results(path)
    assert result.computed == 1 and row["settings"] == {"planner.time_limit": 7} and row["time_limit"] == 7.0
