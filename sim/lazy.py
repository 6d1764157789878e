"""Names a package exports but imports on first use (PEP 562), so that the command line starts fast."""

from __future__ import annotations

import sys
from collections.abc import Callable, Mapping
from importlib import import_module

__all__ = ["lazy_exports"]


def lazy_exports(package: str, where: Mapping[str, str | None]) -> tuple[Callable[[str], object], Callable[[], list[str]]]:
    """A package's ``__getattr__`` and ``__dir__``: ``where`` maps each name to its submodule
    (``None``: the name is a subpackage, imported whole)."""

    def __getattr__(name: str):
        if name in where:
            module = where[name]
            value = import_module(f".{name}", package) if module is None else getattr(
                import_module(f".{module}", package), name)
            setattr(sys.modules[package], name, value)
            return value
        raise AttributeError(f"module {package!r} has no attribute {name!r}")

    def __dir__() -> list[str]:
        return sorted(set(vars(sys.modules[package])) | set(where))

    return __getattr__, __dir__
