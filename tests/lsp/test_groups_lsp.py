"""The language server knows groups, members and loop variables.

The pure analysis first (completion, hover, rename, definitions, outline on a mission with a
group, two loops both counting with ``i``, and a block with a group parameter), then the same
requests through a real LSP client (pytest-lsp) talking to ``eamos lsp`` over stdio.
"""

from __future__ import annotations

import sys

import pytest
import pytest_lsp
from lsprotocol import types as lsp
from pytest_lsp import ClientServerConfig, LanguageClient, client_capabilities

from eamos.compiler import compile_mission
from eamos.lsp import MissionIndex, completions, definition, hover, references, rename, symbols

from .lsp_helpers import REPO, position_of

MISSION = """\
import "fleet"

var Team [4]Quadcopter
var Scout Quadcopter

func SEQ_Main() {
\tfleet.PAR_TakeOff(Team, 2)
\tScout.Arm()
\tPAR_Fly()
\tfor i := range 2 {
\t\tTeam[i].FlyByZ(1 + i)
\t}
\tWaitUntil(All(Team.Z() > 1), SEQ_Down)
}

func PAR_Fly() {
\tfor i, d := range Team {
\t\td.FlyByX(2 * i)
\t\td.FlyByY(1)
\t}
}

func SEQ_Down() {
\tPAR_Half(Team[0:2])
\tPAR_Half(Team[2:4])
}

func PAR_Half(g []Quadcopter) {
\tfor _, m := range g {
\t\tm.Land()
\t}
}
"""


def _index(text: str = MISSION) -> MissionIndex:
    return MissionIndex(text, str(REPO / "missions" / "groups.go"))


def _labels(text: str, needle: str, offset: int, nth: int = 0) -> set[str]:
    return {i.label for i in completions(_index(text), *position_of(text, needle, nth, offset))}


def _apply(text: str, spans: list, new: str) -> str:  # type: ignore[type-arg]
    lines = text.split("\n")
    for span in sorted(spans, reverse=True):
        row = lines[span.line - 1]
        lines[span.line - 1] = row[: span.col - 1] + new + row[span.end_col - 1 :]
    return "\n".join(lines)


def test_the_mission_compiles() -> None:
    compile_mission(MISSION, str(REPO / "missions" / "groups.go"))


def test_renaming_a_group_renames_its_declaration_and_every_use() -> None:
    index = _index()
    spans = rename(index, *position_of(MISSION, "Team [4]"), "Crew")
    assert spans is not None
    renamed = _apply(MISSION, spans, "Crew")
    assert "Team" not in renamed
    assert renamed.count("Crew") == MISSION.count("Team")
    before = compile_mission(MISSION, "m.go")
    after = compile_mission(renamed, "m.go")
    assert sorted(after.programs) == sorted(n.replace("Team", "Crew") for n in before.programs)


def test_renaming_a_loop_variable_leaves_another_loops_variable_of_that_name() -> None:
    index = _index()
    spans = rename(index, *position_of(MISSION, "i := range 2"), "row")
    assert spans is not None and len(spans) == 3  # its declaration and two uses
    renamed = _apply(MISSION, spans, "row")
    assert "Team[row].FlyByZ(1 + row)" in renamed
    assert "for i, d := range Team" in renamed and "d.FlyByX(2 * i)" in renamed
    assert compile_mission(renamed, "m.go").stats() == compile_mission(MISSION, "m.go").stats()
    # The member variable: its declaration and both statements of its loop.
    spans = rename(index, *position_of(MISSION, "d.FlyByY"), "drone")
    assert spans is not None and len(spans) == 3
    assert "drone.FlyByY(1)" in _apply(MISSION, spans, "drone")


def test_a_rename_that_would_clash_is_refused() -> None:
    index = _index()
    at = position_of(MISSION, "d.FlyByX")
    assert rename(index, *at, "i") is None  # the index of the same loop
    assert rename(index, *at, "Team") is None  # a group
    assert rename(index, *at, "Scout") is None  # a drone
    assert rename(index, *at, "range") is None  # Go's keyword
    assert rename(index, *position_of(MISSION, "Team [4]"), "Scout") is None


def test_definition_and_references_of_variables_and_groups() -> None:
    index = _index()
    (found,) = definition(index, *position_of(MISSION, "d.FlyByY"))
    assert (found.line, found.col) == position_of(MISSION, "d := range")
    (found,) = definition(index, *position_of(MISSION, "m.Land"))
    assert (found.line, found.col) == position_of(MISSION, "m := range")
    group_uses = references(index, *position_of(MISSION, "Team.Z()"))
    assert len(group_uses) == MISSION.count("Team")


def test_hover_explains_groups_members_and_loop_variables() -> None:
    index = _index()
    group = hover(index, *position_of(MISSION, "Team [4]"))
    assert group is not None
    assert "a group of 4 Quadcopter drones" in group.markdown and "`Team_3`" in group.markdown
    member = hover(index, *position_of(MISSION, "Team[2:4]"))
    assert member is not None and "a group of 4" in member.markdown
    text = MISSION.replace("Scout.Arm()", "Team[3].Arm()")
    member = hover(_index(text), *position_of(text, "Team[3]"))
    assert member is not None and "member 3 of the group Team" in member.markdown
    assert "the drone `Team_3`" in member.markdown
    d = hover(index, *position_of(MISSION, "d.FlyByX"))
    assert d is not None and "each member of Team in turn" in d.markdown
    assert "Takeoff" in d.markdown  # its type's actions
    i = hover(index, *position_of(MISSION, "2 * i", offset=4))
    assert i is not None and "the index of each member of Team" in i.markdown
    counter = hover(index, *position_of(MISSION, "1 + i", offset=4))
    assert counter is not None and "the counter of the loop at line 10" in counter.markdown
    g = hover(index, *position_of(MISSION, "range g", offset=6))
    assert g is not None and "a parameter of PAR_Half" in g.markdown


