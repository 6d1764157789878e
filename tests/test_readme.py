"""The README's Python API cells and the package docstrings' examples run, and print what they say."""

import contextlib
import doctest
import io
import re
from pathlib import Path

import planner
import sim

ROOT = Path(__file__).resolve().parents[1]
FENCE = re.compile(r"^```(\w*)\n(.*?)^```", re.S | re.M)


def _cells(text: str) -> list[tuple[str, str | None]]:
    """``(python code, the text block right after it or None)`` for every python block."""
    blocks = [(m.group(1), m.group(2)) for m in FENCE.finditer(text)]
    out = []
    for n, (lang, body) in enumerate(blocks):
        if lang == "python":
            nxt = blocks[n + 1] if n + 1 < len(blocks) else None
            out.append((body, nxt[1] if nxt is not None and nxt[0] == "text" else None))
    return out


def test_readme_python_cells_run_and_print_what_the_readme_shows(tmp_path, monkeypatch):
    cells = _cells((ROOT / "README.md").read_text(encoding="utf-8"))
    assert len(cells) >= 4
    monkeypatch.chdir(tmp_path)  # outputs go to tmp_path/media
    (tmp_path / "scenarios").symlink_to(ROOT / "scenarios")
    namespace: dict = {"__name__": "readme"}
    for n, (code, shown) in enumerate(cells):
        buf = io.StringIO()
        with contextlib.redirect_stdout(buf):
            exec(compile(code, f"README.md python cell {n}", "exec"), namespace)
        if shown is not None:
            assert buf.getvalue() == shown, f"cell {n} printed {buf.getvalue()!r}, the README shows {shown!r}"
    assert (tmp_path / "media" / "api-demo.gif").is_file()
    assert (tmp_path / "media" / "fig1-line-to-phi.html").is_file()


def test_a_cell_that_prints_something_else_is_caught(tmp_path, monkeypatch):
    readme = "```python\nprint(1 + 1)\n```\n\n```text\n3\n```\n"
    (code, shown), = _cells(readme)
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        exec(code, {})
    assert buf.getvalue() != shown


def test_package_docstring_examples_run():
    for module in (planner, sim):
        result = doctest.testmod(module, optionflags=doctest.ELLIPSIS)
        assert result.attempted >= 5 and result.failed == 0, module.__name__
