"""Contacts are counted once: sightings of both witnesses grouped into events; the settings table; the phase margin row."""

import math
from html.parser import HTMLParser
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from planner import PlannerParams
from planner.plan import Plan
from planner.problem import Problem
from sim.execute.contacts import Contact
from sim.execute.events import ContactEvent, group_events
from sim.execute.outcome import SimReport
from sim.execute.physics import execute
from sim.output.report import write_run_page
from sim.output.settings import non_defaults, settings_rows
from sim.output.verdict import contact_events, verdict
from sim.scenario.params import Noise, RenderParams, SimParams

REPO = Path(__file__).resolve().parents[2]


class _Tables(HTMLParser):
    """The cell texts of every table with an id, row by row."""

    def __init__(self, html: str):
        super().__init__()
        self.rows: dict[str, list[list[str]]] = {}
        self._table = None
        self._cell = None
        self.feed(html)

    def handle_starttag(self, tag, attrs):
        attrs = dict(attrs)
        if tag == "table" and attrs.get("id"):
            self._table = attrs["id"]
            self.rows[self._table] = []
        elif tag == "tr" and self._table:
            self.rows[self._table].append([])
        elif tag in ("td", "th") and self._table:
            self._cell = []

    def handle_endtag(self, tag):
        if tag == "table":
            self._table = None
        elif tag in ("td", "th") and self._table and self._cell is not None:
            self.rows[self._table][-1].append(" ".join("".join(self._cell).split()))
            self._cell = None

    def handle_data(self, data):
        if self._cell is not None:
            self._cell.append(data)


def _sighting(time, witness, kind="robot-robot", a=0, b=1, depth=0.01):
    return Contact(time, kind, a, b, depth, witness)


# ----------------------------------------------------------------------------
# grouping


def test_both_witnesses_of_one_touch_make_one_event():
    events = group_events([_sighting(1.00, "pymunk", depth=0.02), _sighting(1.02, "monitor", depth=0.01)])
    assert events == [ContactEvent("robot-robot", 0, 1, 1.00, 1.02, ("pymunk", "monitor"), 0.02, 2)]
    assert events[0].pair == (0, 1) and "seen by pymunk and monitor" in events[0].describe()


def test_events_part_by_pair_kind_and_time():
    sightings = [
        _sighting(1.00, "monitor"), _sighting(1.01, "pymunk"),  # one touch, listed monitor first
        _sighting(1.00, "pymunk", a=2, b=3),  # another pair at the same time
        _sighting(1.00, "monitor", kind="robot-wall", a=0, b=-1),  # the same robot, another kind
        _sighting(3.00, "pymunk"), _sighting(3.05, "monitor"),  # the first pair again, later
    ]
    events = group_events(sightings)
    assert [(e.kind, e.a, e.b, e.start) for e in events] == [
        ("robot-robot", 0, 1, 1.00), ("robot-robot", 2, 3, 1.00), ("robot-wall", 0, -1, 1.00),
        ("robot-robot", 0, 1, 3.00)]
    assert events[0].witnesses == ("pymunk", "monitor")  # in the fixed order, whoever came first
    assert events[1].witnesses == ("pymunk",) and events[2].witnesses == ("monitor",)
    assert sum(e.sightings for e in events) == len(sightings)
    # the window: 0.1 s joins, more does not
    assert len(group_events([_sighting(1.0, "pymunk"), _sighting(1.1, "monitor")])) == 1
    assert len(group_events([_sighting(1.0, "pymunk"), _sighting(1.2, "monitor")])) == 2


def test_a_sighting_of_one_witness_is_still_an_event():
    (event,) = group_events([_sighting(2.0, "monitor")])
    assert event.witnesses == ("monitor",) and event.start == event.end == 2.0
    # dicts (a report's contact_list) group the same way; a missing depth is not known
    (event,) = group_events([{"time": 2.0, "kind": "robot-wall", "a": 4, "b": -1, "witness": "pymunk"}])
    assert event.witnesses == ("pymunk",) and math.isnan(event.depth) and event.to_dict()["depth"] is None
    assert group_events([]) == []


