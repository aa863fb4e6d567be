"""Imported first by ``eamos-node``: structlog, loaded without the terminal extras it looks for.

``import structlog`` runs ``structlog.dev``, which imports ``rich`` (and through it
``pygments``) when installed, to render pretty tracebacks on a console.  ``rich`` is
installed for the ground station's live table, so every ``eamos-node`` paid ~45 ms of
its start-up for a console renderer it never uses: a node logs JSON lines
(:mod:`eamos.logs`, ``format_exc_info``, which does not use rich).  structlog has no
setting for this; its documented fallback is ``rich`` failing to import.  So while
structlog is imported, a ``None`` in :data:`sys.modules` makes ``import rich`` fail;
the entry is removed afterwards, so rich stays importable in this process (the ground
station, run by ``eamos-node`` too, may still show a live table).

structlog also imports ``asyncio`` (with ``ssl``, ``socket`` and ``subprocess``:
~25 ms of a node's start-up) for its ``async`` log methods (``ainfo``, ...), which read
``asyncio`` only when called; a node never calls them.  So while structlog is imported,
``asyncio`` in :data:`sys.modules` is a :class:`Deferred` stand-in: structlog's modules
keep it as their ``asyncio`` and the real module is imported the first time one of
them reads an attribute of it.  The stand-in is removed from :data:`sys.modules` right
after, so anything else that imports ``asyncio`` gets the real one.  (A lazy module,
:class:`importlib.util.LazyLoader`, cannot serve: on Python 3.11 the very next ``import
asyncio`` reads its ``__spec__`` and so loads it.)

Nothing happens when structlog is already imported (a test process, ``eamos run``):
only the node's own process start is affected.
"""

from __future__ import annotations

import importlib
import sys
import types
from typing import Any

#: Packages structlog imports only for console rendering (``structlog.dev``,
#: ``structlog.tracebacks``); each is optional there (``except ImportError``).
CONSOLE_EXTRAS = ("rich", "better_exceptions", "colorama")
#: Modules structlog imports but reads only when an ``async`` log method runs.
DEFERRED = ("asyncio",)


class Deferred(types.ModuleType):
    """Stands for module ``name``: imports it on the first attribute read, then reads there."""

    def __getattr__(self, attribute: str) -> Any:
        # Only attributes a plain module lacks get here; __spec__ is None (not a lazy
        # module's trigger), so ``import asyncio`` while this stands in returns it as is.
        if sys.modules.get(self.__name__) is self:  # read while standing in: make way
            del sys.modules[self.__name__]
        return getattr(importlib.import_module(self.__name__), attribute)


def import_structlog_without_console_extras() -> None:
    """Import structlog with :data:`CONSOLE_EXTRAS` hidden and :data:`DEFERRED` deferred.

    Does nothing if structlog is imported already.
    """
    if "structlog" in sys.modules:
        return
    # None is the import system's "not found"; a Deferred imports the module when read.
    stand_ins: dict[str, Any] = {name: None for name in CONSOLE_EXTRAS}
    stand_ins |= {name: Deferred(name) for name in DEFERRED}
    stand_ins = {name: it for name, it in stand_ins.items() if name not in sys.modules}
    sys.modules.update(stand_ins)
    try:
        import structlog  # noqa: F401
    finally:
        for name, stand_in in stand_ins.items():
            if name in sys.modules and sys.modules[name] is stand_in:
                del sys.modules[name]


import_structlog_without_console_extras()
