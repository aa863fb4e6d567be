"""The monitor's web server: one page, its files, a websocket of patches, an abort endpoint.

Starlette on uvicorn, in a thread of its own with its own event loop
(:class:`MonitorServer`), so the ground station never waits for it: the
ground station's threads only touch the :class:`~.hub.Hub` (a lock held for
microseconds) and schedule a wake-up of the loop.  Routes:

=====================  =================================================================
``GET /``              the page (``static/index.html``); ``?token=...`` enables Abort
``GET /static/NAME``   its script and style sheet (vendored, no CDN)
``GET /api/setup``     the mission: participants, colours, homes, nodes
``GET /api/graph/P``   participant ``P``'s MDG picture (the compiler's SVG)
``GET /api/state``     the whole state now (JSON), with counters
``WS  /ws``            ``{"type": "snapshot", "seq", "state"}`` then ``{"type":
                       "patches", "seq", "patches"}`` as things change; in a replay
                       the page sends ``{"type": "seek", "t"}`` and gets a snapshot
``POST /api/abort``    ``{"token"}``: abort the run (403 without the run's token)
``POST /api/command``  ``{"token", "command", "drone"}``: the operator's (:mod:`.commands`)
=====================  =================================================================

What it lets in (docs/monitor.md, "What the server refuses"): a ``Host`` naming this
machine's loopback (or the address it listens on) only, so a DNS-rebinding page gets
nothing (Starlette's ``TrustedHostMiddleware``); an ``Origin``, when a browser sends one,
only this page's own (:func:`same_origin`), so no page of another site reads the state
over the websocket or aborts; an abort body of at most :data:`MAX_BODY_BYTES`, read in
pieces and JSON (``application/json``, which a page of another site cannot send without
a preflight nobody answers); page messages of at most :data:`MAX_WS_MESSAGE_BYTES`; at
most :data:`MAX_CONNECTIONS` at once.  What it refuses is told to the terminal at most
once per :data:`REFUSALS_EVERY_S` after the first :data:`REFUSALS_FIRST`, with a count
(:class:`RefusalLimiter`).
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import secrets
import socket
import threading
import time
import urllib.parse
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import partial
from importlib import resources
from typing import TYPE_CHECKING, Any, Protocol

from .commands import MAX_COMMAND_BYTES, abort_endpoint, amend_endpoint, command_endpoint
from .hub import Hub
from .setup import MonitorError

if TYPE_CHECKING:
    from starlette.applications import Starlette
    from starlette.requests import Request
    from starlette.responses import Response
    from starlette.websockets import WebSocket

#: How often the coalesced drone updates are flushed (s).
TICK_S = 0.1
#: The page's files (package data).
STATIC_FILES = {"monitor.js": "text/javascript", "monitor.css": "text/css"}
#: The largest request body read (an abort or a command: :mod:`.commands`).
MAX_BODY_BYTES = MAX_COMMAND_BYTES
#: The largest message a page may send over the websocket (a replay's seek).
MAX_WS_MESSAGE_BYTES = 65_536
#: Connections served at once (one operator's pages); more are answered 503.
MAX_CONNECTIONS = 64
#: Refusals told to the terminal one by one, then at most one line per period.
REFUSALS_FIRST = 3
REFUSALS_EVERY_S = 10.0
#: The host names a page of this machine's monitor may use (any port: an SSH tunnel's too).
LOOPBACK_HOSTS = ("127.0.0.1", "localhost", "[::1]")


def same_origin(origin: str | None, host: str | None) -> bool:
    """Whether a request's ``Origin`` is the page's own (its host and port are the
    request's ``Host``); True without an ``Origin`` (not a browser's cross-site request:
    browsers send it with every websocket and every cross-site request)."""
    if origin is None:
        return True
    if not host or origin == "null":
        return False
    parts = urllib.parse.urlsplit(origin)
    return parts.scheme in ("http", "https") and parts.netloc.lower() == host.lower()


class RefusalLimiter:
    """Which refusals to tell: the first :data:`REFUSALS_FIRST`, then one per
    :data:`REFUSALS_EVERY_S` with how many were not told since.  Pure (time is given)."""

    def __init__(self, first: int = REFUSALS_FIRST, every_s: float = REFUSALS_EVERY_S) -> None:
        self.first = first
        self.every_s = every_s
        self.count = 0
        self.untold = 0
        self._last_told = float("-inf")

    def tell(self, now: float) -> int | None:
        """None: keep this one quiet; else how many were kept quiet before it."""
        self.count += 1
        if self.count > self.first and now - self._last_told < self.every_s:
            self.untold += 1
            return None
        self._last_told = now
        untold, self.untold = self.untold, 0
        return untold


def _static(name: str) -> str:
    return resources.files("eamos.monitor").joinpath("static", name).read_text(encoding="utf-8")


class ReplaySource(Protocol):
    """What the server needs of a replay (:class:`~.replay.Replay`)."""

    def span(self) -> dict[str, float]:
        """The time range: ``start``, ``end``, ``started`` (wall-clock seconds)."""

    def state_at(self, t: float) -> dict[str, Any]:
        """The page's whole state at time ``t``."""


