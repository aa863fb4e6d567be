"""``eamos lsp``: the language server over stdio (pygls 2, lsprotocol).

This module only speaks the protocol: every answer comes from the pure analysis
(:mod:`.document`, :mod:`.features`, :mod:`.completion`), converted between the compiler's
coordinates and the protocol's (:mod:`.positions`).  Full-text sync: every change is
checked at once by the compiler's checking phases (:func:`~.document.checked_findings`, what
the author sees while typing), then the whole compile runs on a worker thread and, if it finds
more (a limit only the graph phases see), its findings replace them: the editor ends with
exactly what ``eamos compile`` prints.  A handler that
fails logs the error (to the editor's log and to stderr) and answers empty: a bug of ours
must not take the editor's language support down.

The transport is this module's own (:meth:`MissionServer.start_io`, :mod:`.framing`):
pygls' reader goes silent after one frame with a wrong ``Content-Length``, and a
request whose params do not fit their type gets no answer from it at all.  Here every
frame is read by :class:`~.framing.FrameReader`, which finds its way back to the next
header; a request that cannot be decoded, or whose params do not fit, is answered with
a JSON-RPC error (parse error, invalid request, invalid params); everything else goes
to pygls' protocol (``structure_message``, ``handle_message``) as its own reader would
hand it over.
"""

from __future__ import annotations

import asyncio
import functools
import logging
import sys
import urllib.parse
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any, BinaryIO, TypeVar

from lsprotocol import types as lsp
from pygls.io_ import StdoutWriter
from pygls.lsp.server import LanguageServer

from .. import __version__
from .completion import Item, completions
from .document import Finding, MissionIndex, Span, checked_findings, findings
from .features import definition, hover, library_block_at, references, rename, symbols
from .libraries import LibraryBlock
from .positions import Encoding, LineIndex, Point
from .transport import Transport

log = logging.getLogger("eamos.lsp")

F = TypeVar("F", bound=Callable[..., Any])

_KINDS = {
    "action": lsp.CompletionItemKind.Method,
    "property": lsp.CompletionItemKind.Property,
    "control": lsp.CompletionItemKind.Keyword,
    "block": lsp.CompletionItemKind.Function,
    "drone": lsp.CompletionItemKind.Variable,
    "type": lsp.CompletionItemKind.Class,
    "keyword": lsp.CompletionItemKind.Keyword,
    "library": lsp.CompletionItemKind.Module,
    "group": lsp.CompletionItemKind.Variable,
    "variable": lsp.CompletionItemKind.Variable,
}


class MissionServer(LanguageServer):
    """The server, with the analysis of each open document kept until its text changes."""

    def __init__(self) -> None:
        super().__init__(
            "eamos", __version__, text_document_sync_kind=lsp.TextDocumentSyncKind.Full
        )
        self._indexes: dict[str, MissionIndex] = {}
        # One worker: whole compiles run one at a time, and only for the latest text.
        self.compiles = ThreadPoolExecutor(max_workers=1, thread_name_prefix="eamos-compile")
        self.generation: dict[str, int] = {}

    def text(self, uri: str) -> str:
        """The current text of an open document ("" if the editor never opened it)."""
        document = self.workspace.get_text_document(uri)
        return document.source

    def index(self, uri: str) -> MissionIndex:
        """The document's index of names, rebuilt only when its text changed."""
        text = self.text(uri)
        cached = self._indexes.get(uri)
        if cached is None or cached.text != text:
            cached = MissionIndex(text, mission_path(uri))
            self._indexes[uri] = cached
        return cached

    def forget(self, uri: str) -> None:
        """Drop what is kept about a closed document."""
        self._indexes.pop(uri, None)

    @property
    def encoding(self) -> Encoding:
        """The position encoding negotiated with the client (UTF-16 unless it chose another)."""
        chosen = str(self.workspace.position_encoding or "utf-16")
        return chosen if chosen in ("utf-8", "utf-32") else "utf-16"  # type: ignore[return-value]

    def lines(self, text: str) -> LineIndex:
        """A position converter for ``text`` in the negotiated encoding."""
        return LineIndex(text, self.encoding)

    def snippets(self) -> bool:
        """Whether the client accepts snippets in completions."""
        caps = self.client_capabilities.text_document
        item = caps.completion.completion_item if caps and caps.completion else None
        return bool(item and item.snippet_support)

    # -- the transport: framing errors survived, every request answered -----------------

    def tell(self, text: str) -> None:
        """Show the editor a problem with what it sent (as pygls' own reader does)."""
        self.window_show_message(lsp.ShowMessageParams(lsp.MessageType.Error, text))

    def start_io(self, stdin: BinaryIO | None = None, stdout: BinaryIO | None = None) -> None:
        """Serve the editor on ``stdin``/``stdout`` until it closes them or says ``exit``."""
        writer = StdoutWriter(stdout or sys.stdout.buffer)
        self.protocol.set_writer(writer)
        transport = Transport(self.protocol, writer, self.tell)
        try:
            asyncio.run(transport.serve(stdin or sys.stdin.buffer))
        except BrokenPipeError:
            log.error("eamos lsp: the editor went away")
        except (KeyboardInterrupt, SystemExit):
            pass  # "exit" from the editor (pygls raises SystemExit), or Ctrl-C
        finally:
            self.shutdown()


