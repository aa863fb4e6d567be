"""Out-Bridge and In-Bridge (the paper's names): the sockets between participants.

Each participant (drone or ground station) owns exactly one :class:`OutBridge`
(an XPUB socket it binds; everything it sends leaves through it) and one
:class:`InBridge` (one SUB socket connected to the Out-Bridges of its peers).

Threading model
---------------
ZeroMQ sockets must not be used by two threads at once, so each bridge owns one
thread that is the only user of its network socket:

* ``OutBridge.send`` may be called from any thread.  It encodes the message in
  the caller's thread (so a bad message raises :class:`~eamos.net.wire.WireError`
  at the caller), then, under a lock, writes the frames into an in-process
  PAIR pipe.  The bridge thread forwards them to the XPUB socket in FIFO order
  and, on the same poller, reads the subscription frames the XPUB socket
  delivers.  Messages from one thread therefore leave in the order they were
  sent.  The pipe has no high-water mark, so ``send`` never blocks.
* ``InBridge`` runs one receive thread polling the SUB socket and a control
  PAIR pipe; ``add_subscription`` and ``close`` talk to it through that pipe.
  ``on_message`` is called on that thread, so it should hand work off quickly
  (e.g. to an actor's mailbox) rather than block.

Lifecycle
---------
Construct (binds/connects and subscribes), ``start()`` (starts the thread),
use, ``close()`` (idempotent, never blocks for long: sockets are closed with a
small linger by the bridge thread itself, which is then joined with a timeout).
Both bridges are also context managers (``with OutBridge(...) as out:``).
Closing sockets never blocks in ZeroMQ; only ``Context.term()`` waits for up to
the linger time to flush messages still queued to peers, which is what lets a
final Abort or Complete get out before the process exits.

Security
--------
With ``curve=`` (a :class:`~eamos.net.keys.FleetKeys`) the Out-Bridge is a
CURVE server (ZAP domain :data:`~eamos.net.keys.ZAP_DOMAIN`, enforced: a
context without a ZAP handler admits nobody) and the In-Bridge opens one CURVE
client socket per peer, each knowing that peer's public key, so a message read
from a socket comes from that peer.  With ``check_sender=True`` the In-Bridge
also drops messages whose ``sender`` is not the peer of the socket they came
in on (a fleet member impersonating another).  Without ``curve`` the sockets
are plain; *whether* plain is allowed is decided above (config, runtime), see
:func:`eamos.net.keys.plain_refusal`.  Failed handshakes (wrong keys, a plain
peer meeting a CURVE one) are seen through ZeroMQ socket monitors and logged
as ``net.auth.failed``; unknown keys refused by ZAP as ``net.auth.denied``.

Reliability (sequence numbers, acks, retransmission, heartbeats) lives one
level up, in :mod:`eamos.net.link`, which uses ``on_subscription`` and
``on_batch_end`` to react to reconnections and to acknowledge in batches.

Connections: ZeroMQ heartbeats (``heartbeat_ms``) drop a connection whose
peer went silent, and connection attempts time out after
``CONNECT_TIMEOUT_MS``, so a link that comes back is reconnected within about
a second instead of waiting for TCP's own back-off.
"""

from __future__ import annotations

import threading
import uuid
from collections.abc import Callable, Iterable, Mapping
from typing import TYPE_CHECKING, Any, Final

import zmq
from zmq.utils.monitor import parse_monitor_message

from eamos.logs import make_logger
from eamos.net.wire import MAX_PAYLOAD_BYTES, Message, WireError, decode, encode

if TYPE_CHECKING:
    from eamos.net.keys import FleetKeys

__all__ = ["DEFAULT_HWM", "DEFAULT_LINGER_MS", "InBridge", "OutBridge"]

DEFAULT_HWM: Final = 100_000
"""Per-peer queue limit (messages).  ZeroMQ PUB sockets silently drop beyond it,
so it is set far above any burst a mission produces (the default 1000 is not)."""

DEFAULT_LINGER_MS: Final = 500
"""How long ``Context.term()`` may wait to flush messages after ``close()``."""

JOIN_TIMEOUT_S: Final = 5.0
"""Upper bound on how long ``close()`` waits for a bridge thread to finish."""

