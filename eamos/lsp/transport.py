"""The language server's transport: frames in, pygls' protocol, errors out.

:class:`Transport` replaces pygls' reader loop (``pygls.io_.run_async``), which goes
silent after one frame with a wrong ``Content-Length`` and leaves a request whose params
do not fit their type without any answer.  Frames are read by
:class:`~.framing.FrameReader`, which finds its way back to the next header; a body that
is not JSON, a message that is not an object and a request whose params pygls cannot
type are answered with a JSON-RPC error (parse error, invalid request, invalid params);
every other message goes to pygls' protocol through its public ``structure_message`` and
``handle_message``, as its own reader hands them over.  Each problem is logged on one
line (the first few, then every 100th).
"""

from __future__ import annotations

import asyncio
import functools
import json
import logging
import os
import threading
from collections.abc import Callable
from typing import Any, BinaryIO

from lsprotocol import types as lsp
from pygls.exceptions import JsonRpcException
from pygls.io_ import StdoutWriter
from pygls.protocol import JsonRPCProtocol

from .framing import BadFrame, Frame, FrameReader

__all__ = ["Transport"]

log = logging.getLogger("eamos.lsp")

#: Framing and decoding problems logged one by one up to this many, then every 100th.
_LOG_FIRST = 20


class Transport:
    """Reads frames from the editor, hands messages to pygls' protocol, answers the rest.

    Runs on the server's event loop (every write to the editor happens there, pygls'
    too); one daemon thread reads the input, so a read that blocks never keeps the
    process from ending.
    """

    def __init__(
        self,
        protocol: JsonRPCProtocol,
        writer: StdoutWriter,
        tell: Callable[[str], None] = lambda text: None,
    ) -> None:
        self.protocol = protocol
        self.writer = writer
        self.tell = tell  # shows the editor a problem no error answer carries
        self.problems = 0

    async def serve(self, stdin: BinaryIO) -> None:
        """Until the input ends: read, frame, dispatch."""
        loop = asyncio.get_running_loop()
        chunks: asyncio.Queue[bytes] = asyncio.Queue(maxsize=16)  # the reader waits beyond
        threading.Thread(
            target=_pump, args=(stdin, loop, chunks), name="eamos-lsp-stdin", daemon=True
        ).start()
        frames = FrameReader()
        while chunk := await chunks.get():
            for event in frames.feed(chunk):
                if isinstance(event, Frame):
                    self.message(event.body)
                else:
                    self.bad_frame(event)

    def bad_frame(self, event: BadFrame) -> None:
        request = _json_object(event.body)
        answered = request is not None and "id" in request
        self.problem(f"eamos lsp: {event.reason}", told=answered)
        if request is not None and answered:
            self.error(request["id"], lsp.ErrorCodes.InvalidRequest, f"bad frame: {event.reason}")

    def message(self, body: bytes) -> None:
        """One frame's body: decoded, typed by pygls and handled, or answered with an error."""
        try:
            data = json.loads(body)
        except (ValueError, RecursionError) as exc:
            self.problem(f"eamos lsp: a body that is not JSON ({type(exc).__name__})", exc=exc)
            self.error(None, lsp.ErrorCodes.ParseError, "Parse error: the body is not JSON")
            return
        if not isinstance(data, dict):
            self.problem("eamos lsp: a message that is not a JSON object")
            self.error(None, lsp.ErrorCodes.InvalidRequest, "Invalid request: not an object")
            return
        request = "id" in data and "method" in data
        protocol = self.protocol
        try:
            message = protocol.structure_message(data)
        except JsonRpcException as exc:
            what = exc.message or type(exc).__name__
            self.problem(f"eamos lsp: {data.get('method')!r:.60}: {what}", request, exc)
            if request:
                self.error(data["id"], exc.code, exc.message or "Invalid params")
            return
        except Exception as exc:  # a message pygls' types cannot take at all
            self.problem(f"eamos lsp: {data.get('method')!r:.60}: {exc!r:.200}", request, exc)
            if request:
                self.error(data["id"], lsp.ErrorCodes.InvalidRequest, "Invalid request")
            return
        try:
            protocol.handle_message(message)
        except Exception as exc:  # pygls answers its handlers' failures; this is not one
            method = f"{data.get('method')!r:.60}"
            self.problem(f"eamos lsp: {method} failed: {exc!r:.200}", request, exc)
            if request:
                self.error(data["id"], lsp.ErrorCodes.InternalError, "Internal error")

    def error(self, msg_id: Any, code: int, text: str) -> None:
        """Answer the request ``msg_id`` (None: one whose id cannot be read) with an error."""
        number = isinstance(msg_id, int) and not isinstance(msg_id, bool)
        valid = number or isinstance(msg_id, str)
        reply = {
            "jsonrpc": "2.0",
            "id": msg_id if valid else None,
            "error": {"code": int(code), "message": text},
        }
        body = json.dumps(reply).encode("utf-8")
        self.writer.write(b"Content-Length: %d\r\n\r\n" % len(body) + body)

    def problem(self, text: str, told: bool = False, exc: BaseException | None = None) -> None:
        """Log one line for what the editor sent wrong (the first few, then every 100th),
        and show it in the editor unless an error answer ``told`` it already."""
        self.problems += 1
        if self.problems <= _LOG_FIRST or self.problems % 100 == 0:
            log.warning("%s (problem %d)", text, self.problems, exc_info=exc)
            if not told:
                self.tell(text)


def _pump(stdin: BinaryIO, loop: asyncio.AbstractEventLoop, chunks: asyncio.Queue[bytes]) -> None:
    """The reader thread: stdin's bytes to the loop as they come; b"" at the end."""
    read: Callable[[int], bytes]
    try:
        # The file descriptor, not the buffered file: a thread blocked in a buffered
        # read holds its lock, and the interpreter aborts at exit when it finds it taken.
        read = functools.partial(os.read, stdin.fileno())
    except (AttributeError, OSError, ValueError):  # a file without one (a test's BytesIO)
        read = stdin.read
    while True:
        try:
            chunk = read(65536)
        except (OSError, ValueError):  # closed under us
            chunk = b""
        try:
            asyncio.run_coroutine_threadsafe(chunks.put(chunk), loop).result()
        except (RuntimeError, asyncio.CancelledError):
            return  # the loop ended
        if not chunk:
            return


def _json_object(body: bytes) -> dict[str, Any] | None:
    try:
        data = json.loads(body) if body else None
    except (ValueError, RecursionError):
        return None
    return data if isinstance(data, dict) else None
