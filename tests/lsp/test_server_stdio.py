"""``eamos lsp`` end to end: a real LSP client (pytest-lsp) talks to the server over stdio.

The server runs as ``python -m eamos.cli lsp``, exactly as an editor starts ``eamos lsp``.
"""

from __future__ import annotations

import asyncio
import contextlib
import sys
import time
from collections.abc import Callable, Sequence

import pytest
import pytest_lsp
from lsprotocol import types as lsp
from pytest_lsp import ClientServerConfig, LanguageClient, client_capabilities

from eamos.compiler import MissionError, compile_mission

from .lsp_helpers import MISSIONS, THREE_ERRORS, position_of, too_many_sync_arcs

pytestmark = [pytest.mark.asyncio(loop_scope="module"), pytest.mark.xdist_group("lsp-stdio-server")]

TIMEOUT_S = 60.0  # generous: a loaded 2-core machine starts Python slowly


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


Check = Callable[[list[lsp.Diagnostic]], bool]


async def _diagnostics(
    client: LanguageClient, uri: str, until: Check = lambda d: True
) -> list[lsp.Diagnostic]:
    """The diagnostics last published for ``uri`` once they satisfy ``until``.

    Re-checked after every notification (and at least every second, so that two
    notifications read in one go cannot leave the wait hanging).
    """
    deadline = time.monotonic() + TIMEOUT_S
    while True:
        current = client.diagnostics.get(uri)
        if current is not None and until(list(current)):
            return list(current)
        remaining = deadline - time.monotonic()
        if remaining <= 0:
            raise TimeoutError(f"no diagnostics as expected for {uri}: {current}")
        with contextlib.suppress(TimeoutError):
            await asyncio.wait_for(
                client.wait_for_notification(lsp.TEXT_DOCUMENT_PUBLISH_DIAGNOSTICS),
                min(1.0, remaining),
            )


async def _open(
    client: LanguageClient, uri: str, text: str, until: Check = lambda d: True
) -> list[lsp.Diagnostic]:
    client.text_document_did_open(
        lsp.DidOpenTextDocumentParams(lsp.TextDocumentItem(uri, "eamos", 1, text))
    )
    return await _diagnostics(client, uri, until)


def _expected(text: str) -> list[tuple[int, int, str]]:
    with pytest.raises(MissionError) as info:
        compile_mission(text, "three.go")
    return [
        (d.loc.line - 1, d.loc.col - 1, f"{d.message}\nhint: {d.hint}" if d.hint else d.message)
        for d in info.value.diagnostics
    ]


def _got(diagnostics: list[lsp.Diagnostic]) -> list[tuple[int, int, str]]:
    return [(d.range.start.line, d.range.start.character, d.message) for d in diagnostics]


async def test_three_errors_then_two_after_a_fix(client: LanguageClient) -> None:
    uri = "file:///missions/three.go"
    found = await _open(client, uri, THREE_ERRORS)
    assert len(found) == 3
    assert _got(found) == _expected(THREE_ERRORS)
    assert all(d.severity == lsp.DiagnosticSeverity.Error for d in found)
    first = found[0].range
    assert (first.end.character - first.start.character) == len("Takof")

    fixed = THREE_ERRORS.replace("Takof(", "Takeoff(")
    client.text_document_did_change(
        lsp.DidChangeTextDocumentParams(
            lsp.VersionedTextDocumentIdentifier(2, uri),
            [lsp.TextDocumentContentChangeWholeDocument(fixed)],
        )
    )
    now = await _diagnostics(client, uri, lambda d: len(d) != 3)
    assert len(now) == 2
    assert _got(now) == _expected(fixed)


async def test_non_ascii_names_get_utf16_ranges(client: LanguageClient) -> None:
    uri = "file:///missions/unicode.go"
    text = "var Drône𠀋 Quadcopter\nfunc SEQ_A() { Drône𠀋.Arm(); Drône𠀋.Takof(1) }\n"
    (found,) = await _open(client, uri, text)
    line, col = position_of(text, "Takof")
    # Two names of 6 characters each stand before it, each 7 UTF-16 code units long.
    assert found.range.start == lsp.Position(line - 1, col - 1 + 2)
    assert found.range.end == lsp.Position(line - 1, col - 1 + 2 + 5)


async def test_completion_after_a_drone(client: LanguageClient) -> None:
    uri = "file:///missions/complete.go"
    text = "var Drone1 DroneType2\nfunc SEQ_A() {\n\tDrone1.Arm()\n\tDrone1.\n}\n"
    await _open(client, uri, text)
    result = await client.text_document_completion_async(
        lsp.CompletionParams(lsp.TextDocumentIdentifier(uri), lsp.Position(3, 8))
    )
    assert isinstance(result, lsp.CompletionList)
    labels = {item.label for item in result.items}
    assert {"Takeoff", "FlyToXYZ", "TurnOnCamera", "PauseWhile"} <= labels
    takeoff = next(i for i in result.items if i.label == "Takeoff")
    assert takeoff.insert_text == "Takeoff(${1:height_m})"
    assert takeoff.insert_text_format == lsp.InsertTextFormat.Snippet


