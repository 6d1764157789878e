"""Command-line value parsers shared by the subcommands (argparse ``type=``)."""

from __future__ import annotations

import argparse
import math
from typing import Callable

__all__ = ["int_at_least", "int_in", "seconds"]


def int_at_least(low: int, high: int = 2**63 - 1) -> Callable[[str], int]:
    """A parser for integers ``>= low`` (and at most ``high``)."""

    def parse(value: str) -> int:
        text = value.strip()
        if len(text) > 40 or not text.lstrip("+-").isdigit():
            raise argparse.ArgumentTypeError(f"must be an integer >= {low}, got {_short(value)}")
        v = int(text)
        if v < low:
            raise argparse.ArgumentTypeError(f"must be an integer >= {low}, got {v}")
        if v > high:
            raise argparse.ArgumentTypeError(f"must be an integer in [{low}, {high}], got {v}")
        return v

    return parse


MAX_SECONDS = 3600.0
"""The longest time limit an option takes [s] (the same as planner.time_limit's range)."""


def seconds(value: str) -> float:
    """A finite number of seconds in ``(0, 3600]``."""
    try:
        v = float(value) if len(value) <= 40 else math.nan
    except ValueError:
        v = math.nan
    if not (math.isfinite(v) and 0 < v <= MAX_SECONDS):
        raise argparse.ArgumentTypeError(f"must be a number of seconds in (0, {MAX_SECONDS:g}], got {_short(value)}")
    return v


def int_in(low: int, high: int) -> Callable[[str], int]:
    """A parser for integers in ``[low, high]``; the value is echoed cut to 40 characters."""

    def parse(value: str) -> int:
        text = value.strip()
        if len(text) > 40 or not text.lstrip("+-").isdigit():
            raise argparse.ArgumentTypeError(f"must be an integer in [{low}, {high}], got {_short(value)}")
        v = int(text)
        if not low <= v <= high:
            raise argparse.ArgumentTypeError(f"must be an integer in [{low}, {high}], got {v}")
        return v

    return parse


def _short(value: str, limit: int = 40) -> str:
    r = repr(value)
    return r if len(r) <= limit else r[: limit - 4] + "...'"
