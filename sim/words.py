"""Counted nouns in messages: ``1 step``, ``2 steps``, ``1 contact``."""

from __future__ import annotations

__all__ = ["plural", "reached_phrase"]


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
