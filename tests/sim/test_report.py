"""The run page (sim.report), its time series (sim.series), and what `swarmform run` writes and says."""

import json
import subprocess
import sys
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pytest

from planner import Plan
from planner.problem import Problem
from sim.execute.series import run_series
from sim.output import plots
from sim.output.report import run_page, verdict, write_run_page

ROOT = Path(__file__).resolve().parents[2]
EXE = str(Path(sys.executable).parent / "swarmform")


class _Page(HTMLParser):
    """Elements by id, every src/href, the text of each table's rows, and the page text."""

    def __init__(self, html: str):
        super().__init__()
        self.ids: dict[str, tuple[str, dict]] = {}
        self.urls: list[str] = []
        self.tags: list[str] = []
        self.rows: dict[str, list[list[str]]] = {}
        self.row_classes: dict[str, list[str]] = {}
        self.text: list[str] = []
        self._table = None
        self._stack: list[str] = []
        self.feed(html)

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        self.tags.append(tag)
        if "id" in a:
            self.ids[a["id"]] = (tag, a)
        for key in ("src", "href"):
            if key in a:
                self.urls.append(a[key])
        if tag == "table":
            self._table = a.get("id", "")
            self.rows[self._table] = []
            self.row_classes[self._table] = []
        elif tag == "tr" and self._table is not None:
            self.rows[self._table].append([])
            self.row_classes[self._table].append(a.get("class", ""))
        self._stack.append(tag)

    def handle_endtag(self, tag):
        if tag == "table":
            self._table = None
        if self._stack:
            self._stack.pop()

    def handle_data(self, data):
        if self._stack and self._stack[-1] in ("style", "script"):
            return
        self.text.append(data)
        if self._table is not None and self._stack and self._stack[-1] in ("td", "th"):
            self.rows[self._table][-1].append(data.strip())

    @property
    def all_text(self) -> str:
        return " ".join(" ".join(self.text).split())


def _report(**sim_extra):
    sim = {
        "ok": False, "contacts": 2, "contacts_pymunk": 1, "contacts_monitor": 1,
        "min_clearance": -0.02, "min_clearance_time": 1.2, "min_clearance_kind": "robot-robot",
        "min_clearance_pair": [0, 1], "max_tracking_error": 0.03, "reached": True, "final_error": 0.001,
        "sim_time_s": 5.0, "wall_time_s": 0.1, "realtime_factor": 50.0,
        "contact_list": [
            {"time": 1.2, "kind": "robot-robot", "a": 0, "b": 1, "depth": 0.02, "witness": "pymunk"},
            {"time": 1.21, "kind": "robot-wall", "a": 1, "b": -1, "depth": 0.01, "witness": "monitor"},
        ],
    }
    sim.update(sim_extra)
    return {
        "scenario": "unit", "seed": 3, "robots": 2, "radius": 0.5, "margin": 0.1, "scenario_file": "unit.yaml",
        "plan": {"found": True, "planning_time_s": 0.25, "g": "auto", "q": "auto", "graphs": 0, "connections": 1,
                 "steps": 1, "makespan_s": 3.0, "path_length": 8.0, "min_clearance": 0.1,
                 "makespan_lower_bound_s": 2.0, "path_length_lower_bound": 7.5, "valid": True},
        "sim": sim, "media": [], "ok": False,
    }


def _series(m=2, n=50):
    t = np.linspace(0.0, 5.0, n)
    return {"times": t, "min_gap": 0.3 - 0.3 * np.exp(-((t - 1.2) ** 2)),
            "tracking_error": np.abs(np.sin(t[:, None] + np.arange(m)[None])) * 0.03}


def _picture():
    img = np.full((60, 80, 3), 240, np.uint8)
    img[20:40, 30:50] = (40, 90, 200)
    return img


def _gif(path: Path) -> Path:
    from sim.output.media import write_gif

    frames = [np.full((40, 60, 3), 248, np.uint8) for _ in range(3)]
    for k, f in enumerate(frames):
        f[10:20, 5 + 10 * k : 15 + 10 * k] = (230, 20, 20)
    return write_gif(path, frames, 10)


