"""Exact refusals and boundaries of the strict YAML loader (sim/scenario/yamlfile.py).

Each test pins what a user reads: where (line and column) and why a document is
refused, and the limits (nesting depth, integer length) at their exact edge.
"""

import pytest
import yaml

from planner.inputfile import HugeInt
from sim.scenario.yamlfile import MAX_DEPTH, YamlRefused, _code, _short, _where, load_yaml


def refused(text):
    with pytest.raises(YamlRefused) as e:
        load_yaml(text)
    return e.value


def test_plain_documents_load():
    assert load_yaml("a: 1\nb: [x, 2.5, true, null]\n") == {"a": 1, "b": ["x", 2.5, True, None]}
    assert load_yaml("!!str 12") == "12"
    assert load_yaml("!!map {a: !!int '3'}") == {"a": 3}
    assert load_yaml("") is None


def test_nesting_is_allowed_to_the_cap_and_refused_past_it():
    assert MAX_DEPTH == 32
    assert load_yaml("[" * 32 + "]" * 32) is not None
    e = refused("[" * 33 + "]" * 33)
    assert (e.where, e.reason) == ("line 1, column 33", "nesting deeper than 32 levels")
    assert str(e) == "line 1, column 33: nesting deeper than 32 levels"
    # closing lists lowers the depth again: many shallow lists side by side are fine
    assert load_yaml("[" + ", ".join(["[[1]]"] * 40) + "]") is not None
    deep_map = "".join("  " * i + f"k{i}:\n" for i in range(32)) + "  " * 32 + "v"
    assert load_yaml(deep_map) is not None
    e = refused("".join("  " * i + f"k{i}:\n" for i in range(33)) + "  " * 33 + "v")
    assert e.reason == "nesting deeper than 32 levels"
    assert e.where == "line 33, column 65"


def test_aliases_and_anchors_are_refused_where_they_are():
    e = refused("a: &x 1\nb: 2\n")
    assert (e.where, e.reason) == ("line 1, column 4", "anchors (&name) are not allowed in a scenario file")
    e = refused("a: 1\nb: *x\n")
    assert (e.where, e.reason) == ("line 2, column 4", "aliases (*name) are not allowed in a scenario file")


def test_only_the_core_tags_are_allowed():
    e = refused("a: !!python/object:os.system x\n")
    assert e.where == "line 1, column 4"
    assert e.reason == (
        "the tag '!!python/object:os.system' is not allowed (only YAML's own str, int, float, bool, "
        "null, seq and map)"
    )
    e = refused("a: !mine x\n")
    assert e.reason.startswith("the tag '!mine' is not allowed")
    e = refused("a: !!binary aGVsbG8=\n")
    assert e.reason.startswith("the tag '!!binary' is not allowed")
    e = refused("a: !" + "t" * 200 + " x\n")
    assert e.reason.startswith("the tag '!ttttttttt...' (201 characters) is not allowed")
    for tag in ("str", "int", "float", "bool", "null", "seq", "map"):
        value = {"str": "x", "int": "1", "float": "1.5", "bool": "true", "null": "~", "seq": "[1]",
                 "map": "{a: 1}"}[tag]
        load_yaml(f"a: !!{tag} {value}\n")


def test_duplicate_and_unhashable_keys_are_refused():
    e = refused("a: 1\nb: 2\na: 3\n")
    assert (e.where, e.reason) == ("line 3, column 1", "invalid YAML: duplicate key 'a'")
    e = refused("? [1, 2]\n: x\n")
    assert e.where == "line 1, column 3"
    assert e.reason == "invalid YAML: a mapping key must be a plain value, not a list or mapping"
    e = refused("1: a\n1: b\n")
    assert e.reason == "invalid YAML: duplicate key number 1"
    assert load_yaml("a: {b: 1}\nc: {b: 2}\n") == {"a": {"b": 1}, "c": {"b": 2}}


def test_nested_mappings_are_built_deep():
    doc = load_yaml("a:\n  b: [1, {c: 2}]\n")
    assert doc == {"a": {"b": [1, {"c": 2}]}}


