"""The run's settings that are not the defaults: what the run page's settings table lists.

:func:`non_defaults` compares a scenario's planner, sim and render
parameters (:class:`planner.PlannerParams`, :class:`sim.scenario.params.SimParams`,
:class:`sim.scenario.params.RenderParams`) with their defaults, field by
field; nested parameter records are flattened (``sim.noise.position``).  The
run report keeps the result under ``non_defaults`` and the ``--set`` values
under ``settings``; :func:`settings_rows` turns both into table rows.
"""

from __future__ import annotations

import dataclasses
import math

__all__ = ["non_defaults", "settings_rows"]

_VALUE_CHARS = 160  # the longest value shown in the table


def _plain(v):
    """``v`` as JSON-ready data: dataclasses as dicts, tuples as lists."""
    if dataclasses.is_dataclass(v) and not isinstance(v, type):
        return {f.name: _plain(getattr(v, f.name)) for f in dataclasses.fields(v)}
    if isinstance(v, (list, tuple)):
        return [_plain(x) for x in v]
    if isinstance(v, dict):
        return {str(k): _plain(x) for k, x in v.items()}
    if isinstance(v, float) and not math.isfinite(v):
        return str(v)
    if hasattr(v, "item") and callable(v.item):  # a numpy scalar
        return v.item()
    return v


def _diff(prefix: str, value, default, out: dict) -> None:
    if dataclasses.is_dataclass(value) and type(value) is type(default):
        for f in dataclasses.fields(value):
            _diff(f"{prefix}.{f.name}", getattr(value, f.name), getattr(default, f.name), out)
    elif _plain(value) != _plain(default):
        out[prefix] = _plain(value)


def non_defaults(scenario) -> dict:
    """``{"planner.g": 4, "sim.noise.position": 0.01, ...}``: every parameter that differs from its default.

    scenario: anything with ``planner``, ``sim`` and ``render`` parameter
    dataclasses (a :class:`sim.scenario.Scenario`); a missing one is skipped.
    """
    out: dict = {}
    for name in ("planner", "sim", "render"):
        params = getattr(scenario, name, None)
        if params is None or not dataclasses.is_dataclass(params):
            continue
        try:
            default = type(params)()
        except TypeError:  # no defaults to compare with
            continue
        _diff(name, params, default, out)
    return out


def _text(v) -> str:
    if isinstance(v, bool):
        return "yes" if v else "no"
    if v is None:
        return "auto / none"
    if isinstance(v, float):
        return f"{v:.6g}"
    if isinstance(v, (list, dict)):
        import json

        text = json.dumps(v, separators=(", ", ": "))
    else:
        text = str(v)
    return text if len(text) <= _VALUE_CHARS else text[: _VALUE_CHARS - 3] + "..."


def settings_rows(report: dict) -> list[tuple[str, str, str]]:
    """``(setting, value, where from)`` rows: the ``--set`` values first, then the other non-defaults.

    report: the run report; ``settings`` holds the ``--set`` values (scenario
    keys such as ``robots.margin``), ``non_defaults`` the parameters that
    differ from their defaults.  A parameter both set and non-default is
    listed once, as set.  Old reports without these keys give no rows.
    """
    sets = report.get("settings")
    sets = sets if isinstance(sets, dict) else {}
    other = report.get("non_defaults")
    other = other if isinstance(other, dict) else {}
    rows = [(str(k), _text(v), "--set") for k, v in sets.items()]
    rows += [(str(k), _text(v), "scenario file") for k, v in other.items() if k not in sets]
    return rows
