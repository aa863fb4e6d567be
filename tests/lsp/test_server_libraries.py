"""``eamos lsp`` end to end for mission libraries: a real LSP client over stdio (pytest-lsp).

The server runs as ``python -m eamos.cli lsp`` with ``EAMOS_PATH`` set, as an editor
would start it; the mission's URI names a file in ``tests/lsp/libraries/mission/``, so
its folder, ``EAMOS_PATH`` and the standard library are all searched.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import pytest
import pytest_lsp
from lsprotocol import types as lsp
from pytest_lsp import ClientServerConfig, LanguageClient, client_capabilities

from .lsp_helpers import position_of
from .test_server_stdio import _open

pytestmark = [
    pytest.mark.asyncio(loop_scope="module"),
    pytest.mark.xdist_group("lsp-libraries-server"),
]

HERE = Path(__file__).resolve().parent / "libraries"
MISSION = HERE / "mission" / "uses.go"
URI = MISSION.as_uri()
TEXT = MISSION.read_text(encoding="utf-8")


@pytest_lsp.fixture(
    scope="module",
    config=ClientServerConfig(
        server_command=[sys.executable, "-m", "eamos.cli", "lsp"],
        server_env={**os.environ, "EAMOS_PATH": str(HERE / "path")},
    ),
)
async def client(lsp_client: LanguageClient):  # type: ignore[no-untyped-def]
    await lsp_client.initialize_session(
        lsp.InitializeParams(capabilities=client_capabilities("visual-studio-code"))
    )
    yield
    await lsp_client.shutdown_session()


def _at(text: str, needle: str, offset: int = 0) -> lsp.Position:
    line, col = position_of(text, needle, offset=offset)
    return lsp.Position(line - 1, col - 1)


async def _complete(
    client: LanguageClient, uri: str, where: lsp.Position
) -> list[lsp.CompletionItem]:
    result = await client.text_document_completion_async(
        lsp.CompletionParams(lsp.TextDocumentIdentifier(uri), where)
    )
    assert isinstance(result, lsp.CompletionList)
    return list(result.items)


async def test_a_mission_using_three_libraries_has_no_findings(client: LanguageClient) -> None:
    assert await _open(client, URI, TEXT) == []


async def test_import_completes_every_library_folder(client: LanguageClient) -> None:
    uri = (HERE / "mission" / "typing.go").as_uri()
    text = 'import "\nvar D1 Quadcopter\n'
    await _open(client, uri, text, lambda d: len(d) > 0)
    items = await _complete(client, uri, lsp.Position(0, 8))
    by_label = {i.label: i for i in items}
    assert {"inspection", "lab/hover", "shapes", "survey", "fleet"} <= set(by_label)
    assert by_label["inspection"].kind == lsp.CompletionItemKind.Module
    assert by_label["inspection"].detail == "library (mission folder)"
    assert by_label["lab/hover"].detail == "library (EAMOS_PATH)"
    assert by_label["shapes"].detail == "library (standard library)"


async def test_a_package_member_completes_its_blocks(client: LanguageClient) -> None:
    uri = (HERE / "mission" / "member.go").as_uri()
    text = TEXT.replace("\tshapes.SEQ_Square(D1, 2)\n", "\tshapes.\n")
    await _open(client, uri, text, lambda d: len(d) > 0)
    items = await _complete(client, uri, _at(text, "shapes.\n", 7))
    by_label = {i.label: i for i in items}
    assert set(by_label) == {"SEQ_Square", "SEQ_Orbit"}
    square = by_label["SEQ_Square"]
    assert square.insert_text == "SEQ_Square(${1:d}, ${2:side_m})"
    assert square.insert_text_format == lsp.InsertTextFormat.Snippet
    assert square.detail == "shapes.SEQ_Square(d fleet.Flyer, side_m float64)"


async def test_hover_and_go_to_a_library_blocks_definition(client: LanguageClient) -> None:
    await _open(client, URI, TEXT)
    where = _at(TEXT, "SEQ_Look", 3)
    found = await client.text_document_hover_async(
        lsp.HoverParams(lsp.TextDocumentIdentifier(URI), where)
    )
    assert found is not None and isinstance(found.contents, lsp.MarkupContent)
    assert "inspection.SEQ_Look(d Quadcopter, height_m float64)" in found.contents.value
    assert "climbs height_m" in found.contents.value

    targets = await client.text_document_definition_async(
        lsp.DefinitionParams(lsp.TextDocumentIdentifier(URI), where)
    )
    assert isinstance(targets, list) and len(targets) == 1
    library = HERE / "mission" / "inspection" / "inspection.go"
    assert targets[0].uri == library.as_uri()
    text = library.read_text(encoding="utf-8")
    assert targets[0].range.start == _at(text, "func SEQ_Look", 5)
    assert targets[0].range.end.character == targets[0].range.start.character + len("SEQ_Look")

    # A block of the standard library too.
    targets = await client.text_document_definition_async(
        lsp.DefinitionParams(lsp.TextDocumentIdentifier(URI), _at(TEXT, "SEQ_Square", 2))
    )
    assert isinstance(targets, list) and targets[0].uri.endswith("missions_lib/shapes/shapes.go")