def test_integers_longer_than_forty_characters_become_huge_ints():
    assert load_yaml("n: " + "9" * 40) == {"n": int("9" * 40)}
    n = load_yaml("n: " + "9" * 41)["n"]
    assert isinstance(n, HugeInt) and n.digits == 41
    n = load_yaml("n: -" + "1" * 5000)["n"]
    assert isinstance(n, HugeInt) and (n.negative, n.digits) == (True, 5000)
    assert load_yaml("n: 0x1F") == {"n": "0x1F"}  # not a decimal number: text


@pytest.mark.parametrize("text, silently", [
    ("017", 15), ("0x1F", 31), ("1_000", 1000), ("1:30", 90), ("0o17", "0o17"), ("00.5", 0.5), ("1:00", 60),
])
def test_only_decimal_and_exponent_forms_are_numbers(text, silently):
    """YAML 1.1's octal, hex, underscore and sexagesimal forms stay text, so the field refuses them."""
    import yaml

    assert load_yaml(f"v: {text}") == {"v": text}
    # the negative control: PyYAML's own safe loader changes these values without a word
    if not isinstance(silently, str):
        assert yaml.safe_load(f"v: {text}") == {"v": silently}


@pytest.mark.parametrize("text, value", [
    ("0", 0), ("-7", -7), ("+7", 7), ("12", 12), ("0.5", 0.5), (".5", 0.5), ("1.", 1.0), ("1e3", 1000.0),
    ("-2.5E-3", -0.0025), ("1.0e+3", 1000.0), (".inf", float("inf")), ("-.inf", float("-inf")),
])
def test_decimal_and_exponent_forms_are_numbers(text, value):
    assert load_yaml(f"v: {text}") == {"v": value}


def test_syntax_errors_name_line_column_and_problem():
    e = refused("a: [1, 2\nb: 3\n")
    assert e.where == "line 2, column 2"
    if yaml.__with_libyaml__:  # the events are read by libyaml, so its wording
        assert e.reason == "invalid YAML: did not find expected ',' or ']'"
    else:
        assert e.reason.startswith("invalid YAML: ") and "expected ',' or ']'" in e.reason
    e = refused("a: 'x\n")
    assert e.reason == "invalid YAML: found unexpected end of stream"
    assert e.where == "line 2, column 1"


def test_forbidden_characters_are_named_with_their_place():
    e = refused("a: 1\nb: x\x07y\n")
    assert (e.where, e.reason) == ("line 2, column 5", "invalid YAML: the character U+0007 is not allowed")
    e = refused("\x00")
    assert (e.where, e.reason) == ("line 1, column 1", "invalid YAML: the character U+0000 is not allowed")


def test_helpers():
    assert _code("A") == 65 and _code(65) == 65

    class Mark:
        line, column = 4, 9

    assert _where(Mark()) == "line 5, column 10"
    assert _where(None) == "yaml"
    assert _short("a \n  b") == "a b"
    assert _short("x" * 100) == "x" * 100
    assert _short("x" * 101) == "x" * 97 + "..."
    assert _short(12) == "12"


def test_closing_a_list_lowers_the_depth_by_one():
    # 31 open, one more opened and closed, then two more: 33 deep
    e = refused("[" * 31 + "[], [[1]]" + "]" * 31)
    assert e.reason == "nesting deeper than 32 levels"
    assert load_yaml("[" * 31 + "[], [1]" + "]" * 31) is not None


def test_long_duplicate_keys_are_cut():
    key = "k" * 60
    e = refused(f"{key}: 1\n{key}: 2\n")
    assert e.reason == "invalid YAML: duplicate key 'kkkkkkkkkk...' (60 characters)"


def test_the_place_of_a_bad_character_counts_every_line_before_it():
    e = refused("\n\na: 1\nb: 2\nc: x\x07\nd: 1\ne: 2\n")
    assert e.where == "line 5, column 5"
    e = refused("\nab\x07\n")
    assert e.where == "line 2, column 3"
