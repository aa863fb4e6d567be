"""Half-typed text never breaks the language server: every request kind on prefixes of every
mission in missions/ answers without an exception.

Deterministic sampling keeps it fast: prefixes every few characters (the stride differs per
mission so that every residue is exercised), the cursor at the prefix's end (where a person
types) and at a few positions spread over the text before it.
"""

from __future__ import annotations

import pytest

from eamos.lsp import (
    LineIndex,
    MissionIndex,
    Point,
    completions,
    definition,
    findings,
    hover,
    references,
    rename,
    symbols,
)

from .lsp_helpers import MISSIONS

MISSION_FILES = sorted(MISSIONS.glob("*.go"))


def _every_request(index: MissionIndex, line: int, col: int) -> None:
    completions(index, line, col)
    hover(index, line, col)
    definition(index, line, col)
    references(index, line, col)
    rename(index, line, col, "Renamed")
    symbols(index)


def _end(text: str) -> tuple[int, int]:
    lines = LineIndex(text).lines
    return len(lines), len(lines[-1]) + 1


@pytest.mark.parametrize("path", MISSION_FILES, ids=lambda p: p.name)
def test_every_request_on_prefixes_of_a_mission_answers(path) -> None:  # type: ignore[no-untyped-def]
    text = path.read_text(encoding="utf-8")
    stride = 3 + MISSION_FILES.index(path) % 4
    for cut in [*range(0, len(text), stride), len(text)]:
        prefix = text[:cut]
        for finding in findings(prefix):
            assert finding.span.end_col > finding.span.col
        line, col = _end(prefix)
        mission = MissionIndex(prefix)
        _every_request(mission, line, col)
        # Some positions inside the prefix, including out-of-range ones a client may send.
        for probe in (cut // 3, cut // 2, (2 * cut) // 3):
            at = mission.lines.to_location(Point(prefix.count("\n", 0, probe), 4 + probe % 11))
            _every_request(mission, *at)
        _every_request(mission, line + 3, col + 40)


def test_windows_line_ends_and_tabs_do_not_break_requests() -> None:
    text = (MISSIONS / "experiment_d.go").read_text(encoding="utf-8").replace("\n", "\r\n")
    for cut in range(0, len(text), 37):
        prefix = text[:cut]
        findings(prefix)
        _every_request(MissionIndex(prefix), *_end(prefix))
