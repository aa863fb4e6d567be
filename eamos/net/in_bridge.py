"""The In-Bridge: a participant's SUB sockets, one per peer, and their receive thread.

See :mod:`eamos.net.bridges` for the threading model, the lifecycle and security.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterable, Mapping
from typing import TYPE_CHECKING, Any

import zmq

from eamos.logs import EventLog, make_logger
from eamos.net.receive_host import ReceiveHost
from eamos.net.reconnect import Reconnector
from eamos.net.sockets import (
    CONNECTING_PING_FACTOR,
    DEFAULT_HEARTBEAT_MS,
    DEFAULT_HWM,
    EVENTS_OPT,
    JOIN_TIMEOUT_S,
    MAX_FRAME_BYTES,
    POLLIN_BIT,
    Bridge,
    Monitor,
    connection_options,
    curve_client,
    recv_message,
    should_log,
)
from eamos.net.wire import Message, WireError, decode

if TYPE_CHECKING:
    from eamos.net.keys import FleetKeys

__all__ = ["InBridge", "latest_telemetry", "read_batch"]


def latest_telemetry(batch: list[list[bytes]]) -> tuple[list[list[bytes]], int]:
    """``batch`` without the telemetry samples a newer one of the same drone follows; how many.

    Telemetry is latest-value: a receiver that fell behind decodes only each
    drone's newest sample.  Everything else stays, in order: control messages
    never wait behind a backlog of samples.
    """
    if len(batch) < 2:
        return batch, 0  # the usual batch (one message): nothing can be newer
    newest = {frames[0]: i for i, frames in enumerate(batch) if frames[0][:3] == b"tm/"}
    kept = [f for i, f in enumerate(batch) if f[0][:3] != b"tm/" or newest[f[0]] == i]
    return kept, len(batch) - len(kept)


#: The most messages one socket gives per turn (others are not starved by a flood).
READ_BATCH = 256


def read_batch(sub: zmq.Socket[Any], limit: int = READ_BATCH) -> list[list[bytes]]:
    """The multipart messages waiting on ``sub``, at most ``limit``.

    Bounded so that a stop or subscribe command, or another peer, is not
    starved by a flood.  ``ZMQ_EVENTS`` says when the socket is empty: cheaper
    than the exception a read of an empty socket raises.
    """
    batch: list[list[bytes]] = []
    for _ in range(limit):
        try:
            batch.append(recv_message(sub))
        except zmq.Again:
            break
        if not sub.getsockopt(EVENTS_OPT) & POLLIN_BIT:  # type: ignore[operator]
            break
    return batch


class ReceiveLedger:
    """What became of the messages one In-Bridge received: the counts, and their log lines.

    Each message taken off a socket ends one way: delivered (:attr:`received`),
    on a topic that only shares a prefix with a subscription (:attr:`ignored`),
    skipped undecoded for a newer telemetry sample (:attr:`superseded`),
    dropped for a reason (:attr:`dropped`, :attr:`dropped_by_reason`), or
    raising, in filtering or decoding (:attr:`message_errors`) or in the
    consumer (:attr:`callback_errors`).  Kept apart from the receive loop so
    that each outcome is counted and logged in one place, by one rule: the
    first :data:`~eamos.net.sockets.LOG_FIRST` and then every
    :data:`~eamos.net.sockets.LOG_EVERY`-th, so a flood of bad messages
    cannot flood the log.

    Written only by the receive thread; its plain ints are safe to read elsewhere.
    """

    def __init__(self, log: EventLog) -> None:
        self._log = log
        self.received = 0
        self.dropped = 0
        self.dropped_by_reason: dict[str, int] = {}
        self.ignored = 0
        self.superseded = 0
        self.callback_errors = 0
        self.message_errors = 0

    def drop(self, reason: str, topic: bytes, detail: str, **extra: Any) -> None:
        """A message refused for ``reason`` (``net.in.drop``)."""
        self.dropped += 1
        self.dropped_by_reason[reason] = self.dropped_by_reason.get(reason, 0) + 1
        if should_log(self.dropped):
            self._log.warning(
                "net.in.drop",
                reason=reason,
                topic=topic.decode("utf-8", "replace"),
                detail=detail,
                dropped=self.dropped,
                **extra,
            )

    def message_failed(self, exc: BaseException, frames: list[bytes], peer: str) -> None:
        """Filtering or decoding ``frames`` from ``peer`` raised (``net.in.message_error``)."""
        self.message_errors += 1
        if should_log(self.message_errors):
            self._log.error(
                "net.in.message_error",
                error=f"{type(exc).__name__}: {exc}"[:300],
                topic=frames[0][:64].decode("utf-8", "replace") if frames else "",
                peer=peer,
                errors=self.message_errors,
                exc_info=exc,
            )

    def stalled(self, seconds: float, on_stall: Callable[[float], None] | None) -> None:
        """A turn of the receive thread took ``seconds`` (more than
        :data:`~eamos.net.receive_host.STALL_S`): told to ``on_stall``, for what peers
        sent meanwhile waited unread, which is not their silence."""
        if on_stall is not None:
            try:
                on_stall(seconds)
            except BaseException as exc:  # a consumer's failure is its own
                self.consumer_failed(exc, type="stall")

    def consumer_failed(self, exc: BaseException, **fields: Any) -> None:
        """The consumer's callback raised ``exc`` (``net.in.callback_error``)."""
        self.callback_errors += 1
        if should_log(self.callback_errors):
            self._log.error(
                "net.in.callback_error",
                error=f"{type(exc).__name__}: {exc}"[:300],
                errors=self.callback_errors,
                exc_info=exc,
                **fields,
            )