DEFAULT_HEARTBEAT_MS: Final = 1000
"""ZeroMQ (ZMTP) heartbeat interval; a connection silent for 5 of them is dropped."""

CONNECT_TIMEOUT_MS: Final = 1000
"""A TCP connect attempt is abandoned (and retried) after this long."""

RECONNECT_IVL_MS: Final = 100
RECONNECT_IVL_MAX_MS: Final = 1000

_AUTH_FAILURES: Final[dict[int, str]] = {
    zmq.EVENT_HANDSHAKE_FAILED_AUTH: "auth",
    zmq.EVENT_HANDSHAKE_FAILED_PROTOCOL: "protocol",
    zmq.EVENT_HANDSHAKE_FAILED_NO_DETAIL: "no_detail",
}
_MONITOR_EVENTS: Final = (
    zmq.EVENT_HANDSHAKE_FAILED_AUTH
    | zmq.EVENT_HANDSHAKE_FAILED_PROTOCOL
    | zmq.EVENT_HANDSHAKE_FAILED_NO_DETAIL
    | zmq.EVENT_HANDSHAKE_SUCCEEDED
    | zmq.EVENT_DISCONNECTED
)

# Control-pipe commands (first frame).  Never on the network.
_CMD_SEND: Final = b"send"
_CMD_SUB: Final = b"sub"
_CMD_STOP: Final = b"stop"

# Drops are logged one by one up to this count, then every _LOG_EVERY-th, so a
# flooding peer cannot fill the disk with log lines.
_LOG_FIRST: Final = 100
_LOG_EVERY: Final = 1000


def _control_pair(context: zmq.Context[Any], name: str) -> tuple[zmq.Socket[Any], zmq.Socket[Any]]:
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


def _should_log(count: int) -> bool:
    return count <= _LOG_FIRST or count % _LOG_EVERY == 0


def _connection_options(sock: zmq.Socket[Any], heartbeat_ms: int) -> None:
    """Liveness and reconnection settings shared by both bridges' network sockets."""
    if heartbeat_ms > 0:
        sock.setsockopt(zmq.HEARTBEAT_IVL, heartbeat_ms)
        sock.setsockopt(zmq.HEARTBEAT_TIMEOUT, 5 * heartbeat_ms)
        sock.setsockopt(zmq.HEARTBEAT_TTL, 5 * heartbeat_ms)
    sock.setsockopt(zmq.CONNECT_TIMEOUT, CONNECT_TIMEOUT_MS)
    sock.setsockopt(zmq.RECONNECT_IVL, RECONNECT_IVL_MS)
    sock.setsockopt(zmq.RECONNECT_IVL_MAX, RECONNECT_IVL_MAX_MS)


class _Monitor:
    """Reads one socket's monitor events on the bridge thread; logs handshake failures."""

    def __init__(self, sock: zmq.Socket[Any], log: Any, peer: str) -> None:
        self.socket = sock.get_monitor_socket(_MONITOR_EVENTS)
        self._owner = sock
        self._log = log
        self._peer = peer
        self.failures = 0
        self.connections = 0

    def drain(self) -> None:
        while True:
            try:
                frames = self.socket.recv_multipart(zmq.NOBLOCK)
            except zmq.Again:
                return
            try:
                event = parse_monitor_message(frames)
            except (ValueError, IndexError):  # pragma: no cover - libzmq wrote it
                continue
            kind = int(event["event"])
            raw = event["endpoint"]
            endpoint = raw.decode("utf-8", "replace") if isinstance(raw, bytes) else str(raw)
            if kind in _AUTH_FAILURES:
                self.failures += 1
                if _should_log(self.failures):
                    self._log.warning(
                        "net.auth.failed",
                        peer=self._peer,
                        endpoint=endpoint,
                        failure=_AUTH_FAILURES[kind],
                        code=event["value"],
                        count=self.failures,
                    )
            elif kind == zmq.EVENT_HANDSHAKE_SUCCEEDED:
                self.connections += 1
                self._log.debug("net.connected", peer=self._peer, endpoint=endpoint)
            elif kind == zmq.EVENT_DISCONNECTED:
                self._log.debug("net.disconnected", peer=self._peer, endpoint=endpoint)

    def close(self) -> None:
        try:
            self._owner.disable_monitor()
        except zmq.ZMQError:
            pass
        self.socket.close(linger=0)


