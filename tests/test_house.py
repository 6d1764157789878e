"""The house: rooms of sim/ import one way, no import cycle, no module over 400 lines."""

import ast
from pathlib import Path

import networkx as nx
import pytest

ROOT = Path(__file__).resolve().parents[1]
MAX_LINES = 400
# sim's rooms from the bottom up: a room may import the rooms below it, never above.
ROOMS = ["scenario", "execute", "output", "tune"]
# shared leaves of sim/ that every room may use (they import no room)
LEAVES = {"sim.errors", "sim.words", "sim.stops", "sim.lazy", "sim.argtypes", "sim.progress", "sim._pygame"}


def _module(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def import_graph(packages=("planner", "sim")) -> nx.DiGraph:
    """Module -> module edges of every import (function-level ones too) inside ``packages``."""
    g = nx.DiGraph()
    files = [p for pkg in packages for p in sorted((ROOT / pkg).rglob("*.py"))]
    known = {_module(p) for p in files}
    for path in files:
        mod = _module(path)
        g.add_node(mod)
        is_pkg = path.name == "__init__.py"
        for node in ast.walk(ast.parse(path.read_text())):
            targets = []
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                if node.level:
                    base = mod.split(".") if is_pkg else mod.split(".")[:-1]
                    base = base[: len(base) - (node.level - 1)]
                    stem = ".".join(base + ([node.module] if node.module else []))
                else:
                    stem = node.module or ""
                targets = [stem] + [f"{stem}.{a.name}" for a in node.names]
            for t in targets:
                while t and t not in known:
                    t = t.rpartition(".")[0]
                if t and t != mod and t.partition(".")[0] in packages:
                    g.add_edge(mod, t)
    return g


def _room(mod: str) -> str | None:
    parts = mod.split(".")
    return parts[1] if len(parts) > 1 and parts[0] == "sim" and parts[1] in ROOMS else None


def wrong_way(g: nx.DiGraph) -> list[tuple[str, str]]:
    """Imports that run up: a room importing a room above it, the top of sim/, or a leaf importing a room."""
    bad = []
    for a, b in g.edges:
        ra, rb = _room(a), _room(b)
        if a.startswith("planner") and b.startswith("sim"):
            bad.append((a, b))
        elif ra and rb and ROOMS.index(rb) > ROOMS.index(ra):
            bad.append((a, b))
        elif ra and b.startswith("sim") and rb is None and b not in LEAVES and b != "sim":
            bad.append((a, b))  # a room importing runner, cli or check
        elif a in LEAVES and (rb or b in ("sim.runner", "sim.cli")):
            bad.append((a, b))
    return bad


def test_no_import_cycle():
    g = import_graph()
    # a package importing its own submodules lazily is not a cycle of the house
    g.remove_edges_from([(a, b) for a, b in list(g.edges) if b.startswith(a + ".") or a.startswith(b + ".")])
    cycles = list(nx.simple_cycles(g))
    assert cycles == [], cycles[:5]


def test_rooms_import_one_way():
    assert wrong_way(import_graph()) == []


def test_the_checks_catch_a_wrong_way_import_and_a_cycle():
    # Negative controls: an edge from the scenario room up to output, and a two-module cycle.
    g = import_graph()
    g.add_edge("sim.scenario.reader", "sim.output.render")
    assert ("sim.scenario.reader", "sim.output.render") in wrong_way(g)
    g.add_edge("sim.execute.world", "sim.execute.physics")
    g.add_edge("sim.execute.physics", "sim.execute.world")
    assert any(set(c) == {"sim.execute.world", "sim.execute.physics"} for c in nx.simple_cycles(g))


@pytest.mark.parametrize("package", ["planner", "sim"])
def test_no_module_over_400_lines(package):
    long = {str(p.relative_to(ROOT)): n for p in sorted((ROOT / package).rglob("*.py"))
            if (n := len(p.read_text().splitlines())) > MAX_LINES}
    assert long == {}
