"""The summary as data: headings, paragraphs, tables and lists, written as Markdown or HTML.

The tables of a sweep are built once as blocks; :func:`markdown` writes
``NAME.md`` (and what the command prints) from them, and the HTML page's
template walks the same blocks.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass

__all__ = ["Block", "Bullets", "Heading", "Para", "Table", "markdown"]


@dataclass(frozen=True)
class Heading:
    level: int
    text: str
    kind = "heading"


@dataclass(frozen=True)
class Para:
    text: str
    kind = "para"


@dataclass(frozen=True)
class Table:
    head: tuple[str, ...]
    rows: tuple[tuple[str, ...], ...]
    kind = "table"

    @classmethod
    def of(cls, head: Sequence[str], rows: Iterable[Sequence[str]]) -> Table:
        return cls(tuple(head), tuple(tuple(r) for r in rows))


@dataclass(frozen=True)
class Bullets:
    items: tuple[str, ...]
    kind = "bullets"


Block = Heading | Para | Table | Bullets


def markdown(blocks: Iterable[Block]) -> str:
    """The blocks as Markdown, one blank line between blocks."""
    parts = []
    for b in blocks:
        if isinstance(b, Heading):
            parts.append("#" * b.level + " " + b.text)
        elif isinstance(b, Para):
            parts.append(b.text)
        elif isinstance(b, Table):
            lines = ["| " + " | ".join(b.head) + " |", "|" + "---|" * len(b.head)]
            lines += ["| " + " | ".join(r) + " |" for r in b.rows]
            parts.append("\n".join(lines))
        elif isinstance(b, Bullets):
            parts.append("\n".join(f"- {item}" for item in b.items))
    return "\n\n".join(parts) + ("\n" if parts else "")
