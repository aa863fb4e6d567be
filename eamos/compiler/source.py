"""Mission text as lines and characters: the one definition of "line" and "column".

A line ends at ``\\n``, ``\\r\\n`` or a lone ``\\r``; no other character ends a
line (form feed, vertical tab, U+0085, U+2028 and U+2029 are characters of
their line).  A column counts characters (Unicode code points) from 1, a tab
counting one.  tree-sitter counts rows at ``\\n`` only and columns in UTF-8
bytes, so the parser hands it the *normalised* text (every line end made
``\\n``) and converts its byte columns here; the renderer splits lines with
the same :func:`split_lines`.  Both therefore agree on every location.
"""

from __future__ import annotations

import re

_LINE_END = re.compile(r"\r\n|\r")
_SPLIT = re.compile(r"\r\n|\r|\n")
# Characters a terminal would not show as one column on the line (they would
# break or shift it): shown as a space so the caret stays under its character.
_INVISIBLE = re.compile(r"[\x00-\x08\x0b-\x1f\x7f\x85\u2028\u2029]")


def normalise(source: str) -> str:
    """``source`` with every line end (``\\r\\n``, lone ``\\r``) made ``\\n``."""
    return _LINE_END.sub("\n", source) if "\r" in source else source


def split_lines(source: str) -> list[str]:
    """The lines of ``source`` (line ends removed), by the definition above."""
    return _SPLIT.split(source)


def display_line(line: str) -> str:
    """A line as printed under a diagnostic: one visible column per character, tabs kept."""
    return _INVISIBLE.sub(" ", line)


class SourceText:
    """Normalised mission text, its UTF-8 bytes, and byte-to-character column conversion."""

    def __init__(self, source: str) -> None:
        self.text = normalise(source)
        # Lone surrogates cannot come from a file (compile_file decodes strictly) but a
        # caller may pass them in a str; surrogatepass keeps every character one-to-one.
        self.data = self.text.encode("utf-8", errors="surrogatepass")
        self._starts: list[int] | None = None
        self._ascii = self.text.isascii()

    def _line_starts(self) -> list[int]:
        if self._starts is None:
            starts = [0]
            find = self.data.find
            at = find(b"\n")
            while at != -1:
                starts.append(at + 1)
                at = find(b"\n", at + 1)
            self._starts = starts
        return self._starts

    def column(self, row: int, byte_col: int) -> int:
        """The 1-based character column of a tree-sitter point (0-based row, byte column)."""
        if self._ascii:
            return byte_col + 1
        starts = self._line_starts()
        if row >= len(starts):  # pragma: no cover - tree-sitter points are inside the text
            return byte_col + 1
        begin = starts[row]
        prefix = self.data[begin : begin + byte_col]
        if prefix.isascii():
            return byte_col + 1
        return len(prefix.decode("utf-8", errors="surrogatepass")) + 1

    def char_to_byte(self, offsets: list[int]) -> list[int]:
        """UTF-8 byte offsets of increasing character offsets, in one pass over the text."""
        if self._ascii:
            return list(offsets)
        out: list[int] = []
        char_at = byte_at = 0
        for offset in offsets:
            byte_at += len(self.text[char_at:offset].encode("utf-8", errors="surrogatepass"))
            char_at = offset
            out.append(byte_at)
        return out
