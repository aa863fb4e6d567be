"""The language server answers every request and survives framing errors (issue 28).

Raw bytes are written to a real ``eamos lsp`` process, as a buggy editor would send them:
lying ``Content-Length`` headers (too long, too short, not a number, absurdly large), junk
between frames, bodies that are not JSON or nest 200 000 deep, requests whose params
have the wrong types.  After each, a good request gets its answer; each bad request got
an error.  Before, the server went silent after the first bad frame.
"""

from __future__ import annotations

import json
import subprocess
import sys
import threading
from collections.abc import Iterator
from typing import Any

import pytest

from eamos.lsp.framing import MAX_BODY_BYTES, BadFrame, Frame, FrameReader

pytestmark = pytest.mark.timeout(300)

WAIT_S = 60.0  # a loaded 2-core machine starts Python slowly
URI = "file:///tmp/framing.go"
TEXT = "func SEQ_Main() {\n\tDrone1.Arm()\n\tDrone1.Takeoff(2)\n}\n"


def frame(message: dict[str, Any] | bytes, length: int | str | None = None) -> bytes:
    body = message if isinstance(message, bytes) else json.dumps(message).encode()
    return (
        b"Content-Length: %s\r\n\r\n" % str(len(body) if length is None else length).encode() + body
    )


def request(msg_id: int, method: str, params: Any) -> dict[str, Any]:
    return {"jsonrpc": "2.0", "id": msg_id, "method": method, "params": params}


def symbols(msg_id: int) -> dict[str, Any]:
    return request(msg_id, "textDocument/documentSymbol", {"textDocument": {"uri": URI}})


# -- the reader alone (pure) ----------------------------------------------------------------

GOOD = json.dumps(symbols(1)).encode()


@pytest.mark.parametrize(
    ("stream", "expected"),
    [
        (frame(GOOD) * 2, ["frame", "frame"]),
        (frame(GOOD, 9999) + frame(GOOD), ["bad", "frame"]),  # too long: ends at the next header
        (frame(GOOD, 5) + frame(GOOD), ["frame", "bad", "frame"]),  # too short: cut, then skipped
        (
            frame(GOOD, "abc") + frame(GOOD),
            ["bad", "bad", "frame"],
        ),  # no length: its body given back
        (frame(GOOD, 10**11) + frame(GOOD), ["bad", "frame"]),
        (b"junk\r\n" + frame(GOOD), ["bad", "frame"]),
        (b"\r\n" + frame(GOOD) + b"\r\n" + frame(GOOD), ["frame", "frame"]),  # blank lines: fine
        (b"Content-Length: 0\r\n\r\n" + frame(GOOD), ["frame", "frame"]),
    ],
    ids=["good", "too-long", "too-short", "not-a-number", "huge", "junk", "blank-lines", "empty"],
)
def test_the_reader_finds_the_next_frame_after_any_bad_one(
    stream: bytes, expected: list[str]
) -> None:
    for size in (len(stream), 1, 7):  # at once, byte by byte, in odd chunks
        reader = FrameReader()
        events: list[Frame | BadFrame] = []
        for at in range(0, len(stream), size):
            events += reader.feed(stream[at : at + size])
        assert ["frame" if isinstance(e, Frame) else "bad" for e in events] == expected, (
            size,
            events,
        )
        assert isinstance(events[-1], Frame) and events[-1].body == GOOD


def test_a_too_long_frame_gives_back_its_body_for_the_request_id() -> None:
    (bad, good) = FrameReader().feed(frame(GOOD, 9999) + frame(GOOD))
    assert isinstance(bad, BadFrame) and json.loads(bad.body)["id"] == 1
    assert "Content-Length of 9999 bytes for a body of" in bad.reason
    assert isinstance(good, Frame)
    assert MAX_BODY_BYTES >= 6 * 2_000_000  # a mission at its size limit, every byte escaped


# -- a real server ----------------------------------------------------------------------------


