"""Compiler diagnostics: located user errors, kept apart from compiler bugs.

Every user-facing problem is a :class:`Diagnostic` carrying its source location
and a hint.  A phase collects all diagnostics it can find, then raises one
:class:`MissionError` holding them, so the user sees every error of a file at
once.  :class:`CompilerBug` is for broken invariants inside the compiler:
those are our mistakes, not the user's, and are reported differently.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from ..hints import closest

Severity = Literal["error", "warning"]


@dataclass(frozen=True, order=True)
class SourceLocation:
    """A 1-based line and column in a mission file."""

    line: int
    col: int

    def __str__(self) -> str:
        return f"{self.line}:{self.col}"


NOWHERE = SourceLocation(1, 1)


@dataclass(frozen=True)
class Diagnostic:
    """One finding about a mission, with where it is and how to fix it."""

    severity: Severity
    loc: SourceLocation
    message: str
    hint: str = ""
    end_col: int | None = None  # last column of the offending text, for the caret

    def render(self, path: str, source: str | None) -> str:
        """``file:line:col: severity: message``, the line with a caret, and the hint."""
        out = [f"{path}:{self.loc}: {self.severity}: {self.message}"]
        if source is not None:
            lines = source.splitlines()
            if 1 <= self.loc.line <= len(lines):
                text = lines[self.loc.line - 1].expandtabs(4)
                raw = lines[self.loc.line - 1]
                # Tabs were expanded for display; move the caret the same way.
                col = len(raw[: self.loc.col - 1].expandtabs(4)) + 1
                width = 1
                if self.end_col is not None and self.end_col > self.loc.col:
                    width = len(raw[self.loc.col - 1 : self.end_col - 1].expandtabs(4)) or 1
                out.append(f"    {text}")
                out.append("    " + " " * (col - 1) + "^" + "~" * (width - 1))
        if self.hint:
            out.append(f"    hint: {self.hint}")
        return "\n".join(out)


class MissionError(Exception):
    """A mission has errors; ``diagnostics`` holds every one found (and any warnings)."""

    def __init__(self, diagnostics: list[Diagnostic]) -> None:
        self.diagnostics = sorted(diagnostics, key=lambda d: (d.loc, d.severity))
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
        body = "\n".join(d.render(path, source) for d in self.diagnostics)
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