def to_range(lines: LineIndex, span: Span) -> lsp.Range:
    """A span of the text as a protocol range."""
    start = lines.to_point(span.line, span.col)
    end = lines.to_point(span.line, span.end_col)
    return lsp.Range(
        lsp.Position(start.line, start.character), lsp.Position(end.line, end.character)
    )


def to_diagnostic(lines: LineIndex, finding: Finding) -> lsp.Diagnostic:
    """A compiler finding as a protocol diagnostic: the message, then its hint."""
    message = f"{finding.message}\nhint: {finding.hint}" if finding.hint else finding.message
    severity = (
        lsp.DiagnosticSeverity.Error
        if finding.severity == "error"
        else lsp.DiagnosticSeverity.Warning
    )
    return lsp.Diagnostic(
        range=to_range(lines, finding.span), message=message, severity=severity, source="eamos"
    )


def to_completion(item: Item, snippets: bool) -> lsp.CompletionItem:
    """A completion as the protocol's item (a snippet only if the client takes snippets)."""
    doc = (
        lsp.MarkupContent(lsp.MarkupKind.Markdown, item.documentation)
        if item.documentation
        else None
    )
    use_snippet = snippets and item.snippet is not None
    return lsp.CompletionItem(
        label=item.label,
        kind=_KINDS[item.kind],
        detail=item.detail,
        documentation=doc,
        insert_text=item.snippet if use_snippet else None,
        insert_text_format=lsp.InsertTextFormat.Snippet if use_snippet else None,
    )


def _log_failure(server: MissionServer, name: str, exc: Exception) -> None:
    log.error("eamos lsp: %s failed: %r", name, exc, exc_info=exc)
    try:
        server.window_log_message(
            lsp.LogMessageParams(lsp.MessageType.Error, f"eamos lsp: {name} failed: {exc!r}")
        )
    except Exception:  # pragma: no cover - the client went away
        pass


def _safe(default: Callable[[], object]) -> Callable[[F], F]:
    """Turn an exception in a handler into a logged error and an empty answer."""

    def wrap(handler: F) -> F:
        @functools.wraps(handler)
        def safe(server: MissionServer, params: Any) -> Any:
            try:
                return handler(server, params)
            except Exception as exc:  # any bug of ours: log it, answer empty
                _log_failure(server, handler.__name__, exc)
                return default()

        return safe  # type: ignore[return-value]

    return wrap


async def _safely(server: MissionServer, name: str, work: Any) -> None:
    """Await a notification's work; a failure is logged, never raised to the protocol."""
    try:
        await work
    except Exception as exc:  # any bug of ours: log it
        _log_failure(server, name, exc)


def _where(
    server: MissionServer, uri: str, position: lsp.Position
) -> tuple[MissionIndex, LineIndex, int, int]:
    index = server.index(uri)
    lines = server.lines(index.text)
    line, col = lines.to_location(Point(position.line, position.character))
    return index, lines, line, col


