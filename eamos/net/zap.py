"""A ZAP handler (ZeroMQ RFC 27) for CURVE key checks: one small thread per context.

libzmq asks the handler bound at ``inproc://zeromq.zap.01`` of a context
whether each CURVE handshake of that context's server sockets may proceed.
pyzmq's ``ThreadAuthenticator`` does this too, but it imports asyncio (about
30 ms of every drone's start-up) and runs an event loop; this handler is a
blocking poll on the ZAP socket and a stop pipe, answering as pyzmq's does:

* ``CURVE`` in the configured domain: ``allow(domain, z85 key)`` decides
  (200 with the z85 key as user id, or 400 "Unknown key"); another domain
  is refused ("Unknown domain");
* ``NULL`` is let through (the sockets that use it are plain on loopback);
* every other mechanism, a malformed request or another ZAP version is refused.

The answer is computed in the handler thread from an in-memory key table, so a
key check costs one inproc round trip, not a thread per connection.
"""

from __future__ import annotations

import threading
import uuid
from collections.abc import Callable
from typing import Any, Final

import zmq
from zmq.utils import z85

__all__ = ["ZAP_ENDPOINT", "ZapHandler", "zap_reply"]

ZAP_ENDPOINT: Final = "inproc://zeromq.zap.01"
_VERSION: Final = b"1.0"


def zap_reply(
    request: list[bytes], domain: str, allow: Callable[[str, bytes], bool]
) -> list[bytes] | None:
    """The reply frames to one ZAP request (None when it cannot be answered at all)."""
    if len(request) < 2:
        return None
    if len(request) < 6:
        return [_VERSION, request[1], b"400", b"Not enough frames", b"", b""]
    version, request_id, req_domain, _address, _identity, mechanism = request[:6]
    credentials = request[6:]

    def refuse(text: bytes) -> list[bytes]:
        return [_VERSION, request_id, b"400", text, b"", b""]

    if version != _VERSION:
        return refuse(b"Invalid version")
    if mechanism == b"NULL":
        return [_VERSION, request_id, b"200", b"OK", b"anonymous", b""]
    if mechanism != b"CURVE":
        return refuse(b"NO ACCESS")
    if len(credentials) != 1 or len(credentials[0]) != 32:
        return refuse(b"Invalid credentials")
    name = req_domain.decode("utf-8", "replace") or "*"
    if name != domain:
        return refuse(b"Unknown domain")
    key = z85.encode(credentials[0])
    if not allow(name, key):
        return refuse(b"Unknown key")
    return [_VERSION, request_id, b"200", b"OK", key, b""]


class ZapHandler:
    """Answers the ZAP requests of one ZeroMQ context until :meth:`stop`.

    Raises ``zmq.ZMQError`` when the context has a ZAP handler already (the
    endpoint is bound).  ``allow(domain, z85_key)`` runs on the handler thread;
    an exception in it refuses that connection and is counted (:attr:`errors`).
    """

    def __init__(
        self, context: zmq.Context[Any], domain: str, allow: Callable[[str, bytes], bool]
    ) -> None:
        self._domain = domain
        self._allow = allow
        self.errors = 0
        self._zap = context.socket(zmq.REP)
        self._zap.linger = 0
        try:
            self._zap.bind(ZAP_ENDPOINT)
        except zmq.ZMQError:
            self._zap.close()
            raise
        pipe = f"inproc://eamos-zap-stop-{uuid.uuid4().hex}"
        self._stop_rx = context.socket(zmq.PAIR)
        self._stop_rx.linger = 0
        self._stop_rx.bind(pipe)
        self._stop_tx = context.socket(zmq.PAIR)
        self._stop_tx.linger = 0
        self._stop_tx.connect(pipe)
        self._lock = threading.Lock()
        self._stopped = False
        self._thread = threading.Thread(target=self._run, name="zap", daemon=True)
        self._thread.start()

    def _checked(self, domain: str, key: bytes) -> bool:
        try:
            return bool(self._allow(domain, key))
        except Exception:  # a checker bug must refuse, never admit nor kill the thread
            self.errors += 1
            return False

    def _run(self) -> None:
        poller = zmq.Poller()
        poller.register(self._zap, zmq.POLLIN)
        poller.register(self._stop_rx, zmq.POLLIN)
        try:
            while True:
                ready = dict(poller.poll())
                if self._stop_rx in ready:
                    return
                if self._zap in ready:
                    request = self._zap.recv_multipart()
                    reply = zap_reply(request, self._domain, self._checked)
                    # A REP socket must answer before it can receive again.
                    self._zap.send_multipart(reply or [_VERSION, b"", b"500", b"", b"", b""])
        except zmq.ContextTerminated:
            return
        finally:
            self._zap.close()
            self._stop_rx.close()

    def stop(self) -> None:
        """Stop answering and close the sockets (before ``Context.term``); idempotent."""
        with self._lock:
            if self._stopped:
                return
            self._stopped = True
            try:
                self._stop_tx.send(b"")
            except zmq.ZMQError:
                pass  # the context is going: the thread ends by itself
            self._thread.join()
            self._stop_tx.close()
