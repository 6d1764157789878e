"""``--set KEY=VALUE`` overrides of scenario fields: parsing and applying them.

KEY is a dotted path into the scenario's YAML document (``robots.margin``,
``sim.kp``, ``planner.time_limit``; a number picks a list item, as in
``obstacles.0.circle.radius``).  Each VALUE is read as a YAML scalar (a
number, ``true``/``false``, ``null`` or a string), except that ``1e-3``
style numbers, which YAML 1.1 reads as strings, are numbers here.  ``run``
takes one value per key; ``tune`` takes a comma-separated list and sweeps
the grid of every combination.

:func:`apply_overrides` changes the loaded document before the scenario is
checked (``read_scenario(path, overrides=...)``), so an overridden value
passes the same checks as one written in the file, and an error about it
names the option (:func:`blame`): ``--set sim.nosie.position: unknown key
'nosie' in sim (allowed here: ...)``.

>>> parse_set("robots.margin=0.1,0.2")
Override(key='robots.margin', values=(0.1, 0.2))
>>> apply_overrides({"robots": {"count": 7}}, {"robots.margin": 0.2})
{'robots': {'count': 7, 'margin': 0.2}}
"""

from __future__ import annotations

import itertools
import math
import re
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from .model import ScenarioError
from .yamlfile import YamlRefused, load_yaml

__all__ = ["Override", "OverrideError", "apply_overrides", "blame", "combinations", "parse_set"]

_KEY_RE = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*(\.([A-Za-z_][A-Za-z0-9_]*|[0-9]+))*$")
_NUMBER_RE = re.compile(r"^[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$")
_MAX_VALUES = 1000  # values of one --set; a grid is their product, bounded again by the sweep
_MAX_TEXT = 80  # characters of a value echoed in an error


class OverrideError(ScenarioError):
    """A bad ``--set`` option: ``str()`` is one line ``--set KEY: reason``."""

    def __init__(self, key: str, reason: str):
        self.option = f"--set {key}" if key else "--set"
        ValueError.__init__(self, f"{self.option}: {reason}")
        self.path, self.field, self.reason = self.option, key, reason


@dataclass(frozen=True)
class Override:
    """One ``--set KEY=V1,V2,...``: the dotted key and its values, in the order given."""

    key: str
    values: tuple


def parse_set(text: str, *, many: bool = True) -> Override:
    """Parse ``KEY=V1,V2,...`` (``many=False``: exactly one value, commas kept in it)."""
    key, sep, rest = str(text).partition("=")
    key = key.strip()
    if not sep:
        raise OverrideError(_short(key), f"must be KEY=VALUE{',VALUE...' if many else ''}, got {_short(text)!r}")
    if not _KEY_RE.match(key):
        raise OverrideError(_short(key), "the key must be a dotted path of field names (and list "
                            "indices), e.g. robots.margin or sim.kp")
    pieces = _split(rest) if many else [rest]
    if len(pieces) > _MAX_VALUES:
        raise OverrideError(key, f"at most {_MAX_VALUES} values, got {len(pieces)}")
    values = tuple(_scalar(key, p) for p in pieces)
    if len(set(map(_identity, values))) != len(values):
        raise OverrideError(key, f"a value is given twice in {_short(rest)!r}")
    return Override(key, values)


def combinations(overrides: Sequence[Override]) -> list[dict[str, Any]]:
    """Every combination of the overrides' values, the last key varying fastest.

    ``[]`` gives one empty combination (no settings); a key given twice is
    an error.
    """
    keys = [o.key for o in overrides]
    for key in keys:
        if keys.count(key) > 1:
            raise OverrideError(key, "is given twice; list all its values in one --set")
    return [dict(zip(keys, combo)) for combo in itertools.product(*(o.values for o in overrides))]