def publish(server: MissionServer, uri: str, version: int | None, found: list[Finding]) -> None:
    """Publish findings about a document's text as the editor's diagnostics."""
    lines = server.lines(server.text(uri))
    diagnostics = [to_diagnostic(lines, f) for f in found]
    server.text_document_publish_diagnostics(
        lsp.PublishDiagnosticsParams(uri=uri, diagnostics=diagnostics, version=version)
    )


def mission_path(uri: str) -> str:
    """The file a ``file:`` URI names (its folder is where imports are looked up first)."""
    parsed = urllib.parse.urlparse(uri)
    if parsed.scheme != "file":
        return "<mission>"
    return urllib.parse.unquote(parsed.path) or "<mission>"


async def check(server: MissionServer, uri: str, version: int | None) -> None:
    """Publish the checking phases' findings now, the whole compile's when it differs."""
    text = server.text(uri)
    generation = server.generation.get(uri, 0) + 1
    server.generation[uri] = generation
    path = mission_path(uri)
    quick = checked_findings(text, path)
    publish(server, uri, version, quick)

    def whole() -> list[Finding] | None:
        # Skipped when the author typed again meanwhile: a newer check is queued.
        return findings(text, path) if server.generation.get(uri) == generation else None

    full = await asyncio.get_running_loop().run_in_executor(server.compiles, whole)
    if full is not None and full != quick and server.generation.get(uri) == generation:
        publish(server, uri, version, full)


def library_location(server: MissionServer, block: LibraryBlock) -> lsp.Location:
    """Where a library's block is defined: its name in the library file."""
    path = Path(block.file)
    lines = server.lines(path.read_text(encoding="utf-8"))
    span = Span(block.line, block.col, block.col + len(block.name))
    return lsp.Location(path.resolve().as_uri(), to_range(lines, span))


