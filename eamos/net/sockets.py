"""Socket set-up shared by the Out- and In-Bridge: options, CURVE, control pipes, monitors.

Everything here runs on the thread that owns the socket (see
:mod:`eamos.net.bridges` for the threading model).
"""

from __future__ import annotations

import threading
import uuid
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, Final, Self

import zmq
from zmq.utils.monitor import recv_monitor_message

from eamos.net.settings import DEFAULT_HEARTBEAT_MS
from eamos.net.zap import participant_domain

if TYPE_CHECKING:
    from eamos.net.keys import FleetKeys

__all__ = [
    "BOUND_HEARTBEAT_FACTOR",
    "CMD_STOP",
    "CMD_WAKE",
    "CONNECTING_PING_FACTOR",
    "CONNECT_TIMEOUT_MS",
    "DEFAULT_HEARTBEAT_MS",
    "DEFAULT_HWM",
    "DEFAULT_LINGER_MS",
    "EVENTS_OPT",
    "HANDSHAKE_IVL_MS",
    "JOIN_TIMEOUT_S",
    "MAX_FRAME_BYTES",
    "POLLIN_BIT",
    "RECONNECT_IVL_MAX_MS",
    "RECONNECT_IVL_MS",
    "Bridge",
    "BridgeThread",
    "Monitor",
    "connection_options",
    "control_pair",
    "curve_client",
    "curve_server",
    "participant_context",
    "recv_message",
    "send_message",
    "should_log",
]

DEFAULT_HWM: Final = 100_000
"""Per-peer queue limit (messages).  ZeroMQ PUB sockets silently drop beyond it,
so it is set far above any burst a mission produces (the default 1000 is not)."""

DEFAULT_LINGER_MS: Final = 500
"""How long ``Context.term()`` may wait to flush messages after ``close()``."""

JOIN_TIMEOUT_S: Final = 5.0
"""Upper bound on how long ``close()`` waits for a bridge thread to finish."""

CONNECT_TIMEOUT_MS: Final = 1000
"""A TCP connect attempt is abandoned (and retried) after this long."""

MAX_FRAME_BYTES: Final = 16 << 20
"""ZeroMQ refuses frames above this (``ZMQ_MAXMSGSIZE``), before buffering them: the
memory one message from a key holder can take.  Refusing cuts the connection (a
protocol error, after which libzmq does not reconnect: the In-Bridge does), so it
is set well above the wire limit (1 MiB): a message between the two arrives whole
and is dropped by ``decode`` (``oversize``) with the connection kept."""

HANDSHAKE_IVL_MS: Final = 5000
"""A connection whose ZMTP/CURVE handshake is not done after this long is closed
(libzmq's default is 30 s): an idle, unauthenticated client holds a descriptor
for at most this long.  A real handshake takes a few round trips."""

RECONNECT_IVL_MS: Final = 100
#: No back-off: libzmq retries a peer that is not up yet every RECONNECT_IVL_MS.  A drone
#: that binds after its peers tried would otherwise wait for their backed-off retry
#: (0.1, 0.3, 0.7, 1.5 s...) before it is ready; a refused connect on a LAN costs little.
#: (Cutting and remaking the connection when the peer shows up raced libzmq's own
#: retry and made peers resend what they had sent.)
RECONNECT_IVL_MAX_MS: Final = RECONNECT_IVL_MS

AUTH_FAILURES: Final[dict[int, str]] = {
    zmq.EVENT_HANDSHAKE_FAILED_AUTH: "auth",
    zmq.EVENT_HANDSHAKE_FAILED_PROTOCOL: "protocol",
    zmq.EVENT_HANDSHAKE_FAILED_NO_DETAIL: "no_detail",
}
MONITOR_EVENTS: Final = (
    zmq.EVENT_HANDSHAKE_FAILED_AUTH
    | zmq.EVENT_HANDSHAKE_FAILED_PROTOCOL
    | zmq.EVENT_HANDSHAKE_FAILED_NO_DETAIL
    | zmq.EVENT_HANDSHAKE_SUCCEEDED
    | zmq.EVENT_DISCONNECTED
    | zmq.EVENT_ACCEPTED
    | zmq.EVENT_CONNECT_RETRIED
)

