"""Contact events: the sightings of both witnesses grouped into what happened.

The two witnesses (:mod:`sim.execute.contacts`) each report every touching
episode they see, so one touch of two robots is usually two records: one
from pymunk's callbacks, one from the gap monitor, a control step apart.  A
:class:`ContactEvent` is one touch of one pair (two robots, a robot and an
obstacle, a robot and the wall) with the witnesses that saw it.  Counts,
verdicts and tables count events; the sightings stay in the report too.

:func:`group_events` puts sightings of the same pair and kind into one event
when they lie within :data:`SAME_CONTACT_SECONDS` of the event so far (the
witnesses record when an episode began, not how long it lasted, so "overlap"
means "begins within the window of the previous sighting of the pair").
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

__all__ = ["SAME_CONTACT_SECONDS", "WITNESSES", "ContactEvent", "group_events"]

SAME_CONTACT_SECONDS = 0.1
"""Sightings of one pair at most this far apart [sim s] are one contact event."""

WITNESSES = ("pymunk", "monitor")
"""The witnesses, in the order an event names them."""


@dataclass(frozen=True)
class ContactEvent:
    """One contact, with the witnesses that saw it.

    kind: ``robot-robot``, ``robot-obstacle`` or ``robot-wall``.
    a: robot index (the smaller one for ``robot-robot``).
    b: the other robot, the obstacle index, or ``-1`` (the wall).
    start: the first sighting's time [s]; end: the last sighting's [s].
    witnesses: who saw it, a sub-tuple of :data:`WITNESSES` (in that order).
    depth: the deepest overlap any sighting reports, ``>= 0`` [units], or
        NaN when no sighting knows it.
    sightings: how many records the event groups.
    """

    kind: str
    a: int
    b: int
    start: float
    end: float
    witnesses: tuple[str, ...]
    depth: float = float("nan")
    sightings: int = 1

    @property
    def pair(self) -> tuple[int, int]:
        return (self.a, self.b)

    @property
    def time(self) -> float:
        """When it began [s] (the name the sightings use)."""
        return self.start

    def who(self) -> str:
        if self.kind == "robot-robot":
            return f"robots {self.a} and {self.b}"
        if self.kind == "robot-wall":
            return f"robot {self.a} and the wall"
        return f"robot {self.a} and obstacle {self.b}"

    def describe(self) -> str:
        depth = "" if math.isnan(self.depth) else f", depth {self.depth:.3g}"
        return f"{self.who()} touch at t = {self.start:.3f} s{depth} (seen by {' and '.join(self.witnesses)})"

    def to_dict(self) -> dict:
        depth = None if math.isnan(self.depth) else float(self.depth)
        return {"start": self.start, "end": self.end, "kind": self.kind, "a": self.a, "b": self.b,
                "witnesses": list(self.witnesses), "depth": depth, "sightings": self.sightings}


def _order(witnesses: Iterable[str]) -> tuple[str, ...]:
    seen = set(witnesses)
    return tuple(w for w in WITNESSES if w in seen) + tuple(sorted(seen - set(WITNESSES)))


def group_events(contacts: Sequence, window: float = SAME_CONTACT_SECONDS) -> list[ContactEvent]:
    """Group sightings into contact events, in time order (then kind, a, b).

    contacts: records with ``time`` [s], ``kind``, ``a``, ``b``, ``witness``
        and optionally ``depth`` (:class:`sim.execute.contacts.Contact`, or
        dicts with those keys as in a report's ``contact_list``).
    window: sightings of one pair and kind whose times are at most this
        far from the latest sighting of an event [s] join that event.

    A sighting that only one witness made is an event of its own, named
    with that witness alone.
    """
    if not window >= 0:
        raise ValueError(f"window must be a time >= 0 [s], got {window!r}")
    rows = []
    for n, c in enumerate(contacts):
        get = c.get if isinstance(c, dict) else (lambda k, d=None, c=c: getattr(c, k, d))
        try:
            time, kind, a, b = float(get("time")), str(get("kind")), int(get("a")), int(get("b"))
        except (TypeError, ValueError) as e:
            raise ValueError(f"contacts[{n}] needs time, kind, a and b: {e}") from None
        depth = get("depth")
        depth = float(depth) if isinstance(depth, (int, float)) and not isinstance(depth, bool) else float("nan")
        rows.append((kind, a, b, time, str(get("witness", "")), depth))
    rows.sort(key=lambda r: (r[0], r[1], r[2], r[3]))
    events: list[ContactEvent] = []
    open_: dict | None = None
    for kind, a, b, time, witness, depth in rows:
        key = (kind, a, b)
        if open_ is not None and open_["key"] == key and time - open_["end"] <= window + 1e-9:
            open_["end"] = time
            open_["witnesses"].add(witness)
            open_["depths"].append(depth)
            open_["n"] += 1
            continue
        if open_ is not None:
            events.append(_close(open_))
        open_ = {"key": key, "start": time, "end": time, "witnesses": {witness}, "depths": [depth], "n": 1}
    if open_ is not None:
        events.append(_close(open_))
    events.sort(key=lambda e: (e.start, e.kind, e.a, e.b))
    return events


def _close(o: dict) -> ContactEvent:
    known = [d for d in o["depths"] if not math.isnan(d)]
    kind, a, b = o["key"]
    return ContactEvent(kind, a, b, o["start"], o["end"], _order(w for w in o["witnesses"] if w),
                        max(known) if known else float("nan"), o["n"])