def test_completion_knows_members_groups_and_loop_variables() -> None:
    # After a loop's member variable, after a member and after a group parameter's member.
    text = MISSION.replace("\t\td.FlyByY(1)\n", "\t\td.\n")
    assert {"Takeoff", "FlyByX", "Land"} <= _labels(text, "\t\td.\n", 4)
    text = MISSION.replace("\tScout.Arm()\n", "\tTeam[3].\n")
    assert {"Takeoff", "Arm"} <= _labels(text, "\tTeam[3].\n", 9)
    # Inside a group condition: the properties of the members.
    text = MISSION.replace("All(Team.Z() > 1)", "All(Team.)")
    assert {"Z", "X", "Battery"} <= _labels(text, "All(Team.)", 9)
    # At the start of a statement in a loop: its variables, the groups, the loops' snippets.
    text = MISSION.replace("\t\td.FlyByY(1)\n", "\t\t\n")
    offered = _labels(text, "\t\t\n", 2)
    assert {"d", "i", "Team", "Scout", "for", "SEQ_Down"} <= offered
    # Out of the loop, its variables are not offered.
    outside = _labels(MISSION.replace("\tPAR_Fly()\n", "\t\n"), "\t\n", 1)
    assert "Team" in outside and "d" not in outside
    # In len( ... ): the groups.
    text = MISSION.replace("range 2", "range len(")
    assert "Team" in _labels(text, "len(", 4)
    # In a condition: the group conditions.
    text = MISSION.replace("All(Team.Z() > 1)", "")
    assert {"All", "Any", "Count", "Team"} <= _labels(text, "WaitUntil(", 10)


def test_the_outline_lists_the_group_with_its_size_and_type() -> None:
    found = {s.name: s for s in symbols(_index())}
    assert found["Team"].kind == "group" and found["Team"].detail == "[4]Quadcopter"
    assert "d" not in found and "i" not in found


def test_broken_text_still_knows_the_group() -> None:
    text = MISSION.replace("func PAR_Fly() {", "func PAR_Fly() {{")  # does not parse
    index = _index(text)
    assert "Team" in index.groups and "Team" not in index.drones
    assert {"Takeoff", "Land"} <= _labels(text.replace("Scout.Arm()", "Team[1]."), "Team[1].", 8)


# -- through a real client ------------------------------------------------------------------

TIMEOUT_S = 60.0


@pytest_lsp.fixture(
    scope="module",
    config=ClientServerConfig(server_command=[sys.executable, "-m", "eamos.cli", "lsp"]),
)
async def client(lsp_client: LanguageClient):  # type: ignore[no-untyped-def]
    await lsp_client.initialize_session(
        lsp.InitializeParams(capabilities=client_capabilities("visual-studio-code"))
    )
    yield
    await lsp_client.shutdown_session()


async def _open(client: LanguageClient, uri: str, text: str) -> None:
    client.text_document_did_open(
        lsp.DidOpenTextDocumentParams(lsp.TextDocumentItem(uri, "eamos", 1, text))
    )


def _position(text: str, needle: str, offset: int = 0) -> lsp.Position:
    line, col = position_of(text, needle, offset=offset)
    return lsp.Position(line - 1, col - 1)


@pytest.mark.asyncio(loop_scope="module")
async def test_the_server_completes_hovers_and_renames_groups(client: LanguageClient) -> None:
    uri = (REPO / "missions" / "fleets" / "server_groups.go").as_uri()
    text = MISSION.replace("\t\td.FlyByY(1)\n", "\t\td.FlyByY(1)\n\t\td.\n")
    await _open(client, uri, text)
    result = await client.text_document_completion_async(
        lsp.CompletionParams(lsp.TextDocumentIdentifier(uri), _position(text, "\t\td.\n", 4))
    )
    assert isinstance(result, lsp.CompletionList)
    assert {"Takeoff", "FlyByX"} <= {item.label for item in result.items}

    found = await client.text_document_hover_async(
        lsp.HoverParams(lsp.TextDocumentIdentifier(uri), _position(text, "Team [4]"))
    )
    assert found is not None and isinstance(found.contents, lsp.MarkupContent)
    assert "a group of 4 Quadcopter drones" in found.contents.value

    edit = await client.text_document_rename_async(
        lsp.RenameParams(lsp.TextDocumentIdentifier(uri), _position(text, "i := range 2"), "row")
    )
    assert edit is not None and edit.changes is not None
    edits = edit.changes[uri]
    assert len(edits) == 3 and all(e.new_text == "row" for e in edits)
    rows = {e.range.start.line for e in edits}
    assert rows == {position_of(text, "i := range 2")[0] - 1, position_of(text, "1 + i")[0] - 1}
