"""A package whose names load on first use (PEP 562): importing it costs nothing until a name is asked for."""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping


def lazy_names(package: str, where: Mapping[str, str],
               own: Callable[[], dict[str, object]]) -> tuple[Callable[[str], object], Callable[[], list[str]]]:
    """``(__getattr__, __dir__)`` for ``package`` whose name ``n`` lives in its submodule ``where[n]``.

    Parameters
    ----------
    package : str
        The package's ``__name__``.
    where : mapping
        Name -> the submodule (relative to ``package``) that defines it.
    own : callable
        The package's ``globals`` (its own names, listed by ``__dir__`` too).
    """

    def getattr_(name: str) -> object:
        if name in where:
            return getattr(importlib.import_module(f"{package}.{where[name]}"), name)
        raise AttributeError(f"module {package!r} has no attribute {name!r}")

    def dir_() -> list[str]:
        return sorted([*own(), *where])

    return getattr_, dir_
