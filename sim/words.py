"""Counted nouns in messages: ``1 step``, ``2 steps``, ``1 contact``."""

from __future__ import annotations

__all__ = ["plural", "reached_phrase", "run_notes"]


def plural(n: int, noun: str, nouns: str | None = None) -> str:
    """``n`` and ``noun``, with ``nouns`` (default ``noun + "s"``) unless ``n`` is 1."""
    return f"{n} {noun if n == 1 else (nouns or noun + 's')}"


def reached_phrase(failed: bool, parked: int = 0) -> str:
    """What a good run's robots did: ``every robot on a target``; when robots failed,
    ``every working robot on a target``, or ``... on a target or parked`` when failed
    robots block targets and working robots park instead (the caller says how many)."""
    if not failed:
        return "every robot on a target"
    return "every working robot on a target" + (" or parked" if parked > 0 else "")


def run_notes(failed, parked: int, filled, m, replans: int, phase_margin, *,
              list_max: int | None = None, advice: bool = False) -> list[str]:
    """What a realistic run adds to its verdict, in order: failed robots (the first
    ``list_max`` named, then `` ...``), robots parked, empty targets (``filled`` of
    ``m``), replans, and an unstable controller (``advice``: with what to change)."""
    notes = []
    failed = list(failed or [])
    if failed:
        shown = failed if list_max is None else failed[:list_max]
        more = " ..." if len(shown) < len(failed) else ""
        notes.append(f"robot{'s' if len(failed) != 1 else ''} {', '.join(str(i) for i in shown)}{more} failed")
    if parked:
        notes.append(f"{plural(parked, 'robot')} parked")
    if isinstance(filled, int) and isinstance(m, int) and 0 <= filled < m:
        notes.append(f"{filled} of {m} targets filled")
    if replans:
        notes.append(plural(replans, "replan"))
    if isinstance(phase_margin, (int, float)) and phase_margin <= 0:
        notes.append(f"the controller is unstable with its delays (phase margin {phase_margin:.0f} deg)"
                     + (": lower kp and kd, or the latency" if advice else ""))
    return notes
