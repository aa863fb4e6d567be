"""``eamos lsp``: the language server for mission files, over stdin/stdout.

Editors start it (docs/editors.md); it answers with the compiler's errors as the author
types, completion, hover help with units, definitions, references, outline and rename.
"""

from __future__ import annotations

import argparse
from typing import Any

from .errors import command
from .exits import EXIT_OK
from .options import add_verbose

_LSP_HELP = """\
Run the EAMOS language server on stdin/stdout (the Language Server Protocol).
Editors start it themselves: see docs/editors.md for VS Code, Neovim, Helix
and Emacs.  It reports the compiler's errors and warnings as you type, and
offers completion, hover help (units, argument names), go to definition,
references, the block outline and rename of blocks and drones."""


def add_lsp_parser(sub: Any) -> None:
    """Add ``eamos lsp`` to the ``eamos`` command's subparsers."""
    p = sub.add_parser(
        "lsp",
        help="the language server for editors (stdio)",
        description=_LSP_HELP,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    # Editor clients often pass --stdio; stdio is the only transport, so it is accepted.
    p.add_argument("--stdio", action="store_true", help="talk over stdin/stdout (the default)")
    add_verbose(p, "tracebacks of internal errors in the server's log (stderr)")
    command(p, cmd_lsp)


def cmd_lsp(args: argparse.Namespace) -> int:
    """``eamos lsp``: serve until the editor exits."""
    from eamos.lsp.server import serve

    serve(verbose=args.verbose)
    return EXIT_OK


__all__ = ["add_lsp_parser", "cmd_lsp"]
