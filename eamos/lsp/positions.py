"""Character columns (the compiler's) to and from editor positions (the protocol's).

The compiler counts lines from 1 and columns in characters from 1, a line ending at
``\\n``, ``\\r\\n`` or a lone ``\\r`` (:mod:`eamos.compiler.source`).  The Language Server
Protocol counts both from 0 and, by default, columns in UTF-16 code units: a letter outside
the Basic Multilingual Plane (an emoji, a rare CJK character) is two units.  A client may
negotiate UTF-8 bytes or UTF-32 (characters) instead; :class:`LineIndex` converts for all three.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from ..compiler.source import split_lines

Encoding = Literal["utf-8", "utf-16", "utf-32"]


@dataclass(frozen=True, order=True)
class Point:
    """A protocol position: 0-based line and column in the negotiated encoding's units."""

    line: int
    character: int


def _units(text: str, encoding: Encoding) -> int:
    """Length of ``text`` in code units of ``encoding``."""
    if encoding == "utf-32" or text.isascii():
        return len(text)
    if encoding == "utf-16":
        return len(text) + sum(1 for ch in text if ord(ch) > 0xFFFF)
    return len(text.encode("utf-8", errors="surrogatepass"))


class LineIndex:
    """The lines of one document, for converting positions in both directions."""

    def __init__(self, text: str, encoding: Encoding = "utf-16") -> None:
        self.lines = split_lines(text)
        self.encoding = encoding

    def line(self, number: int) -> str:
        """The text of a 1-based line ("" past the end)."""
        return self.lines[number - 1] if 1 <= number <= len(self.lines) else ""

    def to_point(self, line: int, col: int) -> Point:
        """A compiler location (1-based line, 1-based character column) as a protocol point.

        Locations past the end of their line or of the text are clamped to the end.
        """
        if line > len(self.lines):
            last = len(self.lines)
            return Point(last - 1, _units(self.lines[-1], self.encoding))
        text = self.lines[max(line, 1) - 1]
        col = min(max(col, 1), len(text) + 1)
        return Point(max(line, 1) - 1, _units(text[: col - 1], self.encoding))

    def to_location(self, point: Point) -> tuple[int, int]:
        """A protocol point as a compiler (line, character column), clamped into the text.

        A point inside a character (half of a UTF-16 surrogate pair, the middle of a
        UTF-8 sequence) moves to that character's start.
        """
        line = min(max(point.line, 0), len(self.lines) - 1)
        text = self.lines[line]
        want = max(point.character, 0)
        if self.encoding == "utf-32" or text.isascii():
            return line + 1, min(want, len(text)) + 1
        used = 0
        for index, ch in enumerate(text):
            width = _units(ch, self.encoding)
            if used + width > want:
                return line + 1, index + 1
            used += width
        return line + 1, len(text) + 1
