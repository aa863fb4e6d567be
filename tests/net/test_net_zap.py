"""eamos.net.zap: the ZAP handler's answers (pure), and real CURVE handshakes through it."""

from __future__ import annotations

from typing import Any

import pytest
import zmq
from zmq.utils import z85

from eamos.net.zap import ZapHandler, zap_reply

pytestmark = pytest.mark.timeout(60)

KEY = bytes(range(32))
Z85 = z85.encode(KEY)


def request(mechanism: bytes, *credentials: bytes, domain: bytes = b"eamos") -> list[bytes]:
    return [b"1.0", b"id7", domain, b"127.0.0.1", b"", mechanism, *credentials]


def only(key: bytes) -> Any:
    return lambda domain, k: k == key


def test_a_fleet_key_is_admitted_with_its_key_as_user_id() -> None:
    assert zap_reply(request(b"CURVE", KEY), "eamos", only(Z85)) == [
        b"1.0", b"id7", b"200", b"OK", Z85, b""
    ]  # fmt: skip


@pytest.mark.parametrize(
    ("req", "text"),
    [
        (request(b"CURVE", bytes(32)), b"Unknown key"),
        (request(b"CURVE", KEY, domain=b"other"), b"Unknown domain"),
        (request(b"CURVE", KEY, KEY), b"Invalid credentials"),
        (request(b"CURVE", b"short"), b"Invalid credentials"),
        (request(b"PLAIN", b"user", b"pw"), b"NO ACCESS"),
        ([b"2.0", *request(b"CURVE", KEY)[1:]], b"Invalid version"),
        ([b"1.0", b"id7", b"eamos"], b"Not enough frames"),
    ],
)
def test_everything_else_is_refused(req: list[bytes], text: bytes) -> None:
    reply = zap_reply(req, "eamos", only(Z85))
    assert reply is not None and reply[1] == b"id7" and reply[2:4] == [b"400", text]
    assert reply[4] == b""


def test_null_is_let_through_and_a_request_without_id_is_not_answered() -> None:
    assert zap_reply(request(b"NULL"), "eamos", only(Z85))[2] == b"200"  # type: ignore[index]
    assert zap_reply([b"1.0"], "eamos", only(Z85)) is None


def _pair(ctx: zmq.Context[Any], server_secret: bytes, server_public: bytes) -> Any:
    server = ctx.socket(zmq.PULL)
    server.curve_server = True
    server.curve_secretkey = server_secret
    server.curve_publickey = server_public
    server.zap_domain = b"eamos"
    server.setsockopt(zmq.ZAP_ENFORCE_DOMAIN, 1)
    server.linger = 0
    port = server.bind_to_random_port("tcp://127.0.0.1")
    return server, port


def _client(ctx: zmq.Context[Any], port: int, server_public: bytes) -> Any:
    public, secret = zmq.curve_keypair()
    client = ctx.socket(zmq.PUSH)
    client.curve_serverkey = server_public
    client.curve_publickey = public
    client.curve_secretkey = secret
    client.linger = 0
    client.connect(f"tcp://127.0.0.1:{port}")
    return client, public


def test_handshakes_through_the_handler_admit_only_the_allowed_key() -> None:
    ctx: zmq.Context[Any] = zmq.Context()
    allowed: set[bytes] = set()
    asked: list[bytes] = []

    def allow(domain: str, key: bytes) -> bool:
        asked.append(key)
        return key in allowed

    handler = ZapHandler(ctx, "eamos", allow)
    try:
        with pytest.raises(zmq.ZMQError):
            ZapHandler(ctx, "eamos", allow)  # one handler per context
        server_public, server_secret = zmq.curve_keypair()
        server, port = _pair(ctx, server_secret, server_public)
        good, good_key = _client(ctx, port, server_public)
        bad, _ = _client(ctx, port, server_public)
        allowed.add(good_key)
        good.send(b"from the fleet")
        bad.send(b"from outside")
        assert server.poll(10_000) and server.recv() == b"from the fleet"
        assert not server.poll(1_000)  # the intruder's message never arrives
        assert good_key in asked and len(set(asked)) == 2
        for sock in (server, good, bad):
            sock.close()
    finally:
        handler.stop()
        handler.stop()  # idempotent
        ctx.term()
