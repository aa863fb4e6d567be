"""eamos.net.zap: pyzmq's authenticator on a context, through real CURVE handshakes.

Real sockets on loopback: a client whose key the provider admits gets its messages
through; a client with another key, a client without keys, and a client whose
check raised are refused, and the authenticator goes on serving.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import pytest
import zmq

from eamos.net.zap import start_authenticator

pytestmark = pytest.mark.timeout(60)

WAIT_MS = 10_000


class Allowed:
    """A credentials provider admitting ``keys`` (z85); it records what it was asked."""

    def __init__(self, *keys: bytes, broken: bytes = b"") -> None:
        self.keys = set(keys)
        self.broken = broken  # a key whose check raises
        self.asked: list[tuple[str, bytes]] = []

    def callback(self, domain: str, key: bytes) -> bool:
        self.asked.append((domain, key))
        if key == self.broken:
            raise RuntimeError("a bug in the check")
        return key in self.keys


@pytest.fixture
def ctx() -> Iterator[zmq.Context[Any]]:
    context: zmq.Context[Any] = zmq.Context()
    yield context
    context.destroy(linger=0)


def server(ctx: zmq.Context[Any], public: bytes, secret: bytes) -> tuple[Any, int]:
    """A CURVE server in domain ``eamos`` that refuses everyone without a ZAP handler."""
    sock = ctx.socket(zmq.PULL)
    sock.curve_server = True
    sock.curve_secretkey = secret
    sock.curve_publickey = public
    sock.zap_domain = b"eamos"
    sock.setsockopt(zmq.ZAP_ENFORCE_DOMAIN, 1)
    sock.linger = 0
    return sock, sock.bind_to_random_port("tcp://127.0.0.1")


def client(ctx: zmq.Context[Any], port: int, server_key: bytes | None) -> tuple[Any, bytes]:
    """A PUSH client with a fresh key pair (``server_key`` None: no CURVE at all)."""
    public, secret = zmq.curve_keypair()
    sock = ctx.socket(zmq.PUSH)
    if server_key is not None:
        sock.curve_serverkey = server_key
        sock.curve_publickey = public
        sock.curve_secretkey = secret
    sock.linger = 0
    sock.connect(f"tcp://127.0.0.1:{port}")
    return sock, public


def test_only_an_admitted_key_gets_through(ctx: zmq.Context[Any]) -> None:
    server_public, server_secret = zmq.curve_keypair()
    provider = Allowed()
    auth = start_authenticator(ctx, "eamos", provider)
    try:
        pull, port = server(ctx, server_public, server_secret)
        good, good_key = client(ctx, port, server_public)
        wrong, wrong_key = client(ctx, port, server_public)
        keyless, _ = client(ctx, port, None)
        provider.keys.add(good_key)
        wrong.send(b"from outside")
        keyless.send(b"no keys at all")
        good.send(b"from the fleet")
        assert pull.poll(WAIT_MS) and pull.recv() == b"from the fleet"
        assert not pull.poll(1_000)  # neither of the others ever arrives
        asked = {key for _, key in provider.asked}
        assert {good_key, wrong_key} <= asked  # each CURVE client was asked about
        assert {domain for domain, _ in provider.asked} == {"eamos"}
        for sock in (pull, good, wrong, keyless):
            sock.close()
    finally:
        auth.stop()


def test_a_check_that_raises_refuses_and_the_authenticator_goes_on(
    ctx: zmq.Context[Any],
) -> None:
    server_public, server_secret = zmq.curve_keypair()
    provider = Allowed()
    auth = start_authenticator(ctx, "eamos", provider)
    try:
        pull, port = server(ctx, server_public, server_secret)
        first, first_key = client(ctx, port, server_public)
        provider.broken = first_key
        first.send(b"checked by a broken check")
        assert not pull.poll(1_000)
        assert any(key == first_key for _, key in provider.asked)
        second, second_key = client(ctx, port, server_public)
        provider.keys.add(second_key)
        second.send(b"after the bug")
        assert pull.poll(WAIT_MS) and pull.recv() == b"after the bug"
        for sock in (pull, first, second):
            sock.close()
    finally:
        auth.stop()


def test_one_authenticator_per_context_and_nothing_left_open(ctx: zmq.Context[Any]) -> None:
    auth = start_authenticator(ctx, "eamos", Allowed())
    try:
        with pytest.raises(zmq.ZMQError):
            start_authenticator(ctx, "eamos", Allowed())
    finally:
        auth.stop()
        auth.stop()  # idempotent
    # Every socket both made is closed: the context terminates (the fixture's destroy
    # would close leftovers; term does not, it would hang).
    ctx.term()
