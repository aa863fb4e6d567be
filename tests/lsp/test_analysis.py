"""The language server's pure analysis: findings, names, definitions, hovers, completions."""

from __future__ import annotations

import pytest

from eamos.compiler import MissionError, compile_mission
from eamos.lsp import (
    LineIndex,
    MissionIndex,
    Point,
    Span,
    checked_findings,
    completions,
    definition,
    findings,
    hover,
    references,
    rename,
    symbols,
)

from .lsp_helpers import MISSIONS, THREE_ERRORS, position_of, too_many_sync_arcs


def test_findings_are_the_compilers_diagnostics_with_the_same_messages_and_hints() -> None:
    with pytest.raises(MissionError) as info:
        compile_mission(THREE_ERRORS, "x.go")
    got = findings(THREE_ERRORS)
    want = [(d.severity, d.loc.line, d.loc.col, d.message, d.hint) for d in info.value.diagnostics]
    assert [(f.severity, f.span.line, f.span.col, f.message, f.hint) for f in got] == want
    assert len(got) == 3


@pytest.mark.parametrize("path", sorted(MISSIONS.glob("*.go")), ids=lambda p: p.name)
def test_the_checking_phases_agree_with_the_whole_compile(path) -> None:  # type: ignore[no-untyped-def]
    # The server publishes checked_findings at once; they must be what eamos compile says.
    text = path.read_text(encoding="utf-8")
    for cut in [*range(0, len(text), 13), len(text)]:
        assert checked_findings(text[:cut]) == findings(text[:cut]), cut
    for odd in ("", "\x00", "var D1 Quadcopter\n", "func SEQ_A() { SEQ_A() }", THREE_ERRORS):
        assert checked_findings(odd) == findings(odd), odd


def test_only_the_whole_compile_sees_the_synchronisation_limit() -> None:
    text = too_many_sync_arcs()
    assert checked_findings(text) == []
    (finding,) = findings(text)
    assert "more than the limit" in finding.message


def test_findings_underline_the_offending_text() -> None:
    spans = [f.span for f in findings(THREE_ERRORS)]
    lines = THREE_ERRORS.splitlines()
    under = [lines[s.line - 1][s.col - 1 : s.end_col - 1] for s in spans]
    assert under == ["Takof", "SEQ_Fyl", "-2"]


def test_warnings_are_findings_too() -> None:
    text = (
        "var D1 Quadcopter\nvar D2 Quadcopter\n"
        "func SEQ_A() { D1.Arm() }\nfunc SEQ_B() { D1.Land() }\n"
    )
    found = findings(text)
    assert {f.severity for f in found} == {"warning"}
    assert any("never used" in f.message for f in found)
    assert any("SEQ_B" in f.message for f in found)


def test_a_clean_mission_has_no_findings_and_hostile_text_does_not_crash() -> None:
    assert findings((MISSIONS / "experiment_a.go").read_text()) == []
    assert findings("")[0].message == "the mission file is empty"
    assert findings("func\x00")[0].severity == "error"
    assert findings("func SEQ_A() { ((((")[0].severity == "error"


def test_positions_count_utf16_units_for_non_ascii_names() -> None:
    text = "var Drône𠀋 Quadcopter\r\nfunc SEQ_A() { Drône𠀋.Arm(); Drône𠀋.Takof(1) }\r"
    index = LineIndex(text)
    # 'Drône𠀋' is 6 characters, 7 UTF-16 units (𠀋 is outside the BMP), 9 UTF-8 bytes.
    line, col = position_of(text.replace("\r\n", "\n"), "Takof")
    assert index.to_point(line, col) == Point(1, col - 1 + 2)
    assert index.to_location(Point(1, col - 1 + 2)) == (line, col)
    assert LineIndex(text, "utf-8").to_point(line, col) == Point(1, col - 1 + 2 * (1 + 3))
    assert LineIndex(text, "utf-32").to_point(line, col) == Point(1, col - 1)
    # A point inside the surrogate pair moves to the character's start; past the end clamps.
    assert index.to_location(Point(0, 10)) == (1, 10)
    assert index.to_location(Point(9, 99)) == (3, 1)
    assert index.to_point(9, 1) == Point(2, 0)
    finding = next(f for f in findings(text) if "Takof" in f.message)
    assert (finding.span.line, finding.span.col) == (line, col)


def test_index_definitions_references_and_rename() -> None:
    text = (MISSIONS / "experiment_d.go").read_text()
    index = MissionIndex(text)
    use = position_of(text, "PAR_Exit", nth=1)
    (target,) = definition(index, *use)
    assert target == Span(
        *position_of(text, "func PAR_Exit", offset=5),
        position_of(text, "func PAR_Exit", offset=13)[1],
    )
    refs = references(index, *use)
    assert len(refs) == text.count("PAR_Exit") - text.count("// ") * 0 - _in_comments(
        text, "PAR_Exit"
    )
    assert target in refs and target not in references(index, *use, include_declaration=False)
    d3 = position_of(text, "D3.X()")
    spans = rename(index, *d3, "Pilot")
    assert spans is not None and len(spans) == len(index.of("D3", "drone"))
    lines = text.splitlines()
    assert all(lines[s.line - 1][s.col - 1 : s.end_col - 1] == "D3" for s in spans)
    assert rename(index, *d3, "D1") is None  # taken
    assert rename(index, *d3, "Takeoff") is None  # the vocabulary's
    assert rename(index, *d3, "9lives") is None
    assert rename(index, 1, 1, "X") is None  # a comment