def peer_options(
    sub: zmq.Socket[Any], hwm: int, heartbeat_ms: int, curve: tuple[FleetKeys, str] | None
) -> None:
    """Set up ``sub``, an In-Bridge's socket to one peer (``curve``: the keys, the peer)."""
    sub.setsockopt(zmq.LINGER, 0)
    sub.setsockopt(zmq.RCVHWM, hwm)
    # ZeroMQ refuses (and disconnects) peers sending frames larger than this before
    # buffering them: the memory bound.  Oversized messages below it are dropped by
    # decode with the connection kept.
    sub.setsockopt(zmq.MAXMSGSIZE, MAX_FRAME_BYTES)
    connection_options(sub, heartbeat_ms, CONNECTING_PING_FACTOR)
    if curve is not None:
        keys, peer = curve
        curve_client(sub, keys, keys.fleet[peer])


class Admission:
    """Which received messages are this participant's: its topics, its mission, their sender.

    Topics are matched exactly (ZeroMQ's prefix matching would deliver ``to/D10``
    to a subscriber of ``to/D1``); a topic ending in ``/`` (or empty) is a
    deliberate prefix.  Every message turned away is counted in ``ledger``.
    Used on the receive thread only (before it starts, by the bridge's caller).
    """

    def __init__(self, mission: str, check_sender: bool, ledger: ReceiveLedger) -> None:
        self.mission = mission
        self._check_sender = check_sender
        self._ledger = ledger
        self._exact: set[bytes] = set()
        self._prefixes: set[bytes] = set()

    def subscribe(self, topic: bytes) -> None:
        """Take messages on ``topic`` too."""
        if topic == b"" or topic.endswith(b"/"):
            self._prefixes.add(topic)
        else:
            self._exact.add(topic)

    def admit(self, frames: list[bytes], peer: str) -> Message | None:
        """The message ``frames`` carry if it is for us (else None, counted and logged).

        Raises only what the decoder does beyond :class:`~eamos.net.wire.WireError`
        (a bug of ours: the caller counts it)."""
        topic = frames[0]
        if topic not in self._exact and not any(topic.startswith(p) for p in self._prefixes):
            self._ledger.ignored += 1
            return None
        try:
            msg = decode(frames)
        except WireError as exc:
            self._ledger.drop(exc.reason, topic, str(exc), peer=peer)
            return None
        if msg.mission != self.mission:
            self._ledger.drop("other_mission", topic, msg.mission, sender=msg.sender, peer=peer)
            return None
        if self._check_sender and msg.sender != peer:
            self._ledger.drop("sender", topic, f"{msg.sender!r} on {peer!r}'s link", peer=peer)
            return None
        return msg