# ----------------------------------------------------------------------------
# the verdict


def test_verdict_names_what_went_wrong():
    ok_report = _report(contacts=0, contact_list=[], min_clearance=0.11)
    ok_report["ok"] = True
    good, line = verdict(ok_report)
    assert good and line.startswith("ok:") and "margin 0.1" in line
    bad, line = verdict(_report())
    assert not bad and "2 contacts" in line and "robots 0 and 1 at t = 1.2 s" in line
    first = {"time": 0.5, "kind": "robot-obstacle", "a": 1, "b": 0, "depth": 0.1, "witness": "monitor"}
    assert "robot 1 and obstacle 0 at t = 0.5 s" in verdict(_report(first_contact=first))[1]
    one = _report(contacts=1, contact_list=_report()["sim"]["contact_list"][:1])
    assert "1 contact in" in verdict(one)[1]
    missed = _report(contacts=0, contact_list=[], reached=False, reached_robots=1)
    assert "not every robot reached a target (1 of 2 did)" in verdict(missed)[1]
    flags = _report(contacts=0, contact_list=[], reached=False, reached_robots=[True, False])  # as the physics run writes it
    assert "not every robot reached a target (1 of 2 did)" in verdict(flags)[1]
    # a realistic run: a failed robot, a replan, one target left empty; ok for the working robots
    recovered = _report(contacts=0, contact_list=[], reached=True, failed=[1], targets_filled=1,
                        replans=[{"time": 2.0}], phase_margin_deg=40.0)
    recovered["ok"] = True
    good, line = verdict(recovered)
    assert good and "every working robot on a target" in line
    assert line.endswith("; robot 1 failed; 1 of 2 targets filled; 1 replan"), line
    assert "or parked" not in line
    # a working robot parked because the failed one blocks targets: said, not hidden
    parked = _report(contacts=0, contact_list=[], reached=True, failed=[1], targets_filled=0,
                     replans=[{"time": 2.0, "parked": [[3.0, 4.0]]}], phase_margin_deg=40.0)
    parked["ok"] = True
    good, line = verdict(parked)
    assert good and "every working robot on a target or parked (min clearance" in line, line
    assert "; robot 1 failed; 1 robot parked; 0 of 2 targets filled" in line, line
    unstable = _report(contacts=0, contact_list=[], reached=False, stopped="a replan found no way on",
                       phase_margin_deg=-42.0)
    bad, line = verdict(unstable)
    assert not bad and "stopped: a replan found no way on" in line and "not every robot" not in line
    assert "unstable with its delays (phase margin -42 deg)" in line
    below = _report(contacts=0, contact_list=[])
    below["plan"]["valid"] = False
    assert "closer than the margin" in verdict(below)[1]
    none = {"scenario": "x", "plan": {"found": False, "error": "start and target not connected"}, "sim": None,
            "ok": False}
    assert verdict(none) == (False, "FAILED: no plan (start and target not connected)")
    # a report that says ok without its evidence is not called ok
    assert verdict({"ok": True, "plan": {"found": True}, "sim": None})[0] is False


# ----------------------------------------------------------------------------
# the page from plain data


def test_page_lists_the_disturbances_as_the_physics_run_reports_them(tmp_path):
    applied = {"impulses": 0, "pushes": 1, "failures": 1,
               "list": [{"kind": "push", "robot": 3, "time": 3.5, "impulse": [-0.4231, 0.2665]},
                        {"kind": "failure", "robot": 2, "time": 8.0, "impulse": None}]}
    rep = _report(contacts=0, contact_list=[], disturbances=applied)
    doc = _Page(write_run_page(tmp_path / "d.html", rep, _series(), _picture(), None).read_text(encoding="utf-8"))
    assert doc.rows["disturbances"][1:] == [["3.5", "3", "push", "[-0.423, 0.267]"], ["8", "2", "failure", "n/a"]]
    none = _report(contacts=0, contact_list=[], disturbances={"impulses": 0, "pushes": 0, "failures": 0, "list": []})
    assert "disturbances" not in _Page(write_run_page(tmp_path / "n.html", none, _series(), _picture(), None)
                                       .read_text(encoding="utf-8")).ids


