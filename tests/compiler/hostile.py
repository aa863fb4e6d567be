"""Shared checks for bad and odd missions (issue 17): only located MissionErrors, quickly.

Used by the seeded corpus (test_hostile_missions.py) and the hypothesis fuzz
test (test_fuzz_missions.py).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

from eamos.compiler import CompiledMission, Diagnostic, MissionError, compile_mission
from eamos.compiler.source import split_lines

# CPU seconds of this process per mission: the bound is on the compiler's work, so other
# processes on a loaded machine (a CI run, parallel test workers) cannot make it fail; the
# slowest input within the caps takes a few CPU seconds, every fuzzed or corpus mission well
# under one.
SECONDS_PER_MISSION = 10.0


@dataclass(frozen=True)
class Outcome:
    """What compiling one mission gave: the compiled mission or the MissionError."""

    compiled: CompiledMission | None
    error: MissionError | None
    seconds: float  # CPU seconds (time.process_time)

    @property
    def diagnostics(self) -> list[Diagnostic]:
        if self.error is not None:
            return self.error.diagnostics
        assert self.compiled is not None
        return list(self.compiled.warnings)

    def first_error(self) -> Diagnostic:
        assert self.error is not None, "the mission compiled"
        return next(d for d in self.error.diagnostics if d.severity == "error")


def compile_checked(text: str, name: str = "odd.go") -> Outcome:
    """Compile ``text``: anything but a MissionError fails; every location is checked."""
    start = time.process_time()
    try:
        compiled = compile_mission(text, name)
    except MissionError as exc:
        outcome = Outcome(None, exc, time.process_time() - start)
        rendered = exc.render(name, text)
        assert rendered.startswith(f"{name}:"), rendered[:200]
    else:
        outcome = Outcome(compiled, None, time.process_time() - start)
    assert outcome.seconds < SECONDS_PER_MISSION, f"{outcome.seconds:.1f} s"
    assert_located(outcome.diagnostics, text)
    return outcome


def assert_located(diagnostics: list[Diagnostic], text: str) -> None:
    """Every diagnostic points inside the text: a real line, a column on it (or just past)."""
    lines = split_lines(text)
    for d in diagnostics:
        assert 1 <= d.loc.line <= len(lines), (d, len(lines))
        line = lines[d.loc.line - 1]
        assert 1 <= d.loc.col <= len(line) + 1, (d, len(line))
        if d.end_col is not None:
            assert d.loc.col <= d.end_col <= len(line) + 1, (d, len(line))
        if d.source_line is not None:
            assert d.source_line == line, d


def text_at(text: str, d: Diagnostic) -> str:
    """The source from a diagnostic's location to the end of its line."""
    return split_lines(text)[d.loc.line - 1][d.loc.col - 1 :]


def caret_text(text: str, d: Diagnostic) -> str:
    """The characters a diagnostic's caret underlines (one if it has no end column)."""
    line = split_lines(text)[d.loc.line - 1]
    end = d.end_col if d.end_col is not None else d.loc.col + 1
    return line[d.loc.col - 1 : end - 1]