class OutBridge:
    """The participant's outgoing side: one bound XPUB socket, fed by any thread.

    ``bind`` is a ZeroMQ endpoint such as ``tcp://127.0.0.1:6001``; port 0
    (``tcp://127.0.0.1:0``, ``tcp://*:0``) picks a free port, and the actual
    endpoint is available as :attr:`endpoint`.
    """

    def __init__(
        self,
        context: zmq.Context[Any],
        bind: str,
        log: Any = None,
        *,
        hwm: int = DEFAULT_HWM,
        linger_ms: int = DEFAULT_LINGER_MS,
        curve: FleetKeys | None = None,
        heartbeat_ms: int = DEFAULT_HEARTBEAT_MS,
        on_subscription: Callable[[bytes, bool], None] | None = None,
    ) -> None:
        self._log = log if log is not None else make_logger(None)
        self._on_subscription = on_subscription
        self.secure = curve is not None
        self._xpub = context.socket(zmq.XPUB)
        self._xpub.setsockopt(zmq.LINGER, linger_ms)
        self._xpub.setsockopt(zmq.SNDHWM, hwm)
        # VERBOSE: pass every subscription up, not only the first per topic, so a
        # peer that reconnects (or a second peer) is seen too.
        self._xpub.setsockopt(zmq.XPUB_VERBOSE, 1)
        _connection_options(self._xpub, heartbeat_ms)
        self._monitor: _Monitor | None = None
        try:
            if curve is not None:
                from eamos.net.keys import ZAP_DOMAIN

                self._xpub.setsockopt(zmq.CURVE_SERVER, 1)
                self._xpub.setsockopt(zmq.CURVE_PUBLICKEY, curve.public)
                self._xpub.setsockopt(zmq.CURVE_SECRETKEY, curve.secret)
                self._xpub.setsockopt(zmq.ZAP_DOMAIN, ZAP_DOMAIN.encode())
                # Without a ZAP handler on the context, refuse everyone (libzmq's
                # default would be to accept any client key).
                self._xpub.setsockopt(zmq.ZAP_ENFORCE_DOMAIN, 1)
            self._monitor = _Monitor(self._xpub, self._log, "*")
            self._xpub.bind(bind)
        except zmq.ZMQError:
            if self._monitor is not None:
                self._monitor.close()
            self._xpub.close(linger=0)
            raise
        self.endpoint: str = self._xpub.getsockopt(zmq.LAST_ENDPOINT).decode()
        self._ctrl_rx, self._ctrl_tx = _control_pair(context, "out")

        # _lock guards _ctrl_tx, the lifecycle flags and the send counters.
        self._lock = threading.Lock()
        self._started = False
        self._closed = False
        self._tx_open = True
        self._sent_counts: dict[str, int] = {}
        self._sent_bytes_by_type: dict[str, int] = {}
        self._sent_bytes = 0
        # _cond guards the subscription set and _running; wait_subscribed waits on it.
        self._cond = threading.Condition()
        self._subscriptions: set[bytes] = set()
        self._running = False
        self._thread = threading.Thread(
            target=self._run, name=f"eamos-outbridge-{self.endpoint}", daemon=True
        )

    # -- lifecycle ---------------------------------------------------------

    def start(self) -> None:
        """Start the bridge thread (forwarding sends, tracking subscriptions)."""
        with self._lock:
            if self._closed:
                raise RuntimeError("OutBridge is closed")
            if self._started:
                return
            self._started = True
            with self._cond:
                self._running = True
            self._thread.start()

    def close(self) -> None:
        """Stop the thread and close the sockets; idempotent and safe from any thread.

        Messages sent before ``close()`` are handed to the XPUB socket first
        (the stop command travels the same FIFO pipe behind them).
        """
        with self._lock:
            if self._closed:
                return
            self._closed = True
            if not self._started:
                # The thread never ran, so this thread may close its sockets.
                self._ctrl_tx.close()
                self._tx_open = False
                self._ctrl_rx.close()
                if self._monitor is not None:
                    self._monitor.close()
                self._xpub.close()
                return
            if self._tx_open:
                self._ctrl_tx.send(_CMD_STOP)
        if threading.current_thread() is not self._thread:
            self._thread.join(JOIN_TIMEOUT_S)
            if self._thread.is_alive():
                self._log.warning("net.out.close_timeout", endpoint=self.endpoint)

    def __enter__(self) -> OutBridge:
        self.start()
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    @property
    def closed(self) -> bool:
        """Whether ``close()`` was called."""
        return self._closed

    # -- sending -----------------------------------------------------------

    def send(self, msg: Message) -> bool:
        """Queue ``msg`` for publication; thread-safe and non-blocking.

        Returns False (and logs) if the bridge is closed.  Raises
        :class:`~eamos.net.wire.WireError` if ``msg`` cannot be encoded.
        Messages sent before :meth:`start` are queued and go out once started.
        """
        frames = encode(msg)
        with self._lock:
            if self._closed or not self._tx_open:
                self._log.info("net.out.send_after_close", type=type(msg).__name__)
                return False
            self._ctrl_tx.send_multipart([_CMD_SEND, *frames])
            name = type(msg).__name__
            size = len(frames[0]) + len(frames[1])
            self._sent_counts[name] = self._sent_counts.get(name, 0) + 1
            self._sent_bytes_by_type[name] = self._sent_bytes_by_type.get(name, 0) + size
            self._sent_bytes += size
        return True

    @property
    def sent_counts(self) -> dict[str, int]:
        """Messages accepted by :meth:`send`, per message class name (a copy)."""
        with self._lock:
            return dict(self._sent_counts)

    @property
    def sent_bytes(self) -> int:
        """Bytes (topic + payload) accepted by :meth:`send`."""
        with self._lock:
            return self._sent_bytes

    @property
    def sent_bytes_by_type(self) -> dict[str, int]:
        """Bytes (topic + payload) accepted by :meth:`send`, per message class name."""
        with self._lock:
            return dict(self._sent_bytes_by_type)

    @property
    def auth_failures(self) -> int:
        """Handshakes with this bridge that failed (wrong keys, plain peer, ZAP denial)."""
        return self._monitor.failures if self._monitor is not None else 0

    # -- subscriptions -----------------------------------------------------

    @property
    def subscriptions(self) -> frozenset[bytes]:
        """Topic prefixes that currently have at least one subscriber."""
        with self._cond:
            return frozenset(self._subscriptions)

    def _covered(self, topic: bytes) -> bool:
        # SUB filters are prefixes: a subscriber to b"" or b"to/" gets b"to/D2" too.
        return any(topic.startswith(prefix) for prefix in self._subscriptions)

    def wait_subscribed(self, topics: Iterable[bytes], timeout_s: float) -> bool:
        """Block until every topic in ``topics`` has a subscriber, or ``timeout_s`` passes.

        Returns True once all are covered; False on timeout or if the bridge is
        not running.  A message published on a covered topic reaches at least
        one subscriber (the XPUB socket has applied the subscription before it
        reports it to us).
        """
        wanted = list(topics)
        with self._cond:
            self._cond.wait_for(
                lambda: not self._running or all(self._covered(t) for t in wanted), timeout_s
            )
            return self._running and all(self._covered(t) for t in wanted)

    # -- bridge thread -----------------------------------------------------

    def _run(self) -> None:
        poller = zmq.Poller()
        poller.register(self._ctrl_rx, zmq.POLLIN)
        poller.register(self._xpub, zmq.POLLIN)
        monitor = self._monitor
        if monitor is not None:
            poller.register(monitor.socket, zmq.POLLIN)
        try:
            while True:
                events = dict(poller.poll())
                if self._xpub in events:
                    self._read_subscriptions()
                if monitor is not None and monitor.socket in events:
                    monitor.drain()
                if self._ctrl_rx in events and not self._drain_control():
                    return
        except zmq.ContextTerminated:
            self._log.warning("net.out.context_terminated", endpoint=self.endpoint)
        except zmq.ZMQError:
            self._log.exception("net.out.thread_error", endpoint=self.endpoint)
        finally:
            with self._lock:
                self._ctrl_tx.close()
                self._tx_open = False
            self._ctrl_rx.close()
            if monitor is not None:
                monitor.close()
            self._xpub.close()
            with self._cond:
                self._running = False
                self._cond.notify_all()

    def _drain_control(self) -> bool:
        """Forward every queued command; False once the stop command is seen."""
        while True:
            try:
                frames = self._ctrl_rx.recv_multipart(zmq.NOBLOCK)
            except zmq.Again:
                return True
            if frames[0] == _CMD_STOP:
                return False
            self._forward(frames[1:])

    def _forward(self, frames: list[bytes]) -> None:
        # The one place outgoing frames hit the network.  XPUB never blocks: it
        # drops for a peer whose queue is at the HWM (hence the large HWM).
        self._xpub.send_multipart(frames)

    def _read_subscriptions(self) -> None:
        changed: list[tuple[bytes, bool]] = []
        while True:
            try:
                frame = self._xpub.recv(zmq.NOBLOCK)
            except zmq.Again:
                break
            if not frame or frame[0] not in (0, 1):
                continue  # not a (un)subscription frame; SUB peers send nothing else
            topic = frame[1:]
            with self._cond:
                if frame[0] == 1:
                    self._subscriptions.add(topic)
                else:
                    # Without XPUB_VERBOSER, an unsubscribe only arrives once the
                    # last subscriber of this topic is gone.
                    self._subscriptions.discard(topic)
            changed.append((topic, frame[0] == 1))
            self._log.debug(
                "net.out.subscription", topic=topic.decode("utf-8", "replace"), on=frame[0] == 1
            )
        if changed:
            with self._cond:
                self._cond.notify_all()
            if self._on_subscription is not None:
                for topic, on in changed:
                    try:
                        self._on_subscription(topic, on)
                    except Exception:  # the bridge thread must survive its callback
                        self._log.exception("net.out.callback_error")


