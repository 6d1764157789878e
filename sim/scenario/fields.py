"""The typed field reader every scenario section uses: numbers, integers, pairs, points, mappings.

Each check fails with a :class:`ScenarioError` naming the file, the field and the
reason, echoing the value received in at most about 80 characters.
"""

from __future__ import annotations

import math
import re
from typing import Any

from planner.inputfile import echo, echo_key

from .model import _MAX_SEED, ScenarioError

__all__: list[str] = []  # private to the scenario room


class _Reader:
    def __init__(self, path: str):
        self.path = path

    def fail(self, field: str, reason: str):
        raise ScenarioError(self.path, field, reason)

    def mapping(self, value, field: str, allowed: tuple[str, ...]) -> dict:
        if value is None:
            value = {}
        if not isinstance(value, dict):
            self.fail(field, f"must be a mapping, got {_kind(value)}")
        for key in value:
            if key not in allowed:
                hint = ", ".join(allowed)
                where = f"{field}.{echo_key(key)}" if field else echo_key(key)
                self.fail(where, f"unknown key; allowed here: {hint}")
        return value

    def number(self, value, field, *, gt=None, ge=None, le=None, lt=None) -> float:
        """A finite number (not a boolean) within the given bounds."""
        span = _span(gt, ge, le, lt)
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            self.fail(field, f"must be a number{span}, got {_kind(value)}{_numeric_text_hint(value)}")
        if isinstance(value, int) and value.bit_length() > 1000:
            self.fail(field, f"must be a number{span}, got {_kind(value)}")
        value = float(value)
        if not math.isfinite(value):
            self.fail(field, f"must be a finite number{span}, got {value}")
        if ((gt is not None and not value > gt) or (ge is not None and not value >= ge)
                or (le is not None and not value <= le) or (lt is not None and not value < lt)):
            self.fail(field, f"must be a number{span}, got {value:g}")
        return value

    def integer(self, value, field, *, ge=None, le=None) -> int:
        """An integer (not a boolean, not a float) within ``[ge, le]``."""
        span = _span(None, ge, le, None)
        if isinstance(value, bool) or not isinstance(value, int):
            self.fail(field, f"must be an integer{span}, got {_kind(value)}")
        if (ge is not None and value < ge) or (le is not None and value > le):
            self.fail(field, f"must be an integer{span}, got {_kind(value).removeprefix('number ')}")
        return int(value)

    def int_or_auto(self, value, field, *, ge=1, le=None) -> int | None:
        if value == "auto":
            return None
        if isinstance(value, bool) or not isinstance(value, int):
            self.fail(field, f"must be 'auto' or an integer{_span(None, ge, le, None)}, got {_kind(value)}")
        return self.integer(value, field, ge=ge, le=le)

    def boolean(self, value, field) -> bool:
        if not isinstance(value, bool):
            self.fail(field, f"must be true or false, got {_kind(value)}")
        return value

    def pair(self, value, field, **bounds) -> tuple[float, float]:
        """``[x, y]``: two numbers, each within ``bounds`` (as for :meth:`number`)."""
        if not isinstance(value, (list, tuple)) or len(value) != 2:
            self.fail(field, f"must be a pair [x, y], got {_kind(value)}")
        return (
            self.number(value[0], f"{field}[0]", **bounds),
            self.number(value[1], f"{field}[1]", **bounds),
        )

    def inside(self, value, field, width, height) -> tuple[float, float]:
        """A point ``[x, y]`` of the workspace ``[0, width] x [0, height]``."""
        x, y = self.pair(value, field)
        if not (0 <= x <= width and 0 <= y <= height):
            self.fail(field, f"({x:g}, {y:g}) lies outside the {width:g} x {height:g} workspace")
        return x, y


def _bound(v) -> str:
    return "2^63 - 1" if v == _MAX_SEED else f"{v:g}"


def _span(gt, ge, le, lt) -> str:
    """`` in [a, b]``, `` > a`` and the like: the allowed range, for a message."""
    low = f"({_bound(gt)}" if gt is not None else f"[{_bound(ge)}" if ge is not None else None
    high = f"{_bound(le)}]" if le is not None else f"{_bound(lt)})" if lt is not None else None
    if low and high:
        return f" in {low}, {high}"
    if low:
        return f" {'>' if gt is not None else '>='} {low[1:]}"
    if high:
        return f" {'<=' if le is not None else '<'} {high[:-1]}"
    return ""


def _numeric_text_hint(value) -> str:
    """For text that reads as a number (YAML takes ``1e3`` for text): how to write it."""
    if isinstance(value, str) and len(value) <= 40:
        try:
            float(value)
        except ValueError:
            return ""
        if re.fullmatch(r"\s*[-+]?(?:(?:0|[1-9][0-9]*)(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][-+]?[0-9]+)?\s*", value):
            return " (text; write a number such as 1.0e+3 without quotes)"
        if value.strip().lower().lstrip("+-") in ("inf", "infinity", "nan"):
            return ""
        return " (numbers are written in decimal only: 1000, 0.5, 1.0e+3)"
    return ""


def _kind(value: Any) -> str:
    """The value received, for a message: at most about 80 characters."""
    return echo(value)