async def test_hover_an_action_and_go_to_a_blocks_definition(client: LanguageClient) -> None:
    uri = "file:///missions/experiment_d.go"
    text = (MISSIONS / "experiment_d.go").read_text(encoding="utf-8")
    assert await _open(client, uri, text) == []
    line, col = position_of(text, "Takeoff")
    hover = await client.text_document_hover_async(
        lsp.HoverParams(lsp.TextDocumentIdentifier(uri), lsp.Position(line - 1, col))
    )
    assert hover is not None and isinstance(hover.contents, lsp.MarkupContent)
    assert "height_m" in hover.contents.value and "metres" in hover.contents.value

    line, col = position_of(text, "SEQ_2()")
    found = await client.text_document_definition_async(
        lsp.DefinitionParams(lsp.TextDocumentIdentifier(uri), lsp.Position(line - 1, col))
    )
    assert isinstance(found, list) and len(found) == 1
    def_line, def_col = position_of(text, "func SEQ_2", offset=5)
    assert found[0].range.start == lsp.Position(def_line - 1, def_col - 1)

    symbols = await client.text_document_document_symbol_async(
        lsp.DocumentSymbolParams(lsp.TextDocumentIdentifier(uri))
    )
    assert symbols is not None
    assert "PAR_Loop" in {s.name for s in symbols}


async def test_rename_a_drone_across_the_file(client: LanguageClient) -> None:
    uri = "file:///missions/rename.go"
    text = (MISSIONS / "experiment_d.go").read_text(encoding="utf-8")
    await _open(client, uri, text)
    line, col = position_of(text, "D3.Arm")
    edit = await client.text_document_rename_async(
        lsp.RenameParams(lsp.TextDocumentIdentifier(uri), lsp.Position(line - 1, col), "Pilot")
    )
    assert edit is not None and edit.changes is not None
    edits = edit.changes[uri]
    lines = text.splitlines()
    for e in edits:
        assert e.new_text == "Pilot"
        assert lines[e.range.start.line][e.range.start.character : e.range.end.character] == "D3"
    code_uses = sum(line.count("D3") for line in lines if not line.lstrip().startswith("//"))
    assert len(edits) == code_uses
    renamed = _apply(text, edits)
    compile_mission(renamed, "renamed.go")  # still a valid mission
    assert "D3" not in "\n".join(x for x in renamed.splitlines() if not x.startswith("//"))


def _apply(text: str, edits: Sequence[lsp.TextEdit]) -> str:
    lines = text.split("\n")
    for e in sorted(
        edits, key=lambda e: (e.range.start.line, e.range.start.character), reverse=True
    ):
        row = lines[e.range.start.line]
        s, t = e.range.start.character, e.range.end.character
        lines[e.range.start.line] = row[:s] + e.new_text + row[t:]
    return "\n".join(lines)


async def test_requests_on_broken_text_answer(client: LanguageClient) -> None:
    uri = "file:///missions/broken.go"
    text = "var D1 Quadcopter\nfunc SEQ_A() {\n\tD1.Takeoff((\n\tIf(D1.\n"
    found = await _open(client, uri, text)
    assert found and all(d.severity == lsp.DiagnosticSeverity.Error for d in found)
    for line in range(6):
        for character in (0, 3, 9, 50):
            where = lsp.Position(line, character)
            document = lsp.TextDocumentIdentifier(uri)
            await client.text_document_hover_async(lsp.HoverParams(document, where))
            await client.text_document_completion_async(lsp.CompletionParams(document, where))
            await client.text_document_definition_async(lsp.DefinitionParams(document, where))
    props = await client.text_document_completion_async(
        lsp.CompletionParams(lsp.TextDocumentIdentifier(uri), lsp.Position(3, 7))
    )
    assert isinstance(props, lsp.CompletionList)
    assert "Battery" in {i.label for i in props.items}


async def test_a_failing_handler_logs_an_error_and_answers_empty(client: LanguageClient) -> None:
    # A document the editor never opened and that no file holds: reading it fails inside
    # the handler; the server logs the failure and answers empty, and keeps serving.
    uri = "file:///nowhere/never-opened.go"
    document = lsp.TextDocumentIdentifier(uri)
    where = lsp.Position(0, 0)
    assert await client.text_document_hover_async(lsp.HoverParams(document, where)) is None
    assert await client.text_document_definition_async(lsp.DefinitionParams(document, where)) == []
    errors = [m for m in client.log_messages if m.type == lsp.MessageType.Error]
    assert any("on_hover failed" in m.message for m in errors), errors
    found = await _open(client, "file:///missions/after.go", THREE_ERRORS, lambda d: len(d) == 3)
    assert len(found) == 3


async def test_what_only_the_whole_compile_finds_follows(client: LanguageClient) -> None:
    uri = "file:///missions/wide.go"
    text = too_many_sync_arcs()
    # The checking phases find nothing; the whole compile on the worker thread finds the
    # limit and publishes again.
    (found,) = await _open(client, uri, text, lambda d: len(d) > 0)
    assert "more than the limit" in found.message
    assert _got([found]) == _expected(text)