def test_page_holds_every_part_and_needs_nothing_else(tmp_path):
    first = {"time": 1.2, "kind": "robot-robot", "a": 0, "b": 1, "depth": 0.02, "witness": "pymunk"}
    rep = _report(
        first_contact=first, max_tracking_error_time=2.5, reached_robots=2,
        disturbances=[{"time": 2.0, "robot": 1, "kind": "push", "impulse": 0.4}],
        replans=[{"time": 2.1, "reason": "off track", "planning_time_s": 0.05, "robots": 2, "found": True,
                  "steps": 2}],
    )
    rep["video"] = {"speedup": 40.0, "speedup_asked": 1e-9, "speedup_raised": True, "fps": 20, "frames": 120,
                    "seconds": 6.0}
    path = write_run_page(tmp_path / "unit.html", rep, _series(), _picture(), _gif(tmp_path / "unit.gif"))
    html = path.read_text(encoding="utf-8")
    doc = _Page(html)
    assert doc.ids["verdict"][1]["class"].endswith("failed")
    assert doc.all_text.count("FAILED: 2 contacts") == 1
    for ident in ("scenario", "video", "plot-clearance", "plot-tracking", "plan", "physics", "contacts",
                  "disturbances", "replans"):
        assert ident in doc.ids, ident
    # self-contained: every picture and the video are data URIs; nothing is fetched
    imgs = [u for u in doc.urls if not u.endswith(".gif")]
    assert imgs and all(u.startswith("data:") for u in imgs)
    assert sum(u.startswith("data:image/gif;base64,") for u in doc.urls) == 1
    assert sum(u.startswith("data:image/png;base64,") for u in doc.urls) == 3
    assert "script" not in doc.tags and "link" not in doc.tags and "http" not in " ".join(doc.urls)
    # the contacts table: one row per contact, the first marked
    assert len(doc.rows["contacts"]) == 3
    assert doc.rows["contacts"][1][:4] == ["1.2", "robot-robot", "0", "1"]
    assert doc.row_classes["contacts"][1:] == ["first", ""]
    assert doc.rows["contacts"][2][3] == "wall"
    assert doc.rows["disturbances"][1] == ["2", "1", "push", "0.4"]
    assert doc.rows["replans"][1][:2] == ["2.1", "off track"]
    # plan numbers against the lower bounds, in auto mode
    plan_rows = {r[0]: r[1:] for r in doc.rows["plan"][1:]}
    assert plan_rows["g, q"][0] == "auto, auto"
    assert plan_rows["makespan"][1].endswith("1.50x the bound")
    assert plan_rows["total path length"][1].endswith("1.07x the bound")
    physics = {r[0]: r[1:] for r in doc.rows["physics"][1:]}
    assert physics["max tracking error"][1] == "at t = 2.5 s"
    assert physics["every robot on a target"][0] == "yes (2 of 2 robots)"
    assert "raised from 1e-09x" in physics["video playback speed"][1]
    # the raw report, escaped, at the end
    assert json.loads(_Page(html.split("<pre>")[1].split("</pre>")[0]).all_text)["seed"] == 3


def test_page_without_physics_series_picture_or_video(tmp_path):
    rep = {"scenario": "bare", "seed": 0, "robots": 2,
           "plan": {"found": False, "planning_time_s": 0.5, "g": 2, "q": 100, "graphs": 2, "connections": 0,
                    "error": "start and target not connected"},
           "sim": None, "media": [], "ok": False}
    doc = _Page(write_run_page(tmp_path / "bare.html", rep, None, None, None).read_text(encoding="utf-8"))
    assert "FAILED: no plan" in doc.all_text
    for ident in ("scenario", "video", "plot-clearance", "plot-tracking", "physics", "contacts"):
        assert ident not in doc.ids, ident
    assert "No video for this run." in doc.all_text
    assert {r[0]: r[1] for r in doc.rows["plan"][1:]}["why no plan"] == "start and target not connected"
    # with physics but no series: the page says so
    doc = _Page(write_run_page(tmp_path / "s.html", _report(), None, _picture(), None).read_text(encoding="utf-8"))
    assert "No time series were recorded" in doc.all_text and "plot-clearance" not in doc.ids