def apply_overrides(doc: dict, overrides: Mapping[str, Any] | Iterable[tuple[str, Any]]) -> dict:
    """A copy of the YAML document ``doc`` with each ``key: value`` set.

    Missing mappings on the way are created (``sim.kp`` in a file without
    ``sim:``); a list item must exist.  Raises :class:`OverrideError` when a
    path runs through something that is neither a mapping nor a list.
    """
    items = overrides.items() if isinstance(overrides, Mapping) else overrides
    doc = _copy(doc)
    for key, value in items:
        node, parts = doc, key.split(".")
        for depth, part in enumerate(parts):
            last = depth == len(parts) - 1
            where = ".".join(parts[:depth]) or "the document"
            if isinstance(node, list):
                if not part.isdigit() or int(part) >= len(node):
                    raise OverrideError(key, f"{where} is a list of {len(node)}; {part!r} is not an index in it")
                index: Any = int(part)
            elif isinstance(node, dict):
                index = part
            else:
                raise OverrideError(key, f"{where} is {_kind(node)}, not a mapping")
            if last:
                node[index] = value
            else:
                if isinstance(node, dict) and node.get(index) is None:
                    node[index] = {}
                node = node[index]
    return doc


def blame(exc: ScenarioError, overrides: Mapping[str, Any]) -> ScenarioError:
    """The error ``exc`` of a scenario read with ``overrides``, naming the option when one caused it.

    An error about a field that an override sets (or about a key on an
    override's path, such as a misspelt one) becomes an
    :class:`OverrideError`; any other error is returned as it is.
    """
    if isinstance(exc, OverrideError):
        return exc
    field = getattr(exc, "field", "") or ""
    for key in overrides:
        if _on_path(field, key):
            reason = exc.reason
            if reason.startswith("unknown key"):
                parent, _, last = field.rpartition(".")
                where = f" in {parent}" if parent else ""
                return OverrideError(key, f"unknown key {last!r}{where}{reason[len('unknown key'):]}")
            if field == key:
                return OverrideError(key, reason)
            return OverrideError(key, f"{field}: {reason}")
    return exc


def _on_path(field: str, key: str) -> bool:
    """Whether a checker's field (``a.b``, ``a.b[0]``) lies on the override ``key`` or under it."""
    norm = re.sub(r"\[(\d+)\]", r".\1", field)
    return bool(norm) and (norm == key or key.startswith(norm + ".") or norm.startswith(key + "."))


def _split(text: str) -> list[str]:
    """Split at commas outside brackets and quotes (so a bad list is named as one value)."""
    pieces, depth, quote, cur = [], 0, None, []
    for ch in text:
        if quote:
            quote = None if ch == quote else quote
        elif ch in "'\"":
            quote = ch
        elif ch in "[{":
            depth += 1
        elif ch in "]}":
            depth -= 1
        elif ch == "," and depth <= 0:
            pieces.append("".join(cur))
            cur = []
            continue
        cur.append(ch)
    pieces.append("".join(cur))
    return pieces


def _scalar(key: str, text: str):
    text = text.strip()
    if not text:
        raise OverrideError(key, "a value is empty")
    try:
        value = load_yaml(text)  # the file rules: no anchors, aliases or foreign tags
    except YamlRefused as exc:
        raise OverrideError(key, f"value {_short(text)!r}: {exc.reason}") from None
    if isinstance(value, str) and _NUMBER_RE.match(text):
        value = float(text)  # YAML 1.1 reads 1e-3 as a string; here it is a number
    if isinstance(value, float) and not math.isfinite(value):
        raise OverrideError(key, f"value {_short(text)!r} is not finite")
    if isinstance(value, (list, dict)):
        raise OverrideError(key, f"values must be YAML scalars (numbers, true/false, null, text), "
                            f"got {_kind(value)} in {_short(text)!r}")
    if not isinstance(value, (str, int, float, bool)) and value is not None:
        raise OverrideError(key, f"value {_short(text)!r} is {type(value).__name__}; give a number, "
                            "true/false, null or text")
    return value


def _identity(value) -> tuple:
    return (type(value).__name__ if isinstance(value, (bool, type(None), str)) else "number", value)


def _copy(value):
    if isinstance(value, dict):
        return {k: _copy(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_copy(v) for v in value]
    return value


def _kind(value) -> str:
    if value is None:
        return "null"
    if isinstance(value, bool):
        return f"the boolean {str(value).lower()}"
    if isinstance(value, (int, float)):
        return f"the number {value!r}"
    if isinstance(value, str):
        return f"the text {_short(value)!r}"
    if isinstance(value, list):
        return f"a list of {len(value)}"
    return type(value).__name__


def _short(text) -> str:
    text = str(text)
    return text if len(text) <= _MAX_TEXT else text[: _MAX_TEXT - 3] + "..."
