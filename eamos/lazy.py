"""A package's public names loaded on first use: the one lazy-export mechanism of EAMOS.

PEP 562 lets a module define ``__getattr__`` and ``__dir__``; :func:`lazy_exports`
makes that pair for a package, from one mapping *public name -> the module of the
package that defines it*.  A package uses it only where importing everything at once
would load what its light users must not pay for, each saying why in its docstring:

* :mod:`eamos.config` -- a drone's ``eamos-node`` reads a node config and need not
  load fleet files, drone types and the simulator's settings (docs/performance.md);
* :mod:`eamos.hal` -- the adapters: a simulated drone does not load the MAVLink adapter;
* :mod:`eamos.actors` -- a drone's report (read by ``eamos report``) and the pure node
  logic load neither Pykka nor ZeroMQ;
* :mod:`eamos.ground` -- reading a run summary starts neither ZeroMQ nor Pykka.

Every other package imports its names plainly.  A lazy package keeps its ``__all__``,
imports the same names under ``TYPE_CHECKING`` for the type checker, and ends with::

    __getattr__, __dir__ = lazy_exports(globals(), _WHERE)

(the shape of Scientific Python's SPEC 1, ``lazy_loader.attach``).  ``tests/test_layering.py``
checks that every package's ``__all__`` resolves.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping
from typing import Any

__all__ = ["lazy_exports"]


def lazy_exports(
    namespace: Mapping[str, Any], where: Mapping[str, str]
) -> tuple[Callable[[str], Any], Callable[[], list[str]]]:
    """``(__getattr__, __dir__)`` for the package whose ``globals()`` is ``namespace``.

    Each name of ``where`` (name -> the module of the package defining it, relative:
    ``"flight"``, ``"logic.telemetry"``) is imported from its module when first asked for;
    ``dir()`` lists them with the package's own names.
    """
    package = str(namespace["__name__"])

    def getattr_(name: str) -> Any:
        module = where.get(name)
        if module is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        return getattr(importlib.import_module(f".{module}", package), name)

    def dir_() -> list[str]:
        return sorted({*namespace, *where})

    return getattr_, dir_
