"""The scenario room: a YAML file in, a checked :class:`Scenario` and a :class:`planner.Problem` out.

Modules, in the order a file meets them: ``yamlfile`` (strict YAML), ``overrides``
(``--set KEY=VALUE``), ``reader`` (the top level) with ``fields`` (the typed field
reader), ``obstacles``, ``formation_fields`` and ``settings`` (``planner:``,
``sim:``, ``render:``), ``model`` (the frozen specs) and ``params`` (the run's
settings), then ``build`` (the problem), ``placements`` and ``glyphs`` (shapes and
text).  Nothing here imports the physics or the output rooms.
"""

from ..lazy import lazy_exports

_WHERE = {
    **dict.fromkeys(("FormationSpec", "MAX_FILE_BYTES", "PaperRef", "RandomObstacles", "Scenario", "ScenarioError"),
                    "model"),
    **dict.fromkeys(("MAX_TARGETS", "read_scenario"), "reader"),
    "MAX_HOLD": "formation_fields",
    **dict.fromkeys(("build_legs", "build_problem"), "build"),
}

__all__ = sorted(_WHERE, key=str.lower)

__getattr__, __dir__ = lazy_exports(__name__, _WHERE)