# ----------------------------------------------------------------------------
# counts in the physics report, its verdict and its JSON


def _crossing():
    """Two robots driven through the same point at the same time."""
    w = np.array([[[2.0, 5.0], [5.0, 2.0]], [[8.0, 5.0], [5.0, 8.0]]])
    problem = Problem(10.0, 10.0, (), 0.5, 0.1, w[0], w[-1])
    return problem, Plan.from_waypoints(w, 0.5, 0.1, problem.max_speed, problem.max_accel)


def test_a_run_with_one_touch_counts_one_contact_seen_by_both():
    problem, plan = _crossing()
    report = execute(problem, plan, SimParams(settle_time=1.0))
    assert {c.witness for c in report.contacts} == {"pymunk", "monitor"}
    assert len(report.events) == 1 and report.events[0].witnesses == ("pymunk", "monitor")
    assert report.verdict.startswith("1 contact, the first: robots 0 and 1 touch"), report.verdict
    assert "seen by pymunk and monitor" in report.verdict
    d = report.to_dict()
    assert d["contacts"] == 1
    assert d["contacts_pymunk"] == 1 and d["contacts_monitor"] == 1  # sightings stay sightings
    assert len(d["contact_list"]) == 2 and {c["witness"] for c in d["contact_list"]} == {"pymunk", "monitor"}
    (event,) = d["contact_events"]
    assert event["witnesses"] == ["pymunk", "monitor"] and (event["kind"], event["a"], event["b"]) == (
        "robot-robot", 0, 1)
    assert event["start"] <= event["end"] and event["depth"] > 0
    ok, line = verdict({"plan": {"found": True, "valid": True}, "sim": d, "ok": False, "robots": 2})
    assert not ok and "1 contact in the physics run" in line and "seen by pymunk and monitor" in line


def _report(contacts) -> SimReport:
    t = np.array([0.0, 1.0])
    return SimReport(tuple(contacts), -0.01, 1.0, 0.0, True, 0.0, 1.0, 0.1, t, np.zeros((2, 2, 2)),
                     reached_robots=np.array([True, True]))


def test_one_witness_alone_still_counts_a_contact():
    report = _report([_sighting(1.0, "pymunk")])
    assert not report.ok and len(report.events) == 1
    assert report.verdict.startswith("1 contact,") and "seen by pymunk)" in report.verdict
    d = report.to_dict()
    assert d["contacts"] == 1 and d["contacts_pymunk"] == 1 and d["contacts_monitor"] == 0
    assert d["contact_events"][0]["witnesses"] == ["pymunk"]
    clean = _report([]).to_dict()
    assert clean["contacts"] == 0 and clean["contact_events"] == []


def test_old_reports_without_events_are_grouped_from_their_sightings():
    sightings = [{"time": 1.2, "kind": "robot-robot", "a": 0, "b": 1, "depth": 0.02, "witness": "pymunk"},
                 {"time": 1.21, "kind": "robot-robot", "a": 0, "b": 1, "depth": 0.01, "witness": "monitor"}]
    old = {"contacts": 2, "contacts_pymunk": 1, "contacts_monitor": 1, "contact_list": sightings}
    n, events = contact_events(old)
    assert n == 1 and events[0]["witnesses"] == ["pymunk", "monitor"]
    # a count alone (no list) is taken as it is
    assert contact_events({"contacts": 3})[0] == 3 and contact_events({})[0] == 0


# ----------------------------------------------------------------------------
# the run page: contacts table, settings table, phase margin