def _in_comments(text: str, word: str) -> int:
    return sum(line.count(word) for line in text.splitlines() if line.lstrip().startswith("//"))


def test_symbols_are_the_block_outline_with_kinds_and_drones() -> None:
    text = (MISSIONS / "experiment_d.go").read_text()
    outline = {s.name: s for s in symbols(MissionIndex(text))}
    assert outline["PAR_Loop"].kind == "PAR block"
    assert outline["SEQ_2"].kind == "SEQ block"
    assert set(outline["PAR_Loop"].detail.split(", ")) == {"D1", "D2", "D3"}


def test_hover_explains_actions_properties_blocks_drones_and_controls() -> None:
    text = (MISSIONS / "experiment_d.go").read_text()
    index = MissionIndex(text)
    takeoff = hover(index, *position_of(text, "Takeoff", offset=2))
    assert takeoff is not None and "height_m" in takeoff.markdown and "metres" in takeoff.markdown
    x = hover(index, *position_of(text, "X() >"))
    assert x is not None and "north" in x.markdown and "metres" in x.markdown
    block = hover(index, *position_of(text, "PAR_Loop()"))
    assert block is not None and "PAR block" in block.markdown and "D3" in block.markdown
    drone = hover(index, *position_of(text, "D2.Arm"))
    assert drone is not None and "Quadcopter" in drone.markdown and "FlyToLLA" in drone.markdown
    loop = hover(index, *position_of(text, "RepeatWhile"))
    assert loop is not None and "RepeatWhile(cond, Body[, Exit])" in loop.markdown
    assert hover(index, *position_of(text, "(1)", offset=1)) is None


def _labels(text: str, needle: str, offset: int) -> set[str]:
    index = MissionIndex(text)
    return {i.label for i in completions(index, *position_of(text, needle, offset=offset))}


def test_completion_after_a_drone_offers_its_types_actions() -> None:
    text = "var Drone1 DroneType1\nfunc SEQ_A() {\n\tDrone1.\n}\n"
    labels = _labels(text, "Drone1.\n", 7)
    assert {"Takeoff", "Calibrate", "PauseWhile"} <= labels
    assert "TurnOnCamera" not in labels  # DroneType1 has no camera
    assert "X" not in labels


def test_completion_in_conditions_offers_properties_then_blocks() -> None:
    text = (
        "var D1 Quadcopter\nfunc SEQ_A() {\n\tWaitUntil(D1.Z() > 1, SEQ_)\n}\n"
        "func SEQ_B() { D1.Arm() }\n"
    )
    assert "Battery" in _labels(text, "D1.Z", 3)
    assert "Takeoff" not in _labels(text, "D1.Z", 3)
    assert _labels(text, "SEQ_)", 4) == {"SEQ_A", "SEQ_B"}
    assert "D1" in _labels(text, "D1.Z", 0)


def test_completion_of_types_statements_and_top_level() -> None:
    text = "var D1 \nfunc SEQ_A() {\n\t\n}\n"
    assert set(_labels(text, "var D1 ", 7)) >= {"Quadcopter", "DroneType2"}
    group = "var (\n\tD1 Quadcopter\n\tD2 \n)\nfunc SEQ_A() { D1.Arm() }\n"
    assert set(_labels(group, "D2 ", 3)) >= {"Quadcopter", "DroneType3"}
    statement = _labels(text, "\t\n", 1)
    assert {"D1", "SEQ_A", "If", "RepeatFor", "DoWhile", "PauseFor"} <= statement
    assert _labels(text, "func", 0) == {"func", "var", "import"}
    snippets = {i.label: i.snippet for i in completions(MissionIndex(text), 3, 2)}
    assert snippets["If"] == "If(${1:cond}, ${2:Then})"
    assert snippets["SEQ_A"] == "SEQ_A()"


def test_broken_text_still_has_names() -> None:
    text = (
        "var Drone1 Quadcopter\nfunc SEQ_A() {\n\tDrone1.Takeoff(1\n\tSEQ_B(\n}\n"
        "func SEQ_B() { Drone1."
    )
    index = MissionIndex(text)
    assert {"SEQ_A", "SEQ_B"} <= index.blocks
    assert definition(index, *position_of(text, "SEQ_B(")) == [
        Span(
            *position_of(text, "func SEQ_B", offset=5),
            position_of(text, "func SEQ_B", offset=10)[1],
        )
    ]
    assert "Land" in _labels(text, "{ Drone1.", 9)
