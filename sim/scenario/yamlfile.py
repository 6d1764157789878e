"""Strict, bounded YAML: what a scenario file may use, checked before anything is built.

:func:`load_yaml` first walks the document's parse events (libyaml's parser
when PyYAML has it, which is iterative), and refuses, at the first offending
event and before any node is built:

* an anchor (``&name``) or an alias (``*name``): aliases are how a few
  hundred bytes expand to gigabytes ("billion laughs"), and no scenario
  needs them;
* nesting deeper than :data:`MAX_DEPTH` mappings and lists;
* any explicit tag other than YAML's own ``!!str``, ``!!int``, ``!!float``,
  ``!!bool``, ``!!null``, ``!!seq`` and ``!!map`` (``!!python/...`` tags
  are never constructed, let alone executed).

Only then is the document built, with PyYAML's safe constructors plus two
rules: a mapping may not repeat a key, and its keys must be plain values;
an integer literal of more than 40 characters becomes a
:class:`planner.inputfile.HugeInt` (Python refuses to convert more than
4300 digits) so that the reader can name the field that holds it.
"""

from __future__ import annotations

import re

import yaml

from planner.inputfile import HugeInt, echo

__all__ = ["MAX_DEPTH", "YamlRefused", "load_yaml"]

MAX_DEPTH = 32
"""The deepest nesting of mappings and lists a scenario file may have."""

_CORE_TAGS = frozenset(
    "tag:yaml.org,2002:" + t for t in ("str", "int", "float", "bool", "null", "seq", "map")
)
_Parser = getattr(yaml, "CSafeLoader", None) or yaml.SafeLoader


class YamlRefused(ValueError):
    """A document that is not loaded: ``where`` is ``line L, column C`` or ``yaml``."""

    def __init__(self, where: str, reason: str):
        self.where, self.reason = where, reason
        super().__init__(f"{where}: {reason}")


def load_yaml(text: str):
    """The document in ``text``, or :class:`YamlRefused` naming where and why."""
    try:
        _check_events(text)
        return yaml.load(text, Loader=_StrictLoader)  # noqa: S506 - a SafeLoader subclass
    except yaml.reader.ReaderError as exc:  # a character YAML does not allow
        line = text.count("\n", 0, exc.position) + 1
        column = exc.position - (text.rfind("\n", 0, exc.position) + 1) + 1
        raise YamlRefused(f"line {line}, column {column}",
                          f"invalid YAML: the character U+{_code(exc.character):04X} is not allowed") from None
    except yaml.YAMLError as exc:
        where = _where(getattr(exc, "problem_mark", None))
        problem = getattr(exc, "problem", None) or str(exc)
        raise YamlRefused(where, f"invalid YAML: {_short(problem)}") from None


def _code(character) -> int:
    return character if isinstance(character, int) else ord(character)


def _where(mark) -> str:
    return f"line {mark.line + 1}, column {mark.column + 1}" if mark is not None else "yaml"


def _short(text, limit: int = 100) -> str:
    text = " ".join(str(text).split())
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _check_events(text: str) -> None:
    depth = 0
    for ev in yaml.parse(text, Loader=_Parser):
        if isinstance(ev, yaml.AliasEvent):
            raise YamlRefused(_where(ev.start_mark), "aliases (*name) are not allowed in a scenario file")
        if getattr(ev, "anchor", None) is not None:
            raise YamlRefused(_where(ev.start_mark), "anchors (&name) are not allowed in a scenario file")
        tag = getattr(ev, "tag", None)
        if tag is not None and tag not in _CORE_TAGS:
            raise YamlRefused(
                _where(ev.start_mark),
                f"the tag {echo(tag.replace('tag:yaml.org,2002:', '!!'), 50)[7:]} is not allowed "
                "(only YAML's own str, int, float, bool, null, seq and map)",
            )
        if isinstance(ev, (yaml.MappingStartEvent, yaml.SequenceStartEvent)):
            depth += 1
            if depth > MAX_DEPTH:
                raise YamlRefused(_where(ev.start_mark), f"nesting deeper than {MAX_DEPTH} levels")
        elif isinstance(ev, (yaml.MappingEndEvent, yaml.SequenceEndEvent)):
            depth -= 1


class _StrictLoader(_Parser):
    pass


def _construct_mapping(loader, node, deep=False):
    seen = set()
    for key_node, _ in node.value:
        key = loader.construct_object(key_node, deep=deep)
        try:
            hash(key)
        except TypeError:
            raise yaml.constructor.ConstructorError(
                None, None, "a mapping key must be a plain value, not a list or mapping", key_node.start_mark
            ) from None
        if key in seen:
            raise yaml.constructor.ConstructorError(
                None, None, f"duplicate key {echo(key, 50).removeprefix('string ')}", key_node.start_mark
            )
        seen.add(key)
    return yaml.SafeLoader.construct_mapping(loader, node, deep)


def _construct_int(loader, node):
    value = loader.construct_scalar(node)
    if len(value) > 40:
        return HugeInt(value)
    return yaml.SafeLoader.construct_yaml_int(loader, node)


# Numbers are written in decimal, with an optional fraction and exponent, and nothing else:
# YAML 1.1 also reads 017 as 15 (octal), 0x1F as 31, 1_000 as 1000 and 1:30 as 90
# (sexagesimal), which changes a value without a word, and it reads 1e3 as text.  Here
# those forms stay text, so the field that receives one says it wants a number.
_INT, _FLOAT = "tag:yaml.org,2002:int", "tag:yaml.org,2002:float"
_StrictLoader.yaml_implicit_resolvers = {
    first: [(tag, rx) for tag, rx in resolvers if tag not in (_INT, _FLOAT)]
    for first, resolvers in yaml.SafeLoader.yaml_implicit_resolvers.items()
}
_StrictLoader.add_implicit_resolver(_INT, re.compile(r"^[-+]?(?:0|[1-9][0-9]*)$"), list("-+0123456789"))
_StrictLoader.add_implicit_resolver(
    _FLOAT,
    re.compile(r"^(?:[-+]?(?:(?:0|[1-9][0-9]*)(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][-+]?[0-9]+)?|[-+]?\.(?:inf|Inf|INF)|\.(?:nan|NaN|NAN))$"),
    list("-+0123456789."),
)
_StrictLoader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, _construct_mapping)
_StrictLoader.add_constructor("tag:yaml.org,2002:int", _construct_int)
