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

Nothing happens when structlog is already imported (a test process, ``eamos run``):
only the node's own process start is affected.

(structlog also imports ``asyncio``, with ``ssl`` and ``socket``, ~20 ms, for its
``async`` methods.  It cannot be deferred here: a lazy module,
:class:`importlib.util.LazyLoader`, is loaded by the very next ``import asyncio``
on Python 3.11, which reads its ``__spec__``.)
"""

from __future__ import annotations

import sys

#: Packages structlog imports only for console rendering (``structlog.dev``,
#: ``structlog.tracebacks``); each is optional there (``except ImportError``).
CONSOLE_EXTRAS = ("rich", "better_exceptions", "colorama")


def import_structlog_without_console_extras() -> None:
    """Import structlog with :data:`CONSOLE_EXTRAS` hidden, unless it is imported already."""
    if "structlog" in sys.modules:
        return
    hidden = [name for name in CONSOLE_EXTRAS if name not in sys.modules]
    for name in hidden:
        sys.modules[name] = None  # type: ignore[assignment]  # the import system's "not found"
    try:
        import structlog  # noqa: F401
    finally:
        for name in hidden:
            if name in sys.modules and sys.modules[name] is None:
                del sys.modules[name]


import_structlog_without_console_extras()
