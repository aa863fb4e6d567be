"""The language server for mission files: ``eamos lsp``.

Pure analysis of a document (:mod:`.document`, :mod:`.features`, :mod:`.completion`,
:mod:`.positions`) answers every request; :mod:`.server` only speaks the protocol
(pygls over stdio).  Importing this package does not load pygls.
"""

from .completion import Item, completions
from .document import Finding, MissionIndex, Occurrence, Span, checked_findings, findings
from .features import Hover, Symbol, block_drones, definition, hover, references, rename, symbols
from .positions import LineIndex, Point

__all__ = [
    "Finding",
    "Hover",
    "Item",
    "LineIndex",
    "MissionIndex",
    "Occurrence",
    "Point",
    "Span",
    "Symbol",
    "block_drones",
    "checked_findings",
    "completions",
    "definition",
    "findings",
    "hover",
    "references",
    "rename",
    "symbols",
]
