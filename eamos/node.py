"""Moved: ``eamos-node`` is :mod:`eamos.cli.node`.

Only the old console-script path: an install made before the move runs
``eamos.node:main`` (and scripts may run ``python -m eamos.node``).  Delete
this module once ``pip install -e .`` has regenerated the ``eamos-node``
script and nothing runs ``-m eamos.node`` any more.  The command-line module
is found by name, not imported at import time: nothing below the CLI may
depend on it (tests/test_layering.py).
"""

from __future__ import annotations

import importlib
import sys


def main(argv: list[str] | None = None) -> int:
    """``eamos-node`` (:func:`eamos.cli.node.main`)."""
    entry = importlib.import_module("eamos.cli.node")
    return int(entry.main(argv))


if __name__ == "__main__":
    sys.exit(main())