class Server:
    """``eamos lsp`` in a process; its answers read on a thread, waited for by id."""

    def __init__(self) -> None:
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "eamos.cli", "lsp"],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
        )
        self.cond = threading.Condition()
        self.answers: dict[Any, dict[str, Any]] = {}
        self.null_errors: list[dict[str, Any]] = []
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self) -> None:
        assert self.proc.stdout is not None
        reader = FrameReader()
        while chunk := self.proc.stdout.read1(65536):  # type: ignore[attr-defined]
            for event in reader.feed(chunk):
                assert isinstance(event, Frame), event  # the server's own frames are sound
                message = json.loads(event.body)
                with self.cond:
                    if "id" in message and "method" not in message:
                        if message["id"] is None:
                            self.null_errors.append(message)
                        else:
                            self.answers[message["id"]] = message
                    self.cond.notify_all()

    def send(self, data: bytes) -> None:
        assert self.proc.stdin is not None
        self.proc.stdin.write(data)
        self.proc.stdin.flush()

    def answer(self, msg_id: Any) -> dict[str, Any]:
        with self.cond:
            assert self.cond.wait_for(lambda: msg_id in self.answers, WAIT_S), (
                f"no answer to request {msg_id}; stderr so far unread"
            )
            return self.answers[msg_id]

    def nulls(self, count: int) -> list[dict[str, Any]]:
        with self.cond:
            assert self.cond.wait_for(lambda: len(self.null_errors) >= count, WAIT_S)
            return list(self.null_errors)


@pytest.fixture
def server() -> Iterator[Server]:
    srv = Server()
    srv.send(
        frame(request(0, "initialize", {"processId": None, "rootUri": None, "capabilities": {}}))
    )
    assert "result" in srv.answer(0)
    srv.send(frame({"jsonrpc": "2.0", "method": "initialized", "params": {}}))
    srv.send(
        frame(
            {
                "jsonrpc": "2.0",
                "method": "textDocument/didOpen",
                "params": {
                    "textDocument": {"uri": URI, "languageId": "eamos", "version": 1, "text": TEXT}
                },
            }
        )
    )
    yield srv
    if srv.proc.poll() is None:
        srv.proc.kill()
    srv.proc.wait(30)


def good_request_answered(server: Server, msg_id: int) -> None:
    server.send(frame(symbols(msg_id)))
    answer = server.answer(msg_id)
    assert [s["name"] for s in answer["result"]] == ["SEQ_Main"], answer


BAD_FRAMES: list[tuple[str, bytes, Any, int | None]] = [
    # (what, bytes, the id an error must answer, its code)
    ("too long", frame(symbols(10), 9999), 10, -32600),
    ("not a number", frame(symbols(11), "abc"), 11, -32600),
    ("too short", frame(symbols(12), 5), None, -32700),
    ("huge length", frame(symbols(13), 10**11), None, None),
    ("junk", b"\x00\xff junk \r\n\r\n", None, None),
    ("not JSON", frame(b"{not json"), None, -32700),
    ("nested 200000 deep", frame(b"[" * 200_000), None, -32700),
    ("not an object", frame(b"[1, 2]"), None, -32600),
    (
        "wrong-typed params",
        frame(request(14, "textDocument/hover", {"textDocument": {"uri": URI}, "position": "x"})),
        14,
        -32602,
    ),
    ("no params", frame(request(15, "textDocument/completion", None)), 15, -32602),
    ("params a list", frame(request(16, "textDocument/definition", [1, 2])), 16, -32602),
    ("no jsonrpc", frame({"id": 17, "method": "textDocument/hover", "params": {}}), 17, None),
]


def test_every_request_is_answered_and_a_bad_frame_never_silences_the_server(
    server: Server,
) -> None:
    good_request_answered(server, 100)
    nulls = 0
    for i, (what, data, msg_id, code) in enumerate(BAD_FRAMES):
        server.send(data)
        good_request_answered(server, 101 + i)  # the next request is answered: not silent
        if msg_id is not None:
            error = server.answer(msg_id).get("error")
            assert error is not None, what
            assert code is None or error["code"] == code, (what, error)
        elif code is not None:
            nulls += 1
            assert server.nulls(nulls)[-1]["error"]["code"] == code, what
    server.send(frame(request(200, "shutdown", None)))
    assert "result" in server.answer(200)
    server.send(frame({"jsonrpc": "2.0", "method": "exit"}))
    assert server.proc.wait(WAIT_S) == 0
    assert server.proc.stderr is not None
    err = server.proc.stderr.read().decode()
    assert "Traceback" not in err, err  # one line per problem, no traceback
    assert "Content-Length of 9999 bytes" in err and "not JSON" in err
