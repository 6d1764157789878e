"""Command-line value parsers shared by the subcommands (argparse ``type=``)."""

from __future__ import annotations

import argparse
import math
from typing import Callable

__all__ = ["int_at_least", "seconds"]


def int_at_least(low: int) -> Callable[[str], int]:
    """A parser for integers ``>= low``."""

    def parse(value: str) -> int:
        try:
            v = int(value)
        except ValueError:
            raise argparse.ArgumentTypeError(f"must be an integer >= {low}, got {value!r}") from None
        if v < low:
            raise argparse.ArgumentTypeError(f"must be an integer >= {low}, got {v}")
        return v

    return parse


def seconds(value: str) -> float:
    """A finite number of seconds > 0."""
    try:
        v = float(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a number of seconds > 0, got {value!r}") from None
    if not math.isfinite(v) or v <= 0:
        raise argparse.ArgumentTypeError(f"must be a finite number of seconds > 0, got {value}")
    return v
