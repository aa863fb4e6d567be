"""A connection that goes silent without closing (a peer's machine gone) is dropped at both ends.

The In-Bridge's SUB pings every :data:`CONNECTING_PING_FACTOR` intervals (ZeroMQ
heartbeats, ``connection_options``; any frame it receives resets its timeout), the
Out-Bridge's XPUB every :data:`BOUND_HEARTBEAT_FACTOR`.  Between them a
real TCP relay forwards bytes until it is told to go silent: from then on it forwards
nothing on the connections it has, and closes none of them (no FIN, no RST: what a
pulled network cable looks like).  Each bridge must close its end of the frozen
connection (the relay reads its FIN), and the In-Bridge must subscribe again
through a fresh connection.
"""

from __future__ import annotations

import selectors
import socket
import threading
import time
from typing import Any

import pytest
import zmq

from eamos.net import InBridge, OutBridge, topic_to
from eamos.net.sockets import BOUND_HEARTBEAT_FACTOR

from .net_helpers import MISSION, Collector

pytestmark = pytest.mark.timeout(120)

#: A short ZeroMQ heartbeat for the test (the default is 1 s).
HEARTBEAT_MS = 200
#: The bound side times out after five of its own (longer) intervals; generous slack.
DROP_WITHIN_S = 6 * BOUND_HEARTBEAT_FACTOR * HEARTBEAT_MS / 1000 + 20.0


class SilentRelay:
    """Forwards TCP from its own port to ``target`` until :meth:`silence`, which freezes
    the connections it has (kept open, never read or written); later ones forward."""

    def __init__(self, target: tuple[str, int]) -> None:
        self.target = target
        self.listener = socket.create_server(("127.0.0.1", 0))
        self.port = self.listener.getsockname()[1]
        self.selector = selectors.DefaultSelector()
        self.selector.register(self.listener, selectors.EVENT_READ, None)
        self.pairs: list[tuple[socket.socket, socket.socket]] = []
        self.frozen: list[tuple[socket.socket, socket.socket]] = []  # (to SUB, to XPUB)
        self._silence = threading.Event()
        self.is_silent = threading.Event()
        self._stop = threading.Event()
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def silence(self) -> None:
        self._silence.set()

    def _run(self) -> None:
        while not self._stop.is_set():
            if self._silence.is_set():
                self._freeze()
            for key, _ in self.selector.select(0.05):
                if key.data is None:
                    client, _ = self.listener.accept()
                    server = socket.create_connection(self.target)
                    self.selector.register(client, selectors.EVENT_READ, server)
                    self.selector.register(server, selectors.EVENT_READ, client)
                    self.pairs.append((client, server))
                    continue
                src: socket.socket = key.fileobj  # type: ignore[assignment]
                try:
                    data = src.recv(65536)
                except OSError:
                    data = b""
                if data:
                    key.data.sendall(data)

    def _freeze(self) -> None:
        for key in list(self.selector.get_map().values()):
            if key.data is not None:
                self.selector.unregister(key.fileobj)
        self.frozen, self.pairs = self.pairs, []
        self._silence.clear()
        self.is_silent.set()

    def close(self) -> None:
        self._stop.set()
        self.thread.join(10)
        for sock in [*(s for pair in self.frozen for s in pair), self.listener]:
            sock.close()
        for key in list(self.selector.get_map().values()):
            key.fileobj.close()  # type: ignore[union-attr]
        self.selector.close()


def closed_by_its_peer(sock: socket.socket, within_s: float) -> bool:
    """Whether the other end of ``sock`` closes it within ``within_s`` (what it sent since
    the freeze, pings it had no answer to, is read and dropped)."""
    deadline = time.monotonic() + within_s
    while (left := deadline - time.monotonic()) > 0:
        sock.settimeout(left)
        try:
            if not sock.recv(65536):
                return True
        except TimeoutError:
            return False
        except OSError:
            return True  # reset: closed too
    return False


def test_a_silent_connection_is_dropped_at_both_ends_and_made_again(
    ctx: zmq.Context[Any],
) -> None:
    changes: list[tuple[bytes, bool]] = []
    seen = threading.Condition()

    def on_subscription(topic: bytes, on: bool) -> None:
        with seen:
            changes.append((topic, on))
            seen.notify_all()

    def wait_for(count: int, on: bool) -> bool:
        with seen:
            return seen.wait_for(
                lambda: sum(1 for t, o in changes if o is on and t == topic) >= count,
                DROP_WITHIN_S,
            )

    topic = topic_to("D2")
    out = OutBridge(
        ctx,
        "tcp://127.0.0.1:0",
        None,
        heartbeat_ms=HEARTBEAT_MS,
        on_subscription=on_subscription,
    )
    out.start()
    host, port = out.endpoint.removeprefix("tcp://").rsplit(":", 1)
    relay = SilentRelay((host, int(port)))
    inb = InBridge(
        ctx,
        {"D1": f"tcp://127.0.0.1:{relay.port}"},
        [topic],
        Collector(),
        MISSION,
        None,
        heartbeat_ms=HEARTBEAT_MS,
    )
    inb.start()
    try:
        assert wait_for(1, True), changes
        relay.silence()
        assert relay.is_silent.wait(DROP_WITHIN_S)
        [(to_sub, to_xpub)] = relay.frozen
        # The Out-Bridge closes the frozen connection (its own, rarer PINGs unanswered) ...
        assert closed_by_its_peer(to_xpub, DROP_WITHIN_S)
        # ... the In-Bridge closes its end (its PINGs unanswered) and subscribes again.
        assert closed_by_its_peer(to_sub, DROP_WITHIN_S)
        assert wait_for(2, True), changes
    finally:
        inb.close()
        out.close()
        relay.close()