class InBridge:
    """The participant's incoming side: one SUB socket per peer it connects to.

    ``connect`` maps peer names to their Out-Bridge endpoints; ``subscribe``
    lists the topics to receive (see :func:`~eamos.net.wire.topic_to`,
    :func:`~eamos.net.wire.topic_telemetry`, :data:`~eamos.net.wire.TOPIC_ALL`).
    Topics are matched exactly, because ZeroMQ's prefix matching would deliver
    ``to/D10`` to a subscriber of ``to/D1``; a topic ending in ``/`` (or empty)
    is a deliberate prefix subscription.

    Every message that decodes, whose topic was subscribed and whose mission is
    ``mission`` is passed to ``on_message`` on the receive thread.  Malformed
    messages, messages of another wire version or mission, and (with
    ``check_sender``) messages whose sender is not the peer they came from are
    dropped, logged (``net.in.drop`` with a ``reason``) and counted in
    :attr:`dropped` and :attr:`dropped_by_reason`.  ``on_batch_end`` is called
    on the receive thread after each batch of messages (the reliability layer
    acknowledges there, once per batch instead of once per message).

    One socket per peer (rather than one for all) is what lets a CURVE client
    know each peer's public key, and lets the bridge know which peer a message
    came from.
    """

    def __init__(
        self,
        context: zmq.Context[Any],
        connect: Mapping[str, str],
        subscribe: Iterable[bytes],
        on_message: Callable[[Message], None],
        mission: str,
        log: Any = None,
        *,
        hwm: int = DEFAULT_HWM,
        curve: FleetKeys | None = None,
        check_sender: bool = False,
        heartbeat_ms: int = DEFAULT_HEARTBEAT_MS,
        on_batch_end: Callable[[], None] | None = None,
    ) -> None:
        self.mission = mission
        self.peers: dict[str, str] = dict(connect)
        self.secure = curve is not None
        self._on_message = on_message
        self._on_batch_end = on_batch_end
        self._check_sender = check_sender
        self._log = log if log is not None else make_logger(None)
        if curve is not None:
            missing = curve.missing(self.peers)
            if missing:
                raise ValueError(f"no public key for peer(s) {', '.join(missing)}")
        self._subs: dict[zmq.Socket[Any], str] = {}
        self._monitors: list[_Monitor] = []
        self._ctrl_rx, self._ctrl_tx = _control_pair(context, "in")
        # Owned by the receive thread once started; before that, by the caller
        # under _lock (the thread start is the hand-over).
        self._exact: set[bytes] = set()
        self._prefixes: set[bytes] = set()
        topics = list(subscribe)
        try:
            for peer, endpoint in self.peers.items():
                sub = context.socket(zmq.SUB)
                self._subs[sub] = peer
                sub.setsockopt(zmq.LINGER, 0)
                sub.setsockopt(zmq.RCVHWM, hwm)
                # ZeroMQ refuses (and disconnects) peers sending frames larger than
                # any valid message, before they are buffered in full.
                sub.setsockopt(zmq.MAXMSGSIZE, MAX_PAYLOAD_BYTES)
                _connection_options(sub, heartbeat_ms)
                if curve is not None:
                    sub.setsockopt(zmq.CURVE_SERVERKEY, curve.fleet[peer])
                    sub.setsockopt(zmq.CURVE_PUBLICKEY, curve.public)
                    sub.setsockopt(zmq.CURVE_SECRETKEY, curve.secret)
                self._monitors.append(_Monitor(sub, self._log, peer))
                sub.connect(endpoint)
            for topic in topics:
                self._subscribe(topic)
        except zmq.ZMQError:
            # A bad endpoint must not leak sockets (and block Context.term).
            self._close_sockets()
            raise

        self._lock = threading.Lock()  # guards _ctrl_tx and the lifecycle flags
        self._started = False
        self._closed = False
        self._tx_open = True
        # Written only by the receive thread; plain ints are safe to read elsewhere.
        self._received = 0
        self._dropped = 0
        self._dropped_by_reason: dict[str, int] = {}
        self._ignored = 0
        self._callback_errors = 0
        self._thread = threading.Thread(target=self._run, name="eamos-inbridge", daemon=True)

    def _close_sockets(self) -> None:
        for monitor in self._monitors:
            monitor.close()
        for sock in (*self._subs, self._ctrl_rx, self._ctrl_tx):
            sock.close(linger=0)

    # -- lifecycle ---------------------------------------------------------

    def start(self) -> None:
        """Start the receive thread."""
        with self._lock:
            if self._closed:
                raise RuntimeError("InBridge is closed")
            if self._started:
                return
            self._started = True
            self._thread.start()

    def close(self) -> None:
        """Stop the receive thread and close the sockets; idempotent, any thread.

        May be called from ``on_message`` itself: the thread then stops after
        the callback returns (it is not joined, which would deadlock).
        """
        with self._lock:
            if self._closed:
                return
            self._closed = True
            if not self._started:
                self._tx_open = False
                self._close_sockets()
                return
            if self._tx_open:
                self._ctrl_tx.send(_CMD_STOP)
        if threading.current_thread() is not self._thread:
            self._thread.join(JOIN_TIMEOUT_S)
            if self._thread.is_alive():
                self._log.warning("net.in.close_timeout")

    def __enter__(self) -> InBridge:
        self.start()
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    @property
    def closed(self) -> bool:
        """Whether ``close()`` was called."""
        return self._closed

    # -- subscriptions -----------------------------------------------------

    def add_subscription(self, topic: bytes) -> bool:
        """Also receive ``topic``; safe from any thread.  False if closed."""
        with self._lock:
            if self._closed or not self._tx_open:
                return False
            if not self._started:
                self._subscribe(topic)
            else:
                self._ctrl_tx.send_multipart([_CMD_SUB, topic])
        return True

    def _subscribe(self, topic: bytes) -> None:
        for sub in self._subs:
            sub.setsockopt(zmq.SUBSCRIBE, topic)
        if topic == b"" or topic.endswith(b"/"):
            self._prefixes.add(topic)
        else:
            self._exact.add(topic)

    def _wanted(self, topic: bytes) -> bool:
        return topic in self._exact or any(topic.startswith(p) for p in self._prefixes)

    # -- counters ----------------------------------------------------------

    @property
    def received(self) -> int:
        """Messages passed to ``on_message``."""
        return self._received

    @property
    def dropped(self) -> int:
        """Messages dropped (malformed, other version or mission, wrong sender)."""
        return self._dropped

    @property
    def dropped_by_reason(self) -> dict[str, int]:
        """:attr:`dropped` per reason (a copy)."""
        return dict(self._dropped_by_reason)

    @property
    def ignored(self) -> int:
        """Messages on topics that only share a prefix with a subscription."""
        return self._ignored

    @property
    def callback_errors(self) -> int:
        """Calls of ``on_message`` that raised."""
        return self._callback_errors

    @property
    def auth_failures(self) -> int:
        """Handshakes with peers that failed (e.g. an impostor at a peer's address)."""
        return sum(m.failures for m in self._monitors)

    # -- receive thread ----------------------------------------------------

    def _run(self) -> None:
        poller = zmq.Poller()
        poller.register(self._ctrl_rx, zmq.POLLIN)
        for sub in self._subs:
            poller.register(sub, zmq.POLLIN)
        monitors = {m.socket: m for m in self._monitors}
        for mon in monitors:
            poller.register(mon, zmq.POLLIN)
        try:
            while True:
                events = dict(poller.poll())
                if self._ctrl_rx in events and not self._drain_control():
                    return
                delivered = False
                for sock in events:
                    peer = self._subs.get(sock)
                    if peer is not None:
                        delivered = self._drain_sub(sock, peer) or delivered
                    elif sock in monitors:
                        monitors[sock].drain()
                if self._closed:
                    return  # close() was called from on_message
                if delivered and self._on_batch_end is not None:
                    try:
                        self._on_batch_end()
                    except Exception:
                        self._log.exception("net.in.callback_error", type="batch_end")
        except zmq.ContextTerminated:
            self._log.warning("net.in.context_terminated")
        except zmq.ZMQError:
            self._log.exception("net.in.thread_error")
        finally:
            with self._lock:
                self._ctrl_tx.close()
                self._tx_open = False
            self._ctrl_rx.close()
            for monitor in self._monitors:
                monitor.close()
            for sub in self._subs:
                sub.close()

    def _drain_control(self) -> bool:
        while True:
            try:
                frames = self._ctrl_rx.recv_multipart(zmq.NOBLOCK)
            except zmq.Again:
                return True
            if frames[0] == _CMD_STOP:
                return False
            if frames[0] == _CMD_SUB:
                self._subscribe(frames[1])

    def _drain_sub(self, sub: zmq.Socket[Any], peer: str) -> bool:
        # Bounded batch so a stop or subscribe command, or another peer, is not
        # starved by a flood.
        got = False
        for _ in range(256):
            if self._closed:
                return got  # close() was called from on_message: deliver nothing more
            try:
                frames = sub.recv_multipart(zmq.NOBLOCK)
            except zmq.Again:
                return got
            got = True
            self._handle(frames, peer)
        return got

    def _handle(self, frames: list[bytes], peer: str = "") -> None:
        """Filter, decode and deliver one received multipart message from ``peer``."""
        if not self._wanted(frames[0]):
            self._ignored += 1
            return
        try:
            msg = decode(frames)
        except WireError as exc:
            self._drop(exc.reason, frames[0], str(exc), peer=peer)
            return
        if msg.mission != self.mission:
            self._drop("other_mission", frames[0], msg.mission, sender=msg.sender, peer=peer)
            return
        if self._check_sender and msg.sender != peer:
            self._drop("sender", frames[0], f"{msg.sender!r} on {peer!r}'s link", peer=peer)
            return
        self._received += 1
        try:
            self._on_message(msg)
        # Any failure in the consumer must not kill the receive thread: that
        # would silently cut this participant off from the mission.
        except Exception:
            self._callback_errors += 1
            self._log.exception("net.in.callback_error", type=type(msg).__name__, sender=msg.sender)

    def _drop(self, reason: str, topic: bytes, detail: str, **extra: Any) -> None:
        self._dropped += 1
        self._dropped_by_reason[reason] = self._dropped_by_reason.get(reason, 0) + 1
        if _should_log(self._dropped):
            self._log.warning(
                "net.in.drop",
                reason=reason,
                topic=topic.decode("utf-8", "replace"),
                detail=detail,
                dropped=self._dropped,
                **extra,
            )