class InBridge(Bridge):
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
    :attr:`dropped` and :attr:`dropped_by_reason` (the accounting of every
    message is a :class:`ReceiveLedger`).  ``on_batch_end`` is called
    on the receive thread after each batch of messages (the reliability layer
    acknowledges there, once per batch instead of once per message).

    No message stops the receive thread: whatever one message raises, in the
    decoder, the filters or ``on_message`` (any exception, ``SystemExit``
    included), is logged once (``net.in.message_error``, or
    ``net.in.callback_error`` for the consumer; the first
    :data:`~eamos.net.sockets.LOG_FIRST`, then every
    :data:`~eamos.net.sockets.LOG_EVERY`-th), counted in :attr:`message_errors`
    or :attr:`callback_errors`, and the thread goes on with the next message.

    A peer in ``announced`` is connected only once it announces itself
    (:meth:`announce`: it subscribed to this participant's Out-Bridge, so it
    listens), not retried while it is not up yet (:mod:`eamos.net.reconnect`).

    One socket per peer (rather than one for all) is what lets a CURVE client
    know each peer's public key, and lets the bridge know which peer a message
    came from.

    A connection that libzmq drops for a protocol error (a frame over
    :data:`~eamos.net.sockets.MAX_FRAME_BYTES`, a failed handshake) is not
    reconnected by libzmq; the bridge reconnects the peer's socket itself
    (``net.in.reconnect``) when libzmq has not started its own retry within
    :data:`~eamos.net.reconnect.RECONNECT_GRACE_S`, and then at most every
    :data:`~eamos.net.reconnect.OWN_RECONNECT_EVERY_S`, so one bad message never
    cuts a peer off for good.
    """

    def __init__(
        self,
        context: zmq.Context[Any],
        connect: Mapping[str, str],
        subscribe: Iterable[bytes],
        on_message: Callable[[Message], None],
        mission: str,
        log: EventLog | None = None,
        *,
        hwm: int = DEFAULT_HWM,
        curve: FleetKeys | None = None,
        check_sender: bool = False,
        heartbeat_ms: int = DEFAULT_HEARTBEAT_MS,
        on_batch_end: Callable[[], None] | None = None,
        announced: Iterable[str] = (),
        on_stall: Callable[[float], None] | None = None,
        host: ReceiveHost | None = None,
    ) -> None:
        self.mission = mission
        self._on_stall = on_stall
        self.peers: dict[str, str] = dict(connect)
        self.secure = curve is not None
        self._on_message = on_message
        self._on_batch_end = on_batch_end
        self._log = log if log is not None else make_logger(None)
        if curve is not None:
            missing = curve.missing(self.peers)
            if missing:
                raise ValueError(f"no public key for peer(s) {', '.join(missing)}")
        self._subs: dict[zmq.Socket[Any], str] = {}
        self._monitors: dict[zmq.Socket[Any], Monitor] = {}  # by the monitor's socket
        self._reconnector = Reconnector(self.peers, self._log)
        # Owned by the receive thread once started; before that, by the caller
        # under _lock (the thread start is the hand-over).
        self._ledger = ReceiveLedger(self._log)
        self._admission = Admission(mission, check_sender, self._ledger)
        topics = list(subscribe)
        wait_for = set(announced)
        try:
            for peer in self.peers:
                sub = context.socket(zmq.SUB)
                self._subs[sub] = peer
                self._reconnector.sockets[peer] = sub
                peer_options(sub, hwm, heartbeat_ms, None if curve is None else (curve, peer))
                monitor = Monitor(
                    sub,
                    self._log,
                    peer,
                    on_disconnect=self._reconnector.disconnected(peer),
                    on_retry=self._reconnector.retrying(peer),
                )
                self._monitors[monitor.socket] = monitor
                self._reconnector.connect(peer, announced=peer not in wait_for)
            for topic in topics:
                self._subscribe(topic)
        except zmq.ZMQError:
            # A bad endpoint must not leak sockets (and block Context.term).
            self._close_sockets()
            raise
        # The process's receive thread, or one of the bridge's own (module doc of
        # eamos.net.receive_host).
        self._own_host = host is None
        self._host = host if host is not None else ReceiveHost(context, "eamos-inbridge")
        self._lock = threading.Lock()  # guards the lifecycle flags
        self._started = False
        self._closed = False
        self._ended = threading.Event()  # its sockets are closed

    def _close_sockets(self) -> None:
        # Monitors first: a monitor stops only while its socket is open (Monitor.close).
        for monitor in self._monitors.values():
            monitor.close()
        for sock in self._subs:
            sock.close(linger=0)

    # -- lifecycle ---------------------------------------------------------

    def start(self) -> None:
        """Have its sockets read (by its receive thread); a no-op if started,
        RuntimeError once closed or when the receive thread has ended."""
        with self._lock:
            if self._closed:
                raise RuntimeError("InBridge is closed")
            if self._started:
                return
            self._started = True
            if not self._host.add(self):
                self._closed = True
                self.ended()
                raise RuntimeError("InBridge: its receive thread has ended")

    def close(self) -> None:
        """Stop reading and close the sockets; idempotent and safe from any thread.

        Requests made before ``close()`` are carried out first.  May be called from
        the bridge's own callbacks: the sockets then close after the turn (nothing
        more is delivered meanwhile).
        """
        with self._lock:
            if self._closed:
                return
            self._closed = True
            if not self._started:
                self.ended()  # the receive thread never saw its sockets
                if self._own_host:
                    self._host.stop()
                return
            self._host.remove(self, self._ended)
        if self._own_host:
            self._host.stop()
        if self._host.on_its_thread():
            return  # from a callback: it leaves at the start of the next turn
        if not self._ended.wait(JOIN_TIMEOUT_S):
            self._log.warning("net.in.close_timeout")

    def wait_ended(self, timeout_s: float) -> bool:
        """Wait until its sockets are closed (after :meth:`close`); whether they are."""
        return self._ended.wait(timeout_s)

    # -- subscriptions -----------------------------------------------------

    def add_subscription(self, topic: bytes) -> bool:
        """Also receive ``topic``; safe from any thread.  False if closed."""
        with self._lock:
            if self._closed:
                return False
            if not self._started:
                self._subscribe(topic)
                return True
            return self._host.call(self, lambda: self._on_thread(self._subscribe, topic))

    def announce(self, peer: str) -> None:
        """``peer`` listens now: connect to it if it is one of ``announced``; any thread."""
        with self._lock:
            if self._closed:
                return
            if not self._started:
                self._reconnector.announced(peer)
            else:
                self._host.call(self, lambda: self._on_thread(self._reconnector.announced, peer))

    def _on_thread(self, request: Callable[[Any], None], arg: Any) -> None:
        # A socket connected or subscribed raises no signal for what that brings at
        # once: every one is looked at again (eamos.net.readiness).
        request(arg)
        for sub in self._subs:
            self._host.again(sub)

    @property
    def unannounced(self) -> frozenset[str]:
        """The ``announced`` peers not connected yet (they have not subscribed to us)."""
        with self._lock:
            return self._reconnector.unannounced

    def _subscribe(self, topic: bytes) -> None:
        for sub in self._subs:
            sub.setsockopt(zmq.SUBSCRIBE, topic)
        self._admission.subscribe(topic)

    # -- counters ----------------------------------------------------------

    @property
    def reconnects(self) -> int:
        """How many times the bridge reconnected a peer's socket itself."""
        return self._reconnector.reconnects

    @property
    def received(self) -> int:
        """Messages passed to ``on_message``."""
        return self._ledger.received

    @property
    def dropped(self) -> int:
        """Messages dropped (malformed, other version or mission, wrong sender)."""
        return self._ledger.dropped

    @property
    def dropped_by_reason(self) -> dict[str, int]:
        """:attr:`dropped` per reason (a copy)."""
        return dict(self._ledger.dropped_by_reason)

    @property
    def superseded(self) -> int:
        """Telemetry samples skipped undecoded: a newer one of the same drone was waiting."""
        return self._ledger.superseded

    @property
    def ignored(self) -> int:
        """Messages on topics that only share a prefix with a subscription."""
        return self._ledger.ignored

    @property
    def callback_errors(self) -> int:
        """Calls of ``on_message`` (or ``on_batch_end``) that raised."""
        return self._ledger.callback_errors

    @property
    def message_errors(self) -> int:
        """Messages whose filtering or decoding raised something unexpected (not a drop)."""
        return self._ledger.message_errors

    @property
    def alive(self) -> bool:
        """Whether its sockets are read (started, not closed, and its thread runs)."""
        return self._started and not self._ended.is_set() and self._host.alive

    @property
    def auth_failures(self) -> int:
        """Handshakes with peers that failed (e.g. an impostor at a peer's address)."""
        return sum(m.failures for m in self._monitors.values())

    # -- on the receive thread (eamos.net.receive_host.ReceiveMember) --------

    @property
    def log(self) -> EventLog:
        """The bridge's log."""
        return self._log

    def sockets(self) -> list[zmq.Socket[Any]]:
        """Its sockets to watch: the peers' SUB sockets and their monitors."""
        return [*self._subs, *self._monitors]

    def next_due(self) -> float | None:
        """When a reconnect it owes is due (None: none)."""
        return self._reconnector.next_due()

    def turn(self, ready: list[zmq.Socket[Any]], host: ReceiveHost) -> None:
        """Read its sockets in ``ready``, reconnect the peers due; then ``on_batch_end``."""
        for again in self._reconnector.reconnect_due():
            host.again(self._reconnector.sockets[again])
        delivered = False
        for sock in ready:
            if self._closed:
                return  # close() was called from on_message: deliver nothing more
            peer = self._subs.get(sock)
            if peer is not None:
                drained, more = self._drain_sub(sock, peer)
                delivered = drained or delivered
                if more:
                    host.again(sock)
            else:
                self._monitors[sock].drain()
        if delivered and self._on_batch_end is not None and not self._closed:
            try:
                self._on_batch_end()
            except BaseException as exc:  # see _handle
                self._ledger.consumer_failed(exc, type="batch_end")

    def stalled(self, seconds: float) -> None:
        """A turn of its receive thread took ``seconds``: told to ``on_stall``."""
        self._ledger.stalled(seconds, self._on_stall)

    def ended(self) -> None:
        """Close its sockets (it left its receive thread, or never joined one); once."""
        if not self._ended.is_set():
            self._close_sockets()
            self._ended.set()

    def _drain_sub(self, sub: zmq.Socket[Any], peer: str) -> tuple[bool, bool]:
        """Read a batch of ``sub``: whether it held any, and whether more may wait."""
        batch = read_batch(sub)
        kept, skipped = latest_telemetry(batch)
        self._ledger.superseded += skipped
        for frames in kept:
            if self._closed:
                break  # close() was called from on_message: deliver nothing more
            self._handle(frames, peer)
        return bool(batch), len(batch) >= READ_BATCH

    def _handle(self, frames: list[bytes], peer: str = "") -> None:
        """Filter, decode and deliver one received multipart message from ``peer``.

        Never raises: one message must not stop the receive thread, which would
        cut this participant off from the mission for good.  A ``SystemExit`` or
        ``KeyboardInterrupt`` raised on this thread (by a consumer's bug) is no
        request to stop it either: the process's own signals reach its main thread.
        """
        try:
            msg = self._admission.admit(frames, peer)
        except BaseException as exc:  # any exception of one message
            self._ledger.message_failed(exc, frames, peer)
            return
        if msg is None:
            return
        self._ledger.received += 1
        try:
            self._on_message(msg)
        except BaseException as exc:  # a consumer's failure is its own
            self._ledger.consumer_failed(exc, type=type(msg).__name__, sender=msg.sender)