def _page_report(**sim):
    d = _report([_sighting(1.0, "pymunk", depth=0.02), _sighting(1.01, "monitor")]).to_dict()
    d.update(sim)
    return {"scenario": "unit", "seed": 1, "robots": 2, "radius": 0.5, "margin": 0.1,
            "plan": {"found": True, "valid": True, "steps": 1, "makespan_s": 1.0}, "sim": d, "media": [],
            "ok": False, "settings": {"sim.kp": 300, "robots.margin": 0.1},
            "non_defaults": {"sim.kp": 300.0, "planner.g": 3, "sim.noise.position": 0.01}}


def test_page_lists_events_with_their_witnesses_and_the_phase_margin(tmp_path):
    rep = _page_report(phase_margin_deg=57.3)
    doc = _Tables(write_run_page(tmp_path / "p.html", rep, None, None, None).read_text(encoding="utf-8"))
    rows = doc.rows["contacts"][1:]
    assert len(rows) == 1 and rows[0][:4] == ["1", "robot-robot", "0", "1"] and rows[0][5] == "pymunk and monitor"
    physics = {r[0]: r[1:] for r in doc.rows["physics"][1:]}
    assert physics["contacts"][0] == "1" and "1 seen by both witnesses" in physics["contacts"][1]
    assert "pymunk 1, monitor 1" in physics["contacts"][1]
    assert physics["phase margin"][0] == "57.3°"
    rep = _page_report(phase_margin_deg=-4.0)
    doc = _Tables(write_run_page(tmp_path / "q.html", rep, None, None, None).read_text(encoding="utf-8"))
    assert "UNSTABLE" in {r[0]: r[1:] for r in doc.rows["physics"][1:]}["phase margin"][1]


def test_non_defaults_are_flattened_and_defaults_left_out():
    scenario = SimpleNamespace(planner=PlannerParams(g=3), sim=SimParams(noise=Noise(position=0.01)),
                               render=RenderParams())
    assert non_defaults(scenario) == {"planner.g": 3, "sim.noise.position": 0.01}
    assert non_defaults(SimpleNamespace(planner=PlannerParams(), sim=SimParams(), render=RenderParams())) == {}
    assert non_defaults(SimpleNamespace(render=RenderParams(formats=("gif",)))) == {"render.formats": ["gif"]}


def test_settings_table_lists_set_values_and_non_defaults_once(tmp_path):
    rows = settings_rows(_page_report())
    assert rows == [("sim.kp", "300", "--set"), ("robots.margin", "0.1", "--set"),
                    ("planner.g", "3", "scenario file"), ("sim.noise.position", "0.01", "scenario file")]
    assert settings_rows({}) == []  # an old report


def test_a_run_shows_its_set_value_and_non_defaults_not_its_defaults(tmp_path):
    from sim.runner import run_scenario

    run = run_scenario(REPO / "scenarios/paper/fig2-random-to-C.yaml", out_dir=tmp_path, render=False,
                       overrides={"sim.kd": 35.0}, out=None)
    assert run.report["settings"] == {"sim.kd": 35.0}
    assert run.report["non_defaults"]["sim.kd"] == 35.0 and "sim.kp" not in run.report["non_defaults"]
    doc = _Tables(Path(run.report["page"]).read_text(encoding="utf-8"))
    table = {r[0]: r[1:] for r in doc.rows["settings"][1:]}
    assert table["sim.kd"] == ["35", "--set"]
    other = {k for k, (_, src) in table.items() if src == "scenario file"}
    assert other == set(run.report["non_defaults"]) - {"sim.kd"} and other  # the file's own choices
    assert not {"sim.kp", "sim.dt", "render.fps", "planner.time_limit"} & set(table)  # defaults left out
    assert run.report["sim"]["contacts"] == len(run.report["sim"]["contact_events"])


@pytest.mark.parametrize("value", [math.inf, float("nan")])
def test_non_finite_values_stay_json_ready(value):
    import json

    d = non_defaults(SimpleNamespace(sim=SimParams(latency=value)))
    assert json.loads(json.dumps(d, allow_nan=False)) == {"sim.latency": str(value)}