# ZMQ_EVENTS and its POLLIN bit as plain ints (the bridges test them on every message).
EVENTS_OPT: Final = int(zmq.EVENTS)
POLLIN_BIT: Final = int(zmq.POLLIN)


def send_message(sock: zmq.Socket[Any], frames: list[bytes]) -> None:
    """Send the frames of one message (bytes, at least one); raises what ``send`` raises.

    The caller owns ``sock``.
    """
    sock.send_multipart(frames)


def recv_message(sock: zmq.Socket[Any]) -> list[bytes]:
    """The frames of one waiting message; raises :class:`zmq.Again` if none waits."""
    return sock.recv_multipart(zmq.NOBLOCK)


# Control-pipe commands (first frame).  Never on the network.
# Wakes a thread: the Out-Bridge's socket has something to read, a receive thread calls.
CMD_WAKE: Final = b"wake"
CMD_STOP: Final = b"stop"

# Drops are logged one by one up to this count, then every LOG_EVERY-th, so a
# flooding peer cannot fill the disk with log lines.
LOG_FIRST: Final = 100
LOG_EVERY: Final = 1000


def participant_context() -> zmq.Context[Any]:
    """A ZeroMQ context for one participant or for all of a process.

    Its socket limit is libzmq's largest (``ZMQ_SOCKET_LIMIT``), not the default 1023:
    a participant holds two sockets per peer it listens to (its SUB and that SUB's
    monitor) and libzmq one more per monitor, so a ground station of 300 drones, or a
    process of 50 drones in a relay of 100, would run out of sockets (``EMFILE``,
    "Too many open files") long before it runs out of descriptors.
    """
    context: zmq.Context[Any] = zmq.Context()
    context.set(zmq.MAX_SOCKETS, context.get(zmq.SOCKET_LIMIT))
    return context


def control_pair(context: zmq.Context[Any], name: str) -> tuple[zmq.Socket[Any], zmq.Socket[Any]]:
    """An inproc PAIR pipe ``(receiver, sender)`` with a unique address and no HWM."""
    address = f"inproc://eamos-{name}-{uuid.uuid4().hex}"
    rx = context.socket(zmq.PAIR)
    tx = context.socket(zmq.PAIR)
    for sock in (rx, tx):
        sock.setsockopt(zmq.LINGER, 0)
        sock.setsockopt(zmq.SNDHWM, 0)
        sock.setsockopt(zmq.RCVHWM, 0)
    rx.bind(address)
    tx.connect(address)
    return rx, tx


def should_log(count: int) -> bool:
    return count <= LOG_FIRST or count % LOG_EVERY == 0


BOUND_HEARTBEAT_FACTOR: Final = 5
"""The bound side of a connection (an Out-Bridge's XPUB) pings this many times less often.

ZeroMQ heartbeats (ZMTP PING, each answered by a PONG, both sealed with CURVE on the
I/O threads) went both ways on every connection every interval: at 100 drones, more
frames than the fleet's own messages.  The connecting side (an In-Bridge's SUB)
keeps the timeout: it is what makes it reconnect to a peer that came back.
The bound side only has to close a connection whose subscriber vanished, which can
wait; it cannot leave that to the TTL its subscribers' PINGs carry, because libzmq
(``zmtp_engine.cpp``; the bundled 4.3.5 behaves so) arms that timer only while the
connection's output is active, never on an idle publisher's connection
(``tests/net/test_net_dead_connection.py``)."""

CONNECTING_PING_FACTOR: Final = 2
"""The connecting side (an In-Bridge's SUB) pings every this many heartbeats.

Its timeout stays five heartbeats: libzmq arms it when it sends a PING and cancels
it on any frame received (``stream_engine_base.cpp``), and the publisher's own
heartbeat messages arrive every interval, so a PING only has to start the count.
A connection that froze is closed within seven heartbeats instead of six, with
half the PINGs and PONGs."""

