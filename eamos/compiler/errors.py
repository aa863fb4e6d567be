"""Compiler diagnostics: located user errors, kept apart from compiler bugs.

Every user-facing problem is a :class:`Diagnostic` carrying its source location
and a hint.  A phase collects all diagnostics it can find, then raises one
:class:`MissionError` holding them, so the user sees every error of a file at
once.  :class:`CompilerBug` is for broken invariants inside the compiler:
those are our mistakes, not the user's, and are reported differently.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field, replace
from typing import Literal

from ..hints import closest
from .source import display_line, split_lines

Severity = Literal["error", "warning"]


@dataclass(frozen=True, order=True)
class SourceLocation:
    """A 1-based line and column in a mission file."""

    line: int
    col: int
    # The library file the location is in; "" for the mission file itself.
    file: str = field(default="", compare=False)

    def __str__(self) -> str:
        return f"{self.line}:{self.col}"


# Longest part of a source line printed under a diagnostic, in characters.
_EXCERPT = 160


@dataclass(frozen=True)
class Diagnostic:
    """One finding about a mission, with where it is and how to fix it.

    ``loc`` is a line and a *character* column by the definition of
    :mod:`.source`.  ``source_line`` is the text of that line, filled in by
    :func:`~.phases.compile_mission` so that rendering one diagnostic does not
    split the whole file again (which made printing many warnings quadratic).
    """

    severity: Severity
    loc: SourceLocation
    message: str
    hint: str = ""
    end_col: int | None = None  # last column of the offending text, for the caret
    source_line: str | None = field(default=None, compare=False, repr=False)

    def render(self, path: str, source: str | None) -> str:
        """``file:line:col: severity: message``, the line with a caret, and the hint."""
        if source is None:
            return self.render_line(path, None)
        if self.source_line is not None:
            return self.render_line(path, self.source_line)
        return self.render_line(path, _line_of(split_lines(source), self.loc.line))

    def render_line(self, path: str, line: str | None) -> str:
        """As :meth:`render`, given the text of the diagnostic's line (None: no excerpt)."""
        out = [f"{self.loc.file or path}:{self.loc}: {self.severity}: {self.message}"]
        if line is not None:
            raw, first, last = _excerpt(line, self.loc.col, self.end_col)
            text = raw.expandtabs(4)
            # Tabs were expanded for display; move the caret the same way.
            col = len(raw[: first - 1].expandtabs(4)) + 1
            width = 1
            if last is not None and last > first:
                width = len(raw[first - 1 : last - 1].expandtabs(4)) or 1
            out.append(f"    {text}")
            out.append("    " + " " * (col - 1) + "^" + "~" * (width - 1))
        if self.hint:
            out.append(f"    hint: {self.hint}")
        return "\n".join(out)


def _excerpt(line: str, col: int, end_col: int | None) -> tuple[str, int, int | None]:
    """The part of a line shown under a diagnostic, and the caret's columns in it.

    A long line (a generated mission may be one 2 MB line) is cut to a window
    around the caret, so the output stays proportional to the diagnostics.
    """
    if len(line) <= _EXCERPT:
        return display_line(line), col, end_col
    # Cut first, then clean: display_line maps one character to one, and cleaning the
    # whole line for each diagnostic would make many diagnostics on it quadratic.
    start = max(0, min(col - 1 - _EXCERPT // 2, len(line) - _EXCERPT))
    prefix = "..." if start > 0 else ""
    suffix = "..." if start + _EXCERPT < len(line) else ""
    window = prefix + display_line(line[start : start + _EXCERPT]) + suffix
    shift = len(prefix) - start
    last = None if end_col is None else min(end_col, start + _EXCERPT + 1) + shift
    return window, col + shift, last


def _line_of(lines: list[str], number: int) -> str | None:
    return lines[number - 1] if 1 <= number <= len(lines) else None


def with_source_lines(
    diagnostics: list[Diagnostic], source: str, files: Mapping[str, str] | None = None
) -> list[Diagnostic]:
    """The diagnostics, each carrying the text of its line (one split of each file).

    ``files`` holds the text of the library files a location may be in.
    """
    split: dict[str, list[str]] = {"": split_lines(source)}
    out = []
    for d in diagnostics:
        if d.source_line is None:
            name = d.loc.file
            if name not in split:
                split[name] = split_lines((files or {}).get(name, ""))
            d = replace(d, source_line=_line_of(split[name], d.loc.line))
        out.append(d)
    return out


def render_diagnostics(diagnostics: Iterable[Diagnostic], path: str, source: str | None) -> str:
    """Every diagnostic rendered, one after another; linear in the source and their number."""
    lines = split_lines(source) if source is not None else None
    return "\n".join(
        d.render_line(
            path,
            d.source_line
            if d.loc.file
            else (None if lines is None else _line_of(lines, d.loc.line)),
        )
        for d in diagnostics
    )


class MissionError(Exception):
    """A mission has errors; ``diagnostics`` holds every one found (and any warnings)."""

    def __init__(self, diagnostics: list[Diagnostic]) -> None:
        # The mission file's own problems first, then each library file's.
        self.diagnostics = sorted(diagnostics, key=lambda d: (d.loc.file, d.loc, d.severity))
        # Set by the parser when later phases may still check what it could read.
        self.partial: object | None = None
        self.fatal = True
        errors = [d for d in self.diagnostics if d.severity == "error"]
        first = errors[0] if errors else self.diagnostics[0]
        more = f" (and {len(errors) - 1} more)" if len(errors) > 1 else ""
        super().__init__(f"{first.loc}: {first.message}{more}")

    def render(self, path: str, source: str | None) -> str:
        """All diagnostics, in source order, as the CLI prints them."""
        n = sum(1 for d in self.diagnostics if d.severity == "error")
        body = render_diagnostics(self.diagnostics, path, source)
        return f"{body}\n{n} error{'s' if n != 1 else ''} in {path}"


class CompilerBug(Exception):
    """An internal invariant of the compiler broke.  Not the mission author's fault."""


def _stem(name: str) -> str:
    return name[4:] if name[:4] in ("SEQ_", "PAR_") and len(name) > 4 else name


def did_you_mean(word: str, choices: object) -> str:
    """A 'did you mean X?' hint for a misspelt name, or a list of valid names."""
    names = sorted(str(c) for c in choices)  # type: ignore[attr-defined]
    # Block names share their SEQ_/PAR_ prefix, which would make any two look
    # alike ("SEQ_Nope" vs "SEQ_A"): compare what follows the prefix.
    stems: dict[str, str] = {}
    for name in names:
        stems.setdefault(_stem(name), name)
    stem = closest(_stem(word), stems)
    if stem is not None:
        return f"did you mean {stems[stem]}?"
    if len(names) <= 12:
        return "valid names: " + ", ".join(names)
    return ""
