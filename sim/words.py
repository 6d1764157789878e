"""Counted nouns in messages: ``1 step``, ``2 steps``, ``1 contact``."""

from __future__ import annotations

__all__ = ["plural"]


def plural(n: int, noun: str, nouns: str | None = None) -> str:
    """``n`` and ``noun``, with ``nouns`` (default ``noun + "s"``) unless ``n`` is 1."""
    return f"{n} {noun if n == 1 else (nouns or noun + 's')}"