def test_page_escapes_what_it_shows(tmp_path):
    rep = _report()
    rep["scenario"] = "<script>alert(1)</script>"
    rep["sim"]["contact_list"][0]["kind"] = "<b>x</b>"
    html = write_run_page(tmp_path / "e.html", rep, None, None, None).read_text(encoding="utf-8")
    assert "<script>" not in html and "<b>x</b>" not in html
    assert "&lt;script&gt;alert(1)&lt;/script&gt;" in html


def test_a_huge_name_is_cut_in_the_title(tmp_path):
    rep = _report()
    rep["scenario"] = "n" * 1_000_000
    doc = _Page(write_run_page(tmp_path / "n.html", rep, None, None, None).read_text(encoding="utf-8"))
    shown = [t for t in doc.text if t.startswith("nnn")]
    assert "n" * 117 + "..." in shown  # the heading
    assert "n" * 117 + "...: swarmform run" in shown  # the window title


def test_a_large_video_is_linked_not_embedded(tmp_path, monkeypatch):
    gif = _gif(tmp_path / "big.gif")
    monkeypatch.setattr(plots, "EMBED_MAX_BYTES", gif.stat().st_size - 1)
    doc = _Page(write_run_page(tmp_path / "big.html", _report(), None, None, gif).read_text(encoding="utf-8"))
    assert "big.gif" in doc.urls and not any(u.startswith("data:image/gif") for u in doc.urls)
    assert "too large to embed" in doc.all_text


def test_page_replaces_an_older_one_whole(tmp_path):
    path = tmp_path / "r.html"
    path.write_text("old", encoding="utf-8")
    with pytest.raises(TypeError):
        write_run_page(path, _report(), {"times": [0.0, 1.0], "min_gap": object()}, None, None)
    assert path.read_text(encoding="utf-8") == "old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.html"]


# ----------------------------------------------------------------------------
# the series


def test_series_min_gap_and_tracking_error_are_the_exact_values():
    # two robots approach along y = 5 and stop 0.2 apart; a third sits 0.3 from the bottom wall
    start = np.array([[2.0, 5.0], [8.0, 5.0], [5.0, 0.8]])
    mid = np.array([[4.4, 5.0], [5.6, 5.0], [5.0, 0.8]])
    problem = Problem(10.0, 10.0, (), 0.5, 0.1, start, mid)
    plan = Plan.from_waypoints(np.stack([start, mid]), 0.5, 0.1, 2.0, 2.0)
    t = np.linspace(0.0, plan.makespan + 1.0, 301)
    pos = plan.sample(t)[0].copy()
    pos[:, 2, 1] += 0.01  # robot 2 tracks 0.01 above its plan
    s = run_series(problem, plan, t, pos)
    centres = np.linalg.norm(pos[:, 0] - pos[:, 1], axis=1) - 1.0
    wall = pos[:, 2, 1] - 0.5
    assert np.allclose(s["min_gap"], np.minimum(centres, np.minimum(wall, pos[:, :2, 1].min(axis=1) - 0.5)))
    assert s["min_gap"][-1] == pytest.approx(0.2)  # the pair, at the end
    assert s["min_gap"][0] == pytest.approx(0.31)  # the wall, at the start
    assert np.allclose(s["tracking_error"][:, :2], 0.0, atol=1e-12)
    assert np.allclose(s["tracking_error"][:, 2], 0.01)
    # samples are thinned to at most max_samples, first and last kept
    thin = run_series(problem, plan, t, pos, max_samples=40)
    assert len(thin["times"]) <= 41 and thin["times"][0] == t[0] and thin["times"][-1] == t[-1]


