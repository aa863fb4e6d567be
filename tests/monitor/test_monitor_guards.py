"""What the monitor's web server refuses (issue 28), against the real server.

Real HTTP over sockets and a real websocket client: request bodies are bounded (a
64 MiB abort body is refused after 4 KiB, 200 000 ``[`` print no traceback), the
``Host`` must be this machine's (DNS rebinding), the ``Origin`` the page's own (another
site's page neither reads the state over the websocket nor aborts, even with the
token), and refusals reach the terminal at a bounded rate.
"""

from __future__ import annotations

import http.client
import json
import logging
import socket
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest
from websockets.exceptions import InvalidHandshake, InvalidStatus
from websockets.sync.client import connect

from eamos.compiler import compile_file
from eamos.monitor.hub import Hub
from eamos.monitor.server import MAX_BODY_BYTES, MonitorServer, RefusalLimiter, same_origin
from eamos.monitor.setup import build_setup

REPO = Path(__file__).resolve().parents[2]
WAIT_S = 30.0

pytestmark = pytest.mark.timeout(300)


@dataclass
class Told:
    """What the server told the terminal (its callbacks), on a clock the test moves."""

    aborts: list[tuple[str, bool]] = field(default_factory=list)
    problems: list[str] = field(default_factory=list)
    now: float = 1000.0

    def clock(self) -> float:
        return self.now


@pytest.fixture
def served() -> Iterator[tuple[MonitorServer, Told]]:
    setup = build_setup(dict(compile_file(REPO / "missions" / "experiment_a.go").programs), {})
    told = Told()
    server = MonitorServer(
        Hub(setup),
        token="the-token",
        on_abort=lambda origin, ok: told.aborts.append((origin, ok)),
        on_problem=told.problems.append,
        clock=told.clock,
    ).start()
    try:
        yield server, told
    finally:
        server.stop(drain_s=0)


def request(
    server: MonitorServer,
    method: str,
    path: str,
    body: bytes | None = None,
    headers: dict[str, str] | None = None,
) -> tuple[int, bytes]:
    conn = http.client.HTTPConnection("127.0.0.1", server.port, timeout=WAIT_S)
    try:
        conn.request(method, path, body=body, headers=headers or {})
        res = conn.getresponse()
        return res.status, res.read()
    finally:
        conn.close()


JSON = {"Content-Type": "application/json"}


def ws_client(port: int, origin: str | None = None) -> Any:
    """A websocket to the server, sending ``origin`` as a browser's page would."""
    return connect(f"ws://127.0.0.1:{port}/ws", origin=origin, open_timeout=WAIT_S)  # type: ignore[arg-type]


def abort_body(token: str = "the-token") -> bytes:
    return json.dumps({"token": token}).encode()


# -- bodies ------------------------------------------------------------------------------------


def test_a_huge_abort_body_is_refused_after_a_few_kib_never_read_whole(
    served: tuple[MonitorServer, Told],
) -> None:
    server, told = served
    # Declared: refused from the header, before any of it is read.
    status, _ = request(
        server, "POST", "/api/abort", b"x" * 10, {**JSON, "Content-Length": str(512 << 20)}
    )
    assert status == 413
    # Not declared (chunked): the server stops at 4 KiB and answers while the client still sends.
    with socket.create_connection(("127.0.0.1", server.port), timeout=WAIT_S) as sock:
        sock.sendall(
            b"POST /api/abort HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: application/json\r\n"
            b"Transfer-Encoding: chunked\r\n\r\n"
        )
        chunk = b"%x\r\n%s\r\n" % (65536, b"[" * 65536)
        sent = 0
        try:
            for _ in range(1024):  # 64 MiB if the server read it all
                sock.sendall(chunk)
                sent += 65536
                sock.settimeout(0.0 if sent < (1 << 20) else WAIT_S)
                try:
                    head = sock.recv(4096)
                except BlockingIOError:
                    continue
                break
            else:
                head = b""
        except (BrokenPipeError, ConnectionResetError):
            sock.settimeout(WAIT_S)
            head = sock.recv(4096)
        assert head.startswith(b"HTTP/1.1 413"), head[:100]
        assert sent < (8 << 20), sent  # answered long before 64 MiB were sent
    assert not any(ok for _, ok in told.aborts)
    assert request(server, "GET", "/api/state")[0] == 200  # and it serves on