TIMEOUT_HEARTBEATS: Final = 5
"""A connection silent for this many of its side's heartbeats is closed."""


def connection_options(sock: zmq.Socket[Any], heartbeat_ms: int, ping_factor: int = 1) -> None:
    """Liveness and reconnection settings shared by both bridges' network sockets.

    ``heartbeat_ms``: the side's heartbeat (0: no ZeroMQ heartbeats); it pings every
    ``ping_factor`` of them and drops a connection silent for
    :data:`TIMEOUT_HEARTBEATS`.
    """
    if heartbeat_ms > 0:
        sock.setsockopt(zmq.HEARTBEAT_IVL, ping_factor * heartbeat_ms)
        sock.setsockopt(zmq.HEARTBEAT_TIMEOUT, TIMEOUT_HEARTBEATS * heartbeat_ms)
        sock.setsockopt(zmq.HEARTBEAT_TTL, TIMEOUT_HEARTBEATS * heartbeat_ms)
    sock.setsockopt(zmq.CONNECT_TIMEOUT, CONNECT_TIMEOUT_MS)
    sock.setsockopt(zmq.HANDSHAKE_IVL, HANDSHAKE_IVL_MS)
    sock.setsockopt(zmq.RECONNECT_IVL, RECONNECT_IVL_MS)
    sock.setsockopt(zmq.RECONNECT_IVL_MAX, RECONNECT_IVL_MAX_MS)


class Monitor:
    """Reads one socket's monitor events on the bridge thread; logs handshake failures."""

    def __init__(
        self,
        sock: zmq.Socket[Any],
        log: Any,
        peer: str,
        on_disconnect: Callable[[], None] | None = None,
        on_retry: Callable[[], None] | None = None,
    ) -> None:
        # A unique address, not pyzmq's default (made from the socket's descriptor
        # number): the drones of a process share one context, where a descriptor
        # closed by one drone and reused by another would name a monitor still bound.
        self.socket = sock.get_monitor_socket(
            MONITOR_EVENTS, addr=f"inproc://eamos-monitor-{uuid.uuid4().hex}"
        )
        self._owner = sock
        self._log = log
        self._peer = peer
        self._on_disconnect = on_disconnect
        self._on_retry = on_retry  # libzmq reconnects by itself (or already did)
        self.failures = 0
        self.connections = 0
        # Descriptors of the connections accepted and not yet closed (a bound socket).
        self.accepted: set[int] = set()

    def drain(self) -> None:
        while True:
            try:
                event = recv_monitor_message(self.socket, zmq.NOBLOCK)
            except zmq.Again:
                return
            kind, value = int(event["event"]), int(event["value"])
            endpoint = event["endpoint"].decode("utf-8", "replace")
            if kind in AUTH_FAILURES:
                self.failures += 1
                if should_log(self.failures):
                    self._log.warning(
                        "net.auth.failed",
                        peer=self._peer,
                        endpoint=endpoint,
                        failure=AUTH_FAILURES[kind],
                        code=value,
                        count=self.failures,
                    )
            elif kind == zmq.EVENT_HANDSHAKE_SUCCEEDED:
                self.connections += 1
                self._log.debug("net.connected", peer=self._peer, endpoint=endpoint)
                if self._on_retry is not None:
                    self._on_retry()
            elif kind == zmq.EVENT_CONNECT_RETRIED:
                if self._on_retry is not None:
                    self._on_retry()
            elif kind == zmq.EVENT_ACCEPTED:
                self.accepted.add(value)
            elif kind == zmq.EVENT_DISCONNECTED:
                self.accepted.discard(value)
                self._log.debug("net.disconnected", peer=self._peer, endpoint=endpoint)
                if self._on_disconnect is not None:
                    self._on_disconnect()

    def close(self) -> None:
        """Stop the monitor, then close its reading end: before the monitored socket closes.

        libzmq hands each event to the monitor with a blocking send, on the thread that
        raised it (the context's I/O thread).  An event after the reading end closed,
        with the monitor still on (a socket that lingers after its close still raises
        ``EVENT_DISCONNECTED``), blocks that thread for good, and with it every socket
        of the context: drones sharing one context went deaf and mute at a mission's end.
        A monitored socket closed first can no longer stop its monitor: logged
        (``net.monitor.closed_late``), a bug of the caller.
        """
        if self._owner.closed:
            self._log.error("net.monitor.closed_late", peer=self._peer)
        else:
            try:
                self._owner.disable_monitor()
            except zmq.ZMQError:
                self._log.exception("net.monitor.disable_failed", peer=self._peer)
        self.socket.close(linger=0)


