"""MovingAI scenario files (``.scen``): the start and goal cells of the first N agents.

Format: the first line is ``version 1`` (or ``version 1.0``; older files leave it
out), then one agent a line, tab-separated: ``bucket map width height start_x start_y goal_x goal_y
optimal_length``, where x is the column and y the row counted from the top.
Only the first ``count`` agents' lines are parsed; the file is read only when
it is a regular file of at most :data:`MAX_SCEN_BYTES`.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from .maps import MAX_SIDE_CELLS, Grid, MapError, _name, _text

__all__ = ["MAX_SCEN_BYTES", "read_scen"]

MAX_SCEN_BYTES = 4 << 20
"""The largest ``.scen`` file read [bytes] (a benchmark scen of 1000 agents is about 60 KiB)."""

_INT = re.compile(r"[0-9]{1,9}")


def read_scen(path: Path, count: int, grid: Grid | None, goal: bool) -> np.ndarray:
    """``(count, 2)`` integer ``(col, row)`` cells: the agents' starts, or goals when ``goal``.

    Checks each parsed line's fields, that its width and height match
    ``grid`` (when given), that its cells lie on the grid and are free.
    Raises :class:`MapError` naming the file and the line.
    """
    name = _name(path)
    lines = _text(path, MAX_SCEN_BYTES).split("\n")
    first = lines[0].strip() if lines else ""
    body = 1
    if not re.fullmatch(r"version\s+1(\.0)?", first, re.IGNORECASE):
        if len(_fields(first)) != 9:
            raise MapError(f"{name} line 1: expected 'version 1' (a MovingAI .scen file), got {first[:30]!r}")
        body = 0  # no version line (older files): the agents start on line 1
    out = np.zeros((count, 2), np.int64)
    k = 0
    for i, raw in enumerate(lines[body:], start=body + 1):
        if k == count:
            break
        line = raw.rstrip("\r")
        if not line.strip():
            continue
        parts = _fields(line)
        if len(parts) != 9:
            raise MapError(f"{name} line {i}: has {len(parts)} fields, expected 9 (bucket, map, width, height, "
                           "start_x, start_y, goal_x, goal_y, optimal_length)")
        ints = []
        for field, text in zip(("bucket", "width", "height", "start_x", "start_y", "goal_x", "goal_y"),
                               (parts[0], *parts[2:8])):
            if not _INT.fullmatch(text.strip()):
                raise MapError(f"{name} line {i}: {field} must be a whole number, got {text.strip()[:20]!r}")
            ints.append(int(text))
        _, width, height, sx, sy, gx, gy = ints
        if not (1 <= width <= MAX_SIDE_CELLS and 1 <= height <= MAX_SIDE_CELLS):
            raise MapError(f"{name} line {i}: map size {width} x {height} is out of range")
        if grid is not None and (width, height) != (grid.cols, grid.rows):
            raise MapError(f"{name} line {i}: is for a {width} x {height} map, but the map is "
                           f"{grid.cols} x {grid.rows} (width x height)")
        x, y = (gx, gy) if goal else (sx, sy)
        what = "goal" if goal else "start"
        if not (x < width and y < height):
            raise MapError(f"{name} line {i}: {what} cell ({x}, {y}) lies outside the {width} x {height} map")
        if grid is not None and grid.blocked[y, x]:
            raise MapError(f"{name} line {i}: {what} cell ({x}, {y}) (column, row from the top) is blocked "
                           "in the map")
        out[k] = (x, y)
        k += 1
    if k < count:
        raise MapError(f"{name}: holds {k} agents, fewer than the count {count} asked for", "count")
    return out


def _fields(line: str) -> list[str]:
    """The fields of one agent line: tab-separated, or by any whitespace when it has no tab."""
    return line.split("\t") if "\t" in line else line.split()