def test_a_body_of_200000_brackets_prints_no_traceback(
    served: tuple[MonitorServer, Told], caplog: pytest.LogCaptureFixture
) -> None:
    server, _ = served
    with caplog.at_level(logging.WARNING):
        assert request(server, "POST", "/api/abort", b"[" * 200_000, JSON)[0] == 413
        deep = b"[" * (MAX_BODY_BYTES - 1)  # within the limit, too deep for json
        assert request(server, "POST", "/api/abort", deep, JSON)[0] == 403
    errors = [r for r in caplog.records if r.levelno >= logging.ERROR]
    assert not errors, [r.getMessage() for r in errors]


# -- Host and Origin ---------------------------------------------------------------------------


def test_dns_rebinding_gets_nothing(served: tuple[MonitorServer, Told]) -> None:
    server, _ = served
    port = server.port
    assert request(server, "GET", "/api/state")[0] == 200
    for host in (f"localhost:{port}", f"[::1]:{port}", "localhost:8000"):  # 8000: an SSH tunnel
        assert request(server, "GET", "/api/state", headers={"Host": host})[0] == 200, host
    for host in (f"evil.example:{port}", "evil.example", f"127.0.0.1.evil.example:{port}"):
        status, body = request(server, "GET", "/api/state", headers={"Host": host})
        assert status == 400 and b"seq" not in body, host


def test_another_sites_page_neither_reads_the_state_nor_aborts(
    served: tuple[MonitorServer, Told],
) -> None:
    server, told = served
    port = server.port
    own = f"http://127.0.0.1:{port}"
    with ws_client(port, own) as ws:
        assert json.loads(ws.recv(timeout=WAIT_S))["type"] == "snapshot"
    for origin in ("http://evil.example", "null", f"http://127.0.0.1:{port + 1}"):
        refused = (InvalidStatus, InvalidHandshake, ConnectionError, EOFError)
        with pytest.raises(refused), ws_client(port, origin) as ws:
            ws.recv(timeout=WAIT_S)
    # A cross-site form or fetch with the token (text/plain: no preflight) aborts nothing.
    for headers in (
        {"Origin": "http://evil.example", "Content-Type": "text/plain"},
        {"Origin": "http://evil.example", **JSON},
        {"Content-Type": "text/plain"},  # no Origin: still not JSON
    ):
        status, _ = request(server, "POST", "/api/abort", abort_body(), headers)
        assert status in (403, 415), headers
    assert not any(ok for _, ok in told.aborts)
    # The page itself (same origin, JSON, the token) aborts.
    status, _ = request(server, "POST", "/api/abort", abort_body(), {"Origin": own, **JSON})
    assert status == 200 and told.aborts[-1][1] is True


def test_same_origin_is_host_and_port() -> None:
    assert same_origin(None, "127.0.0.1:5") and same_origin("http://127.0.0.1:5", "127.0.0.1:5")
    assert same_origin("http://LOCALHOST:8000", "localhost:8000")
    assert not same_origin("http://127.0.0.1:6", "127.0.0.1:5")
    assert not same_origin("null", "127.0.0.1:5") and not same_origin("http://a", None)
    assert not same_origin("file://", "127.0.0.1:5")


# -- refusals told at a bounded rate -----------------------------------------------------------


