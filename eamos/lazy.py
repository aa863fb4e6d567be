"""A package's public names loaded on first use (PEP 562), for start-up's sake.

A drone's ``eamos-node`` imports only what it runs; a package whose ``__init__``
re-exported every module would load them all (the simulator's adapter and logs,
the fleet files and drone types) for the one name it reads.  Such a package
keeps its ``__all__`` and imports the names under ``TYPE_CHECKING`` for the type
checker, and gets its module ``__getattr__`` and ``__dir__`` from here.
"""

from __future__ import annotations

import importlib
import sys
from collections.abc import Callable, Mapping
from typing import Any

__all__ = ["lazy_exports"]


def lazy_exports(
    package: str, where: Mapping[str, str]
) -> tuple[Callable[[str], Any], Callable[[], list[str]]]:
    """``(__getattr__, __dir__)`` for ``package``: each name of ``where`` (name -> module of
    the package that defines it) is imported from its module when first asked for."""

    def getattr_(name: str) -> Any:
        module = where.get(name)
        if module is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        return getattr(importlib.import_module(f".{module}", package), name)

    def dir_() -> list[str]:
        return sorted({*vars(sys.modules[package]), *where})

    return getattr_, dir_