def test_series_sees_an_obstacle_and_an_overlap():
    from planner.problem import Circle

    start = np.array([[2.0, 2.0], [2.6, 2.0]])  # overlapping discs: a negative gap
    problem = Problem(10.0, 10.0, (Circle((5.0, 5.0), 1.0),), 0.5, 0.1, start, start)
    plan = Plan.from_waypoints(start[None], 0.5, 0.1, 2.0, 2.0)
    pos = np.stack([start, [[5.0, 3.6], [8.0, 8.0]]])  # then robot 0 0.1 from the circle
    s = run_series(problem, plan, np.array([0.0, 1.0]), pos)
    assert s["min_gap"] == pytest.approx([-0.4, -0.1])


# ----------------------------------------------------------------------------
# what `swarmform run` writes and says


def _run(*args, cwd=ROOT):
    return subprocess.run([EXE, *map(str, args)], capture_output=True, text=True, cwd=cwd)


def test_run_writes_the_page_next_to_the_report_and_video(tmp_path):
    scen = tmp_path / "line-to-lambda.yaml"  # the shipped scenario, as a GIF only (faster)
    scen.write_text((ROOT / "scenarios/letters/line-to-lambda.yaml").read_text() + "render: {formats: [gif]}\n")
    r = _run("run", scen, "--out", tmp_path)
    assert r.returncode == 0, r.stdout + r.stderr
    report = json.loads((tmp_path / "line-to-lambda.json").read_text())
    html = tmp_path / "line-to-lambda.html"
    assert report["page"] == str(html) and html.is_file()
    assert report["ok"] is True and report["plan"]["g"] == "auto" and report["plan"]["q"] == "auto"
    assert isinstance(report["plan"]["graphs"], int)
    assert report["video"]["frames"] > 0 and report["video"]["speedup_raised"] is False
    doc = _Page(html.read_text(encoding="utf-8"))
    assert doc.ids["verdict"][1]["class"].endswith(" ok")
    assert {"scenario", "video", "plot-clearance", "plot-tracking"} <= set(doc.ids)
    lines = r.stdout.splitlines()
    assert any("planned in" in x and " s," in x for x in lines)
    for name in ("line-to-lambda.json", "line-to-lambda.html", "line-to-lambda.gif"):
        assert any(x.strip() == f"wrote {tmp_path / name}" for x in lines), name


def test_no_plan_report_has_ok_and_run_says_where_it_wrote_it(tmp_path):
    scen = tmp_path / "split.yaml"
    scen.write_text(
        "name: split\nworkspace: [20, 10]\nrobots: {radius: 0.5, margin: 0.1}\n"
        "obstacles:\n  - polygon: [[9, 0], [11, 0], [11, 10], [9, 10]]\n"
        "start: {points: [[2, 2], [2, 5]]}\ntarget: {points: [[18, 2], [18, 5]]}\nplanner: {time_limit: 0.3}\n"
    )
    r = _run("run", scen, "--out", tmp_path / "out")
    assert r.returncode == 1, r.stdout + r.stderr
    report = json.loads((tmp_path / "out" / "split.json").read_text())
    assert report["ok"] is False and report["plan"]["found"] is False
    # the wall splits the room: proven impossible before any sampling
    assert report["plan"]["g"] == "auto" and report["plan"]["graphs"] == 0
    assert report["plan"]["feasible"] is False and "2 starts and 0 targets" in report["plan"]["infeasible_reason"]
    assert f"wrote {tmp_path / 'out' / 'split.json'}" in r.stdout
    assert f"wrote {tmp_path / 'out' / 'split.html'}" in r.stdout
    assert "no plan exists: " in r.stdout and "(proven in 0." in r.stdout
    doc = _Page((tmp_path / "out" / "split.html").read_text(encoding="utf-8"))
    assert "FAILED: no plan exists" in doc.all_text and "scenario" in doc.ids


def test_run_page_uses_the_physics_series_when_there_are_some(tmp_path):
    start = np.array([[2.0, 5.0], [8.0, 5.0]])
    problem = Problem(10.0, 10.0, (), 0.5, 0.1, start, start)

    class Sim:
        series = _series()
        times = positions = None  # would fail if recomputed

    path = run_page(tmp_path / "p.html", _report(), problem, None, Sim(), [])
    doc = _Page(path.read_text(encoding="utf-8"))
    assert "plot-clearance" in doc.ids and "scenario" in doc.ids and "video" not in doc.ids
