"""The monitor's operator commands: ``POST /api/command`` (pause, resume, a drone's hold ...).

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

__all__ = ["bounded_body", "command_endpoint"]


class CommandedServer(Protocol):
    """What the endpoint needs of :class:`~.server.MonitorServer`."""

    token: str
    replay: Any
    on_command: Callable[[str, str, str], str] | None

    def refuse(self, origin: str, why: str, abort: bool = False) -> None: ...


#: The largest command body read (some 120 bytes).
MAX_COMMAND_BYTES = 4096


async def command_endpoint(server: CommandedServer, request: Request) -> Response:
    """Check a command request and hand it to ``server.on_command`` (on a worker thread:
    it waits for the ground station's answer)."""
    from starlette.responses import JSONResponse

    def answer(error: str, status: int) -> Response:
        return JSONResponse({"ok": False, "error": error}, status_code=status)

    peer = request.client
    origin = f"monitor page at {peer.host}:{peer.port}" if peer else "monitor page"
    if server.replay is not None or server.on_command is None:
        return answer("this monitor cannot command the run (a replay?)", 409)
    kind = request.headers.get("content-type", "").split(";")[0].strip().lower()
    if kind != "application/json":
        server.refuse(origin, "the body is not application/json")
        return answer("send JSON", 415)
    body = await bounded_body(request, MAX_COMMAND_BYTES)
    if body is None:
        server.refuse(origin, f"a body over {MAX_COMMAND_BYTES} bytes")
        return answer("body too large", 413)
    try:
        data = json.loads(body)
    except (ValueError, RecursionError):
        data = None
    data = data if isinstance(data, dict) else {}
    token = data.get("token")
    if not (isinstance(token, str) and secrets.compare_digest(token, server.token)):
        server.refuse(origin, "a command without the run's token")
        return answer("not the run's token", 403)
    command, drone = data.get("command"), data.get("drone", "")
    if not isinstance(command, str) or not isinstance(drone, str):
        return answer("command and drone must be strings", 400)
    why = await asyncio.to_thread(server.on_command, command[:40], drone[:100], origin)
    if why:
        return answer(why, 409)
    return JSONResponse({"ok": True})


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
