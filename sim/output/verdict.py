"""The verdict of a run report: one line that says what happened, and whether the run passed."""

from __future__ import annotations

import math

import numpy as np

from ..execute.drive_timing import timing_notes
from ..execute.events import group_events
from ..words import reached_phrase, run_notes

__all__ = ["contact_events", "verdict"]


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
    n, events = contact_events(sim)
    if n:
        if "contact_events" in sim:
            first = events[0] if events else None
        else:  # an old report: its first sighting
            first = sim.get("first_contact") or (events or [None])[0]
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


def contact_events(sim: dict) -> tuple[int, list[dict]]:
    """How many contact events a physics report counts, and those it lists (dicts, time order).

    A report lists them under ``contact_events`` and counts them under
    ``contacts``.  An older one lists only the sightings (``contact_list``,
    every witness's record), which are grouped here
    (:func:`sim.execute.events.group_events`) when the list is complete;
    otherwise its own count is taken.
    """
    listed = sim.get("contact_events")
    if isinstance(listed, list):
        events = [e for e in listed if isinstance(e, dict)]
        n = sim.get("contacts")
        return (n if isinstance(n, int) and not isinstance(n, bool) else len(events)), events
    sightings = sim.get("contact_list")
    if isinstance(sightings, list) and sightings and not sim.get("contact_list_truncated"):
        try:
            events = [e.to_dict() for e in group_events([c for c in sightings if isinstance(c, dict)])]
        except ValueError:
            events = []
        if events:
            return len(events), events
    n = sim.get("contacts")
    return (n if isinstance(n, int) and not isinstance(n, bool) and n > 0 else 0), []


def _parked(sim: dict) -> int:
    """Working robots parked by the last replan (failed robots block their targets)."""
    replans = sim.get("replans") or []
    last = replans[-1] if replans and isinstance(replans[-1], dict) else {}
    parked = last.get("parked") or []
    return len(parked) if isinstance(parked, list) else 0


def _physics_notes(sim: dict, m) -> list[str]:
    """What a realistic run adds to the verdict: failed robots, empty targets, replans, an unstable loop."""
    return run_notes(sim.get("failed"), _parked(sim), sim.get("targets_filled"), m,
                     len(sim.get("replans") or []), sim.get("phase_margin_deg"), list_max=10) + \
        timing_notes(sim.get("drive_timing"))


def _describe_contact(c: dict) -> str:
    kind, a, b = c.get("kind"), c.get("a"), c.get("b")
    if kind == "robot-robot":
        who = f"robots {a} and {b}"
    elif kind == "robot-wall":
        who = f"robot {a} and the wall"
    else:
        who = f"robot {a} and obstacle {b}"
    time = c.get("start", c.get("time"))
    seen = c.get("witnesses")
    seen = f" (seen by {' and '.join(map(str, seen))})" if isinstance(seen, list) and seen else ""
    return f"{who} at t = {_num(time, 3)} s{seen}"


# ----------------------------------------------------------------------------
# the page


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


def _disturbance_list(sim: dict) -> list:
    """The disturbances applied: the physics report's ``{impulses, pushes, failures, list}`` or a plain list."""
    d = sim.get("disturbances")
    if isinstance(d, dict):
        d = d.get("list")
    return d if isinstance(d, list) else []