def build_server() -> MissionServer:
    """A server with every feature registered (not started)."""
    server = MissionServer()

    @server.feature(lsp.TEXT_DOCUMENT_DID_OPEN)
    async def did_open(ls: MissionServer, params: lsp.DidOpenTextDocumentParams) -> None:
        doc = params.text_document
        await _safely(ls, "did_open", check(ls, doc.uri, doc.version))

    @server.feature(lsp.TEXT_DOCUMENT_DID_CHANGE)
    async def did_change(ls: MissionServer, params: lsp.DidChangeTextDocumentParams) -> None:
        doc = params.text_document
        await _safely(ls, "did_change", check(ls, doc.uri, doc.version))

    @server.feature(lsp.TEXT_DOCUMENT_DID_CLOSE)
    @_safe(lambda: None)
    def did_close(ls: MissionServer, params: lsp.DidCloseTextDocumentParams) -> None:
        ls.forget(params.text_document.uri)
        ls.generation.pop(params.text_document.uri, None)
        ls.text_document_publish_diagnostics(
            lsp.PublishDiagnosticsParams(uri=params.text_document.uri, diagnostics=[])
        )

    @server.feature(
        lsp.TEXT_DOCUMENT_COMPLETION, lsp.CompletionOptions(trigger_characters=[".", "(", ","])
    )
    @_safe(lambda: lsp.CompletionList(is_incomplete=False, items=[]))
    def completion(ls: MissionServer, params: lsp.CompletionParams) -> lsp.CompletionList:
        index, _, line, col = _where(ls, params.text_document.uri, params.position)
        snippets = ls.snippets()
        items = [to_completion(i, snippets) for i in completions(index, line, col)]
        return lsp.CompletionList(is_incomplete=False, items=items)

    @server.feature(lsp.TEXT_DOCUMENT_HOVER)
    @_safe(lambda: None)
    def on_hover(ls: MissionServer, params: lsp.HoverParams) -> lsp.Hover | None:
        index, lines, line, col = _where(ls, params.text_document.uri, params.position)
        found = hover(index, line, col)
        if found is None:
            return None
        content = lsp.MarkupContent(lsp.MarkupKind.Markdown, found.markdown)
        return lsp.Hover(contents=content, range=to_range(lines, found.span))

    @server.feature(lsp.TEXT_DOCUMENT_DEFINITION)
    @_safe(list)
    def on_definition(ls: MissionServer, params: lsp.DefinitionParams) -> list[lsp.Location]:
        uri = params.text_document.uri
        index, lines, line, col = _where(ls, uri, params.position)
        found = [lsp.Location(uri, to_range(lines, s)) for s in definition(index, line, col)]
        library = library_block_at(index, line, col) if not found else None
        if library is not None:
            found = [library_location(ls, library[0])]
        return found

    @server.feature(lsp.TEXT_DOCUMENT_REFERENCES)
    @_safe(list)
    def on_references(ls: MissionServer, params: lsp.ReferenceParams) -> list[lsp.Location]:
        uri = params.text_document.uri
        index, lines, line, col = _where(ls, uri, params.position)
        spans = references(index, line, col, params.context.include_declaration)
        return [lsp.Location(uri, to_range(lines, s)) for s in spans]

    @server.feature(lsp.TEXT_DOCUMENT_DOCUMENT_SYMBOL)
    @_safe(list)
    def on_symbols(ls: MissionServer, params: lsp.DocumentSymbolParams) -> list[lsp.DocumentSymbol]:
        index = ls.index(params.text_document.uri)
        lines = ls.lines(index.text)
        out = []
        for symbol in symbols(index):
            where = to_range(lines, symbol.span)
            kind = {"drone": lsp.SymbolKind.Variable, "group": lsp.SymbolKind.Array}.get(
                symbol.kind, lsp.SymbolKind.Function
            )
            detail = f"{symbol.kind}: {symbol.detail}" if symbol.detail else symbol.kind
            out.append(lsp.DocumentSymbol(symbol.name, kind, where, where, detail=detail))
        return out

    @server.feature(lsp.TEXT_DOCUMENT_PREPARE_RENAME)
    @_safe(lambda: None)
    def on_prepare_rename(ls: MissionServer, params: lsp.PrepareRenameParams) -> lsp.Range | None:
        index, lines, line, col = _where(ls, params.text_document.uri, params.position)
        occ = index.at(line, col)
        return None if occ is None else to_range(lines, occ.span)

    @server.feature(lsp.TEXT_DOCUMENT_RENAME)
    @_safe(lambda: None)
    def on_rename(ls: MissionServer, params: lsp.RenameParams) -> lsp.WorkspaceEdit | None:
        uri = params.text_document.uri
        index, lines, line, col = _where(ls, uri, params.position)
        spans = rename(index, line, col, params.new_name)
        if spans is None:
            return None
        edits = [lsp.TextEdit(to_range(lines, s), params.new_name) for s in spans]
        return lsp.WorkspaceEdit(changes={uri: edits})

    return server


class _OneLine(logging.Formatter):
    """Log records on one line each: no traceback unless ``verbose`` (``eamos lsp -v``)."""

    def __init__(self, verbose: bool) -> None:
        super().__init__("%(levelname)s %(name)s: %(message)s")
        self.verbose = verbose

    def format(self, record: logging.LogRecord) -> str:
        if self.verbose:
            return super().format(record)
        brief = logging.makeLogRecord(record.__dict__)
        # pygls puts tracebacks in some messages' text: the first line only.
        brief.msg, brief.args = record.getMessage().split("\n", 1)[0], None
        if record.exc_info and record.exc_info[1] is not None:
            brief.msg = f"{brief.msg}: {record.exc_info[1]!r}"
        brief.exc_info = brief.exc_text = None
        brief.stack_info = None
        return super().format(brief)


def serve(verbose: bool = False) -> None:
    """Run the language server on stdin/stdout until the client exits.

    Logs go to stderr (the editor's log of the server), one line per record; tracebacks of
    our own failures and of malformed messages only with ``verbose``.
    """
    handler = logging.StreamHandler()
    handler.setFormatter(_OneLine(verbose))
    logging.basicConfig(level=logging.WARNING, handlers=[handler], force=True)
    build_server().start_io()