@dataclass(eq=False)
class _Client:
    """One open websocket."""

    wake: asyncio.Event = field(default_factory=asyncio.Event)
    seq: int = 0
    closed: bool = False


class MonitorServer:
    """Serve the monitor page for ``hub`` (live) or ``replay`` on ``host:port`` in a thread.

    ``on_abort(origin, accepted)`` is told of every accepted abort request (which should
    stop the run) and of refused ones as :class:`RefusalLimiter` lets through (with how
    many were refused meanwhile in ``origin``); ``on_problem(text)`` of the other requests
    refused (another site's page) and of the server's own failures, limited alike.
    """

    def __init__(
        self,
        hub: Hub,
        *,
        host: str = "127.0.0.1",
        port: int = 0,
        token: str | None = None,
        on_abort: Callable[[str, bool], None] | None = None,
        replay: ReplaySource | None = None,
        on_problem: Callable[[str], None] | None = None,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.hub = hub
        self.host = host
        self.port = port
        self.token = token or secrets.token_urlsafe(16)
        self.on_abort = on_abort
        # The operator's commands: (command, drone, origin) -> why refused ("": sent).
        self.on_command: Callable[[str, str, str], str] | None = None
        # An amendment's text from the page: (text, origin) -> its judgement (eamos amend's).
        self.on_amend: Callable[[str, str], dict[str, Any]] | None = None
        self.on_problem = on_problem
        self.clock = clock
        self.refusals = RefusalLimiter()
        self.refused = 0  # requests refused, every kind
        self.problems = 0  # the server's own failures (its flush timer)
        self.replay = replay
        self.bytes_sent = 0
        self.messages_sent = 0
        self._clients: set[_Client] = set()
        self._loop: asyncio.AbstractEventLoop | None = None
        self._closing: asyncio.Event | None = None  # set when the server closes (its loop's)
        self._wake_pending = False
        self._started = threading.Event()
        self._sent = threading.Condition()  # notified when a connection caught up
        self._server: Any = None
        self._thread: threading.Thread | None = None
        self._socket: socket.socket | None = None

    # -- life cycle -------------------------------------------------------------------------

    @property
    def url(self) -> str:
        """The page's address, with the run's token (which allows Abort)."""
        return f"http://{self.host}:{self.port}/?token={self.token}"

    def start(self, timeout_s: float = 30.0) -> MonitorServer:
        """Bind, start the server thread, return once it serves (MonitorError if it cannot)."""
        import uvicorn

        try:
            sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            sock.bind((self.host, self.port))
            # Listening now: a page that connects before uvicorn serves waits in the backlog
            # (uvicorn's startup runs the lifespan, which says "started", before it serves).
            sock.listen(128)
        except OSError as exc:
            raise MonitorError(f"cannot listen on {self.host}:{self.port}: {exc}") from exc
        self._socket = sock
        self.port = sock.getsockname()[1]
        config = uvicorn.Config(
            self.app(),
            log_level="warning",
            ws="websockets-sansio",
            lifespan="on",
            ws_max_size=MAX_WS_MESSAGE_BYTES,
            limit_concurrency=MAX_CONNECTIONS,
        )
        self._server = uvicorn.Server(config)
        self._thread = threading.Thread(
            target=self._server.run, kwargs={"sockets": [sock]}, name="monitor", daemon=True
        )
        self._thread.start()
        if not self._started.wait(timeout_s):
            raise MonitorError(f"the monitor's web server did not start in {timeout_s:g} s")
        self.hub.wake = self._wake
        return self

    def stop(self, drain_s: float = 5.0) -> None:
        """Let open pages receive everything (at most ``drain_s``), then stop the server."""
        deadline = time.monotonic() + drain_s
        with self._sent:
            while any(c.seq < self.hub.seq and not c.closed for c in list(self._clients)):
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    break
                self._sent.wait(remaining)
        self.hub.wake = lambda: None
        self._close_ticker()
        if self._server is not None:
            self._server.should_exit = True
        if self._thread is not None:
            self._thread.join(timeout=10)
        if self._socket is not None:
            self._socket.close()

    def __enter__(self) -> MonitorServer:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def clients(self) -> int:
        """How many pages are connected."""
        return sum(1 for c in list(self._clients) if not c.closed)

    def stats(self) -> dict[str, Any]:
        """The hub's counters plus what went to the browsers."""
        return {
            **self.hub.stats(),
            "clients": self.clients(),
            "bytes_sent": self.bytes_sent,
            "messages_sent": self.messages_sent,
        }

    # -- waking the loop from other threads ------------------------------------------------

    def _close_ticker(self) -> None:
        """End the flush timer now (from any thread): nothing more is due."""
        loop, closing = self._loop, self._closing
        if loop is not None and closing is not None:
            with contextlib.suppress(RuntimeError):  # the loop closed already
                loop.call_soon_threadsafe(closing.set)

    def _wake(self) -> None:
        """Called by the hub at the run's end or an abort (any thread): wake every connection."""
        loop = self._loop
        if loop is None or self._wake_pending:
            return
        self._wake_pending = True
        with contextlib.suppress(RuntimeError):  # the loop closed (the server stopped)
            loop.call_soon_threadsafe(self._notify)

    def _notify(self) -> None:
        self._wake_pending = False
        for client in list(self._clients):
            client.wake.set()

    # -- the application --------------------------------------------------------------------

    def app(self) -> Starlette:
        """The Starlette application."""
        from starlette.applications import Starlette
        from starlette.routing import Route, WebSocketRoute

        @contextlib.asynccontextmanager
        async def lifespan(app: Starlette) -> Any:
            self._loop = asyncio.get_running_loop()
            self._closing = asyncio.Event()
            ticker = asyncio.create_task(self._ticker())
            self._started.set()
            try:
                yield
            finally:
                self._closing.set()
                await ticker

        from starlette.middleware import Middleware
        from starlette.middleware.trustedhost import TrustedHostMiddleware

        hosts = [*LOOPBACK_HOSTS]
        if self.host not in ("0.0.0.0", "::", ""):
            hosts.append(f"[{self.host}]" if ":" in self.host else self.host)
        return Starlette(
            middleware=[
                Middleware(TrustedHostMiddleware, allowed_hosts=hosts, www_redirect=False),
                Middleware(_OriginGuard, server=self),
            ],
            routes=[
                Route("/", self._page),
                Route("/static/{name}", self._file),
                Route("/api/setup", self._setup),
                Route("/api/graph/{name}", self._graph),
                Route("/api/state", self._state),
                Route("/api/abort", partial(abort_endpoint, self), methods=["POST"]),
                Route("/api/command", partial(command_endpoint, self), methods=["POST"]),
                Route("/api/amend", partial(amend_endpoint, self), methods=["POST"]),
                WebSocketRoute("/ws", self._ws),
            ],
            lifespan=lifespan,
        )

    async def _ticker(self) -> None:
        """Every :data:`TICK_S` until the server closes: flush the held drone updates and
        send every page what is new (at most 10 messages a second to a page).

        It waits on the closing event with a timeout (not a sleep), so :meth:`stop`
        ends it at once instead of after the current period.
        """
        closing = self._closing
        assert closing is not None
        sent = -1
        while not closing.is_set():
            with contextlib.suppress(TimeoutError):
                await asyncio.wait_for(closing.wait(), TICK_S)
            if self.replay is None and not closing.is_set():
                try:
                    self.hub.tick()
                    # Events never wake the pages (a thread switch per event would cost
                    # the ground station); what arrived since the last tick goes out now.
                    if self.hub.seq != sent:
                        sent = self.hub.seq
                        self._notify()
                # One failing tick must not stop the timer: the pages would freeze.
                except Exception as exc:
                    self.problems += 1
                    self.problem(f"the monitor's flush timer failed: {exc!r:.200}")

    async def _page(self, request: Request) -> Response:
        from starlette.responses import HTMLResponse

        return HTMLResponse(_static("index.html"), headers={"Cache-Control": "no-store"})

    async def _file(self, request: Request) -> Response:
        from starlette.responses import PlainTextResponse, Response

        name = request.path_params["name"]
        if name not in STATIC_FILES:
            return PlainTextResponse("not found", status_code=404)
        return Response(_static(name), media_type=STATIC_FILES[name])

    async def _setup(self, request: Request) -> Response:
        from starlette.responses import JSONResponse

        data = self.hub.state.setup.to_json()
        data["replay"] = None if self.replay is None else self.replay.span()
        return JSONResponse(data)

    async def _graph(self, request: Request) -> Response:
        from starlette.responses import PlainTextResponse, Response

        name = request.path_params["name"].removesuffix(".svg")
        part = self.hub.state.setup.participant(name)
        if part is None or not part.svg:
            return PlainTextResponse(f"no graph for {name}", status_code=404)
        return Response(part.svg, media_type="image/svg+xml")

    async def _state(self, request: Request) -> Response:
        from starlette.responses import JSONResponse

        seq, snap = self.hub.resync()
        return JSONResponse({"seq": seq, "state": snap, "stats": self.stats()})

    # -- refusals and problems, told at a bounded rate -----------------------------------

    def refuse(self, origin: str, why: str, abort: bool = False) -> None:
        """A request refused: counted; told (and an abort recorded) as the limiter lets."""
        self.refused += 1
        untold = self.refusals.tell(self.clock())
        if untold is None:
            return
        more = f"; {untold} more refused since" if untold else ""
        if abort:
            self.hub.abort_request(origin + more, False)
            if self.on_abort is not None:
                self.on_abort(origin + more, False)
        elif self.on_problem is not None:
            self.on_problem(f"refused a request from the {origin}: {why}{more}")

    def problem(self, text: str) -> None:
        """The server's own failure: told as the limiter lets (never raised to the loop)."""
        if self.refusals.tell(self.clock()) is not None and self.on_problem is not None:
            with contextlib.suppress(Exception):
                self.on_problem(text)

    # -- the websocket ----------------------------------------------------------------------

    async def _send(self, ws: WebSocket, client: _Client, message: dict[str, Any]) -> None:
        text = json.dumps(message, separators=(",", ":"))
        await ws.send_text(text)
        self.bytes_sent += len(text)
        self.messages_sent += 1
        client.seq = int(message.get("seq", client.seq))
        with self._sent:
            self._sent.notify_all()

    async def _ws(self, ws: WebSocket) -> None:
        await ws.accept()
        client = _Client()
        self._clients.add(client)
        reader = asyncio.create_task(self._read(ws, client))
        try:
            if self.replay is not None:
                await reader
                return
            seq, snap = self.hub.resync()
            await self._send(ws, client, {"type": "snapshot", "seq": seq, "state": snap})
            while not client.closed:
                await client.wake.wait()
                client.wake.clear()
                got = self.hub.since(client.seq)
                if got is None:  # fell too far behind: the whole state instead
                    seq, snap = self.hub.resync()
                    await self._send(ws, client, {"type": "snapshot", "seq": seq, "state": snap})
                elif got[1]:
                    msg = {"type": "patches", "seq": got[0], "patches": got[1]}
                    await self._send(ws, client, msg)
        except Exception:  # the page went away mid-send
            client.closed = True
        finally:
            client.closed = True
            reader.cancel()
            self._clients.discard(client)
            with self._sent:
                self._sent.notify_all()

    async def _read(self, ws: WebSocket, client: _Client) -> None:
        """Messages from the page: a replay's seeks; the end of the connection."""
        try:
            while True:
                msg = json.loads(await ws.receive_text())
                if self.replay is not None and msg.get("type") == "seek":
                    snap = self.replay.state_at(float(msg.get("t", 0.0)))
                    await self._send(ws, client, {"type": "snapshot", "seq": 0, "state": snap})
        except Exception:  # closed, or not JSON: the connection is over
            pass
        finally:
            client.closed = True
            client.wake.set()


class _OriginGuard:
    """ASGI middleware: a request (or websocket) whose ``Origin`` is not the page's own is
    refused (HTTP 403; a websocket is closed before it is accepted) and told."""

    def __init__(self, app: Any, server: MonitorServer) -> None:
        self.app = app
        self.server = server

    async def __call__(self, scope: dict[str, Any], receive: Any, send: Any) -> None:
        if scope["type"] not in ("http", "websocket"):
            await self.app(scope, receive, send)
            return
        headers = {k.decode("latin-1"): v.decode("latin-1") for k, v in scope["headers"]}
        origin = headers.get("origin")
        if same_origin(origin, headers.get("host")):
            await self.app(scope, receive, send)
            return
        client = scope.get("client")
        where = f"page of {origin!r:.80}" + (f" at {client[0]}:{client[1]}" if client else "")
        self.server.refuse(where, f"another site's page ({scope['path']!r:.60})")
        if scope["type"] == "websocket":
            await send({"type": "websocket.close", "code": 1008})
            return
        from starlette.responses import JSONResponse

        refusal = JSONResponse({"ok": False, "error": "another site's page"}, status_code=403)
        await refusal(scope, receive, send)
