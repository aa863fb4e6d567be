"""Completion, hover and definition for mission libraries (issue 13), as pure functions.

``import "`` completes the libraries the compiler would find (the mission's folder, each
folder on ``EAMOS_PATH``, the shipped standard library, in that order); ``shapes.``
completes that library's blocks with their parameters.  The answers are checked against
the compiler itself: what is offered compiles.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from eamos.compiler import compile_mission
from eamos.compiler.libraries import STANDARD_LIBRARY
from eamos.lsp import MissionIndex, Span, completions, definition, hover, rename
from eamos.lsp.features import library_block_at
from eamos.lsp.libraries import available_libraries, imported_blocks
from eamos.program import uniform
from eamos.program.uniform import ControlSpec

from .lsp_helpers import position_of

HERE = Path(__file__).resolve().parent / "libraries"
MISSION_DIR = HERE / "mission"
PATH_DIR = HERE / "path"
MISSION_FILE = str(MISSION_DIR / "uses.go")
USES = (MISSION_DIR / "uses.go").read_text(encoding="utf-8")


@pytest.fixture(autouse=True)
def _eamos_path(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("EAMOS_PATH", str(PATH_DIR))


def _labels(index: MissionIndex, needle: str, offset: int, nth: int = 0) -> set[str]:
    return {i.label for i in completions(index, *position_of(index.text, needle, nth, offset))}


def test_every_library_the_compiler_finds_is_offered_with_its_origin() -> None:
    found = {lib.name: lib for lib in available_libraries(MISSION_FILE)}
    standard = {p.name for p in STANDARD_LIBRARY.iterdir() if any(p.glob("*.go"))}
    assert set(found) == {"inspection", "lab/hover"} | standard
    assert found["inspection"].origin == "mission folder"
    assert found["lab/hover"].origin == "EAMOS_PATH"
    assert found["shapes"].origin == "standard library"
    # What is offered compiles: the compiler finds every one of them.
    for name in found:
        package = name.rsplit("/", 1)[-1]
        text = f'import "{name}"\nfunc SEQ_A() {{ PauseFor(1) }}\n'
        compiled = compile_mission(text, MISSION_FILE)
        assert any(f.package == package for f in compiled.mission.libraries), name


def test_the_first_folder_of_the_search_path_wins(tmp_path: Path) -> None:
    mine = tmp_path / "shapes"
    mine.mkdir()
    (mine / "shapes.go").write_text("package shapes\nfunc SEQ_Mine() { PauseFor(1) }\n")
    (tmp_path / ".hidden").mkdir()
    (tmp_path / ".hidden" / "x.go").write_text("package hidden\n")
    found = {lib.name: lib for lib in available_libraries(str(tmp_path / "m.go"), {})}
    assert found["shapes"].folder == mine and found["shapes"].origin == "mission folder"
    assert ".hidden" not in found
    unsaved = {lib.name: lib for lib in available_libraries("<mission>", {})}
    assert unsaved["shapes"].origin == "standard library"


def test_import_quote_completes_library_names() -> None:
    index = MissionIndex('import "\nvar D1 Quadcopter\n', MISSION_FILE)
    items = completions(index, 1, 9)
    assert {"inspection", "lab/hover", "shapes", "fleet"} <= {i.label for i in items}
    assert all(i.kind == "library" and i.snippet is None for i in items)
    bare = completions(MissionIndex("import \n", MISSION_FILE), 1, 8)
    assert {i.label: i.snippet for i in bare}["shapes"] == '"shapes"'
    group = 'import (\n\t"shapes"\n\t\n)\nvar D1 Quadcopter\n'
    assert "inspection" in _labels(MissionIndex(group, MISSION_FILE), '"\n\t\n', 3)


def test_a_package_member_completes_its_blocks_with_parameters() -> None:
    text = USES.replace("\tinspection.SEQ_Look(D1, 3)\n", "\tinspection.\n")
    index = MissionIndex(text, MISSION_FILE)  # half-typed: the parser gives up on it
    items = {i.label: i for i in completions(index, *position_of(text, "inspection.\n", 0, 11))}
    assert set(items) == {"SEQ_Look"}
    look = items["SEQ_Look"]
    assert look.snippet == "SEQ_Look(${1:d}, ${2:height_m})"
    assert look.detail == "inspection.SEQ_Look(d Quadcopter, height_m float64)"
    assert "climbs height_m" in look.documentation
    shapes = _labels(MissionIndex(USES, MISSION_FILE), "shapes.SEQ", 7)
    assert shapes == {"SEQ_Square", "SEQ_Orbit"}
    # Only libraries the mission imports itself: shapes imports fleet, the mission does not.
    assert "fleet" not in MissionIndex(USES, MISSION_FILE).library_blocks


def test_a_package_is_not_a_drone_and_statements_offer_it() -> None:
    index = MissionIndex(USES, MISSION_FILE)
    assert index.drones == {"D1"}
    assert index.packages == {"inspection", "hover", "shapes"}
    statement = _labels(index, "\tD1.Land", 1)
    assert {"D1", "inspection", "hover", "shapes", "SEQ_Main"} <= statement


def test_hover_and_definition_of_a_library_block() -> None:
    index = MissionIndex(USES, MISSION_FILE)
    line, col = position_of(USES, "SEQ_Look")
    found = hover(index, line, col + 2)
    assert found is not None
    assert "inspection.SEQ_Look(d Quadcopter, height_m float64)" in found.markdown
    assert "inspection.go" in found.markdown
    at = library_block_at(index, line, col + 2)
    assert at is not None
    block, span = at
    library = MISSION_DIR / "inspection" / "inspection.go"
    assert Path(block.file) == library
    text = library.read_text(encoding="utf-8")
    assert (block.line, block.col) == position_of(text, "func SEQ_Look", offset=5)
    start = position_of(USES, "inspection.SEQ_Look")
    assert span == Span(*start, start[1] + len("inspection.SEQ_Look"))
    assert definition(index, line, col) == []  # not in this file: the server opens the library
    assert rename(index, line, col, "SEQ_Other") is None


def test_imports_of_broken_text_are_found_lexically() -> None:
    text = 'import (\n\t"shapes" // a comment "not"\n\t"lab/hover"\n)\n/* import "x" */\nfunc {\n'
    index = MissionIndex(text, MISSION_FILE)
    assert [i.path for i in index.imports] == ["shapes", "lab/hover"]
    assert {"SEQ_Square", "SEQ_Orbit"} == set(b.name for b in index.library_blocks["shapes"])


def test_a_missing_library_has_no_blocks_and_no_error() -> None:
    index = MissionIndex('import "nowhere"\nfunc SEQ_A() {\n\tnowhere.\n}\n', MISSION_FILE)
    assert index.library_blocks == {"nowhere": ()}
    assert completions(index, 3, 10) == []
    mission = index.mission
    assert mission is not None
    assert imported_blocks(mission, MISSION_FILE) == {"nowhere": ()}


def test_control_structure_arguments_follow_their_parameters() -> None:
    text = "var D1 Quadcopter\nfunc SEQ_A() {\n\tTry(\n}\nfunc SEQ_B() { D1.Arm() }\n"
    index = MissionIndex(text)
    assert _labels(index, "Try(", 4) == {"SEQ_A", "SEQ_B"}  # Body is a block
    repeat = MissionIndex(text.replace("Try(", "RepeatFor("))
    assert _labels(repeat, "RepeatFor(", 10) == set()  # n is a number
    cond = MissionIndex(text.replace("Try(", "If(D1.Battery() > (1), "))
    assert _labels(cond, "), ", 3) == {"SEQ_A", "SEQ_B"}  # Then, after a nested ()


def test_a_new_control_structure_appears_by_itself(monkeypatch: pytest.MonkeyPatch) -> None:
    # Nothing in eamos.lsp lists the structures: one added to the vocabulary is offered,
    # with its snippet, and its arguments complete by their parameters' kinds.
    spec = ControlSpec("Whenever", ("cond", "Handler"), "Each time `cond` becomes true ...")
    monkeypatch.setitem(uniform.CONTROL_STRUCTURES, "Whenever", spec)
    text = "var D1 Quadcopter\nfunc SEQ_A() {\n\t\n\tWhenever(D1.Z() > 1, \n}\n"
    index = MissionIndex(text)
    items = {i.label: i for i in completions(index, 3, 2)}
    assert items["Whenever"].snippet == "Whenever(${1:cond}, ${2:Handler})"
    assert "Whenever" in (items["Whenever"].documentation or "")
    assert _labels(index, "> 1, ", 5) == {"SEQ_A"}
    line, col = position_of(text, "Whenever")
    found = hover(index, line, col)
    assert found is not None and "Each time" in found.markdown
    assert "`Handler` is a block name" in found.markdown