def test_288_refused_aborts_make_a_few_terminal_lines_with_counts(
    served: tuple[MonitorServer, Told],
) -> None:
    server, told = served
    for _ in range(288):
        assert request(server, "POST", "/api/abort", abort_body("wrong"), JSON)[0] == 403
    assert server.refused == 288
    assert [ok for _, ok in told.aborts] == [False] * 3  # the first three, then quiet
    told.now += 10.0
    assert request(server, "POST", "/api/abort", abort_body("wrong"), JSON)[0] == 403
    assert len(told.aborts) == 4 and told.aborts[-1][0].endswith("; 285 more refused since")
    assert len(server.hub.aborts) == 4  # the record is bounded the same way


def test_the_limiter_tells_the_first_then_one_per_period() -> None:
    limiter = RefusalLimiter(first=2, every_s=10.0)
    told = [limiter.tell(t) for t in (0.0, 0.0, 0.0, 1.0, 10.0, 11.0, 25.0)]
    assert told == [0, 0, None, None, 2, None, 1]


# -- the flush timer survives a failing tick ---------------------------------------------------


def test_a_failing_tick_does_not_freeze_the_pages(
    served: tuple[MonitorServer, Told], monkeypatch: pytest.MonkeyPatch
) -> None:
    server, told = served
    hub = server.hub
    real_tick = hub.tick
    failed = threading.Event()

    def tick() -> None:
        if not failed.is_set():
            failed.set()
            raise RuntimeError("a tick's bug")
        real_tick()

    monkeypatch.setattr(hub, "tick", tick)
    with ws_client(server.port) as ws:
        assert json.loads(ws.recv(timeout=WAIT_S))["type"] == "snapshot"
        assert failed.wait(WAIT_S)
        from eamos.net import wire

        hub.event("GCS", wire.Resolved(mission=hub.state.setup.mission_id, sender="GCS"))
        deadline = time.monotonic() + WAIT_S
        got: dict[str, Any] = {}
        while time.monotonic() < deadline and got.get("type") != "patches":
            got = json.loads(ws.recv(timeout=WAIT_S))
        assert got["type"] == "patches"  # sent by the tick after the failing one
    assert server.problems == 1 and "a tick's bug" in told.problems[0]


# -- an amendment's upload (issue 31) ----------------------------------------------------------


def test_an_amendment_needs_the_token_json_a_bounded_body_and_a_text(
    served: tuple[MonitorServer, Told],
) -> None:
    server, _ = served
    judged: list[tuple[str, str]] = []
    # Without a judge (a replay, a roll-out's monitor): refused as such.
    body = json.dumps({"token": "the-token", "text": "package m"}).encode()
    assert request(server, "POST", "/api/amend", body, JSON)[0] == 409

    def judge(text: str, origin: str) -> dict[str, Any]:
        judged.append((text, origin))
        return {"ok": True}

    server.on_amend = judge
    assert request(server, "POST", "/api/amend", body, {"Content-Type": "text/plain"})[0] == 415
    wrong = json.dumps({"token": "not-it", "text": "package m"}).encode()
    assert request(server, "POST", "/api/amend", wrong, JSON)[0] == 403
    untexted = json.dumps({"token": "the-token", "text": 3}).encode()
    assert request(server, "POST", "/api/amend", untexted, JSON)[0] == 400
    huge = json.dumps({"token": "the-token", "text": "x" * 600_000}).encode()
    assert request(server, "POST", "/api/amend", huge, JSON)[0] == 413
    assert judged == []  # none of those reached the judge
    status, answer = request(server, "POST", "/api/amend", body, JSON)
    assert status == 200 and json.loads(answer) == {"ok": True}
    assert judged and judged[0][0] == "package m" and judged[0][1].startswith("monitor page at")
    # A judge that says the text is bad (it does not compile): 422 with its error.
    server.on_amend = lambda text, origin: {"ok": False, "error": "uploaded.go:1:1: error: ..."}
    status, answer = request(server, "POST", "/api/amend", body, JSON)
    assert status == 422 and json.loads(answer)["error"].startswith("uploaded.go:1:1")
