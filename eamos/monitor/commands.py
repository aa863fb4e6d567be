"""The monitor's commands: ``POST /api/abort`` and ``POST /api/command`` (pause, resume, ...).

``{"token", "command", "drone"}`` (``drone`` "" for the mission's pause and resume), with
the run's token, as the abort: the same guards (JSON only, a bounded body, the page's own
origin).  The command goes to the ground station the way ``eamos pause`` sends it, through
the run folder's operator socket (:mod:`eamos.ground.operator`), with the page as its
origin; the answer says whether the ground station sent it, or why not.
"""

from __future__ import annotations

import asyncio
import json
import secrets
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, Protocol

if TYPE_CHECKING:
    from starlette.requests import Request
    from starlette.responses import Response

__all__ = ["abort_endpoint", "amend_endpoint", "bounded_body", "command_endpoint"]


class CommandedServer(Protocol):
    """What the endpoint needs of :class:`~.server.MonitorServer`."""

    token: str
    replay: Any
    hub: Any
    on_abort: Callable[[str, bool], None] | None
    on_command: Callable[[str, str, str], str] | None
    on_amend: Callable[[str, str], dict[str, Any]] | None

    def refuse(self, origin: str, why: str, abort: bool = False) -> None: ...


#: The largest body read (an abort is ``{"token": "..."}``: some 40 bytes; a command 120).
MAX_COMMAND_BYTES = 4096
#: The largest amendment read: a mission text of a few thousand lines.
MAX_AMEND_BYTES = 512 * 1024


async def abort_endpoint(server: CommandedServer, request: Request) -> Response:
    """``{"token"}``: abort the run (``server.on_abort``), 403 without the run's token."""
    from starlette.responses import JSONResponse

    peer = request.client
    agent = request.headers.get("user-agent", "?")
    origin = f"monitor page at {peer.host}:{peer.port} ({agent[:60]})" if peer else "monitor"
    if server.replay is not None:
        return JSONResponse({"ok": False, "error": "a replay cannot abort"}, status_code=409)
    kind = request.headers.get("content-type", "").split(";")[0].strip().lower()
    if kind != "application/json":
        server.refuse(origin, "the body is not application/json")
        return JSONResponse({"ok": False, "error": "send JSON"}, status_code=415)
    body = await bounded_body(request, MAX_COMMAND_BYTES)
    if body is None:
        server.refuse(origin, f"a body over {MAX_COMMAND_BYTES} bytes")
        return JSONResponse({"ok": False, "error": "body too large"}, status_code=413)
    try:
        data = json.loads(body)
    except (ValueError, RecursionError):
        data = None
    token = data.get("token") if isinstance(data, dict) else None
    accepted = isinstance(token, str) and secrets.compare_digest(token, server.token)
    if accepted:
        server.hub.abort_request(origin, True)
        if server.on_abort is not None:
            server.on_abort(origin, True)
        return JSONResponse({"ok": True})
    server.refuse(origin, "not the run's token", abort=True)
    return JSONResponse({"ok": False, "error": "not the run's token"}, status_code=403)


def _answer(error: str, status: int) -> Response:
    from starlette.responses import JSONResponse

    return JSONResponse({"ok": False, "error": error}, status_code=status)


async def _guarded(
    server: CommandedServer, request: Request, what: str, limit: int
) -> tuple[dict[str, Any], str] | Response:
    """A request to the run checked as every command is: JSON only, a body of at most
    ``limit`` bytes, the run's token; ``(its fields, the page's origin)``, or the answer
    refusing it (each refusal told through ``server.refuse``, as ``what``)."""
    peer = request.client
    origin = f"monitor page at {peer.host}:{peer.port}" if peer else "monitor page"
    kind = request.headers.get("content-type", "").split(";")[0].strip().lower()
    if kind != "application/json":
        server.refuse(origin, "the body is not application/json")
        return _answer("send JSON", 415)
    body = await bounded_body(request, limit)
    if body is None:
        server.refuse(origin, f"{what} over {limit} bytes")
        return _answer("body too large", 413)
    try:
        data = json.loads(body)
    except (ValueError, RecursionError):
        data = None
    data = data if isinstance(data, dict) else {}
    token = data.get("token")
    if not (isinstance(token, str) and secrets.compare_digest(token, server.token)):
        server.refuse(origin, f"{what} without the run's token")
        return _answer("not the run's token", 403)
    return data, origin


async def command_endpoint(server: CommandedServer, request: Request) -> Response:
    """Check a command request and hand it to ``server.on_command`` (on a worker thread:
    it waits for the ground station's answer)."""
    from starlette.responses import JSONResponse

    if server.replay is not None or server.on_command is None:
        return _answer("this monitor cannot command the run (a replay?)", 409)
    checked = await _guarded(server, request, "a command", MAX_COMMAND_BYTES)
    if not isinstance(checked, tuple):
        return checked
    data, origin = checked
    command, drone = data.get("command"), data.get("drone", "")
    if not isinstance(command, str) or not isinstance(drone, str):
        return _answer("command and drone must be strings", 400)
    why = await asyncio.to_thread(server.on_command, command[:40], drone[:100], origin)
    if why:
        return _answer(why, 409)
    return JSONResponse({"ok": True})


async def amend_endpoint(server: CommandedServer, request: Request) -> Response:
    """``{"token", "text"}``: judge an amendment to the flying mission (``server.on_amend``,
    on a worker thread: it compiles and simulates), as ``eamos amend`` does; the answer is
    its report (``ok`` false with ``error`` for a text that does not compile)."""
    from starlette.responses import JSONResponse

    if server.replay is not None or server.on_amend is None:
        return _answer("this monitor cannot amend the run (a replay?)", 409)
    checked = await _guarded(server, request, "an amendment", MAX_AMEND_BYTES)
    if not isinstance(checked, tuple):
        return checked
    data, origin = checked
    text = data.get("text")
    if not isinstance(text, str):
        return _answer("text must be the mission's text", 400)
    doc = await asyncio.to_thread(server.on_amend, text, origin)
    return JSONResponse(doc, status_code=200 if doc.get("ok") else 422)


async def bounded_body(request: Request, limit: int) -> bytes | None:
    """The request's body, read in pieces (Starlette's ``request.stream()``); None as soon
    as it is over ``limit`` bytes (declared or sent), the rest never read."""
    declared = request.headers.get("content-length")
    if declared is not None and (not declared.isdigit() or int(declared) > limit):
        return None
    body = bytearray()
    async for chunk in request.stream():
        body += chunk
        if len(body) > limit:
            return None
    return bytes(body)