def curve_server(sock: zmq.Socket[Any], keys: FleetKeys) -> None:
    """Make ``sock`` (before it binds) a CURVE server that only ZAP-approved keys may join."""
    sock.setsockopt(zmq.CURVE_SERVER, 1)
    sock.setsockopt(zmq.CURVE_PUBLICKEY, keys.public)
    sock.setsockopt(zmq.CURVE_SECRETKEY, keys.secret)
    # The participant's own domain: its provider answers there (eamos.net.zap).
    sock.setsockopt(zmq.ZAP_DOMAIN, participant_domain(keys.me).encode())
    # Without a ZAP handler on the context, refuse everyone (libzmq's default
    # would be to accept any client key).
    sock.setsockopt(zmq.ZAP_ENFORCE_DOMAIN, 1)


def curve_client(sock: zmq.Socket[Any], keys: FleetKeys, server_key: bytes) -> None:
    """Make ``sock`` (before it connects) a CURVE client of the server with ``server_key``."""
    sock.setsockopt(zmq.CURVE_SERVERKEY, server_key)
    sock.setsockopt(zmq.CURVE_PUBLICKEY, keys.public)
    sock.setsockopt(zmq.CURVE_SECRETKEY, keys.secret)


class Bridge:
    """What both bridges offer alike: ``with`` (start, then close) and :attr:`closed`."""

    _closed: bool

    def start(self) -> None:
        """Start the bridge."""
        raise NotImplementedError

    def close(self) -> None:
        """Close the bridge; idempotent."""
        raise NotImplementedError

    def __enter__(self) -> Self:
        self.start()
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    @property
    def closed(self) -> bool:
        """Whether ``close()`` was called."""
        return self._closed


class BridgeThread(Bridge):
    """The lifecycle both bridges share: one thread owns the sockets, a command stops it.

    A subclass builds its sockets, ``_ctrl_tx`` and ``_thread`` and sets
    ``_lock``, ``_started``, ``_closed`` and ``_tx_open``; it provides
    :meth:`_close_sockets` (for a bridge whose thread never ran) and
    :meth:`_close_timeout` (what to log when the thread does not end).
    """

    _lock: threading.Lock
    _started: bool
    _closed: bool
    _tx_open: bool
    _ctrl_tx: zmq.Socket[Any]
    _thread: threading.Thread

    def start(self) -> None:
        """Start the bridge thread; a no-op if running, RuntimeError once closed."""
        with self._lock:
            if self._closed:
                raise RuntimeError(f"{type(self).__name__} is closed")
            if self._started:
                return
            self._started = True
            self._on_start()
            self._thread.start()

    def close(self) -> None:
        """Stop the thread and close the sockets; idempotent and safe from any thread.

        Commands queued before ``close()`` are handled first (the stop command
        travels the same FIFO pipe behind them).  May be called from the bridge's
        own callbacks: the thread then stops after the callback returns (it is
        not joined, which would deadlock).
        """
        with self._lock:
            if self._closed:
                return
            self._closed = True
            if not self._started:
                # The thread never ran, so this thread may close its sockets.
                self._tx_open = False
                self._close_sockets()
                return
            if self._tx_open:
                self._ctrl_tx.send(CMD_STOP)
        if threading.current_thread() is not self._thread:
            self._thread.join(JOIN_TIMEOUT_S)
            if self._thread.is_alive():
                self._close_timeout()

    def _on_start(self) -> None:
        """Called under the lock just before the thread starts."""

    def _close_sockets(self) -> None:
        raise NotImplementedError

    def _close_timeout(self) -> None:
        raise NotImplementedError
