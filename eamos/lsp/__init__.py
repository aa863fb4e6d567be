"""The language server for mission files: ``eamos lsp``.

Pure analysis of a document (:mod:`.document`, :mod:`.features`, :mod:`.completion`,
:mod:`.libraries`, :mod:`.positions`) answers every request; :mod:`.server` only speaks the protocol
(pygls over stdio).  Importing this package does not load pygls.
"""

from .completion import Item, completions
from .document import Finding, MissionIndex, Occurrence, Span, checked_findings, findings
from .features import (
    Hover,
    Symbol,
    block_drones,
    definition,
    hover,
    library_block_at,
    references,
    rename,
    symbols,
)
from .libraries import Library, LibraryBlock, available_libraries, imported_blocks
from .positions import LineIndex, Point

__all__ = [
    "Finding",
    "Hover",
    "Item",
    "Library",
    "LibraryBlock",
    "LineIndex",
    "MissionIndex",
    "Occurrence",
    "Point",
    "Span",
    "Symbol",
    "available_libraries",
    "block_drones",
    "checked_findings",
    "completions",
    "definition",
    "findings",
    "hover",
    "imported_blocks",
    "library_block_at",
    "references",
    "rename",
    "symbols",
]
