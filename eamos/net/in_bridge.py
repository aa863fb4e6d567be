"""The In-Bridge: a participant's SUB sockets, one per peer, and their receive thread.

See :mod:`eamos.net.bridges` for the threading model, the lifecycle and security.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Iterable, Mapping
from typing import TYPE_CHECKING, Any

import zmq

from eamos.logs import EventLog, make_logger
from eamos.net.readiness import SocketWatch
from eamos.net.reconnect import Reconnector
from eamos.net.sockets import (
    CMD_CONNECT,
    CMD_STOP,
    CMD_SUB,
    CONNECTING_PING_FACTOR,
    DEFAULT_HEARTBEAT_MS,
    DEFAULT_HWM,
    EVENTS_OPT,
    MAX_FRAME_BYTES,
    POLLIN_BIT,
    BridgeThread,
    Monitor,
    connection_options,
    control_pair,
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


#: A turn of the receive loop longer than this is reported (``on_stall``): far above a
#: turn's usual length, and below the link's own stall threshold.
STALL_S = 0.05

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

    def turn_took(self, seconds: float, on_stall: Callable[[float], None] | None) -> None:
        """A turn of the receive loop took ``seconds``: told to ``on_stall`` when that is
        long (:data:`STALL_S`): what peers sent meanwhile waited unread, not their silence."""
        if seconds > STALL_S and on_stall is not None:
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


class InBridge(BridgeThread):
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
    ) -> None:
        self.mission = mission
        self._on_stall = on_stall
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
        self._monitors: list[Monitor] = []
        self._reconnector = Reconnector(self.peers, self._log)
        self._ctrl_rx, self._ctrl_tx = control_pair(context, "in")
        # Owned by the receive thread once started; before that, by the caller
        # under _lock (the thread start is the hand-over).
        self._exact: set[bytes] = set()
        self._prefixes: set[bytes] = set()
        topics = list(subscribe)
        wait_for = set(announced)
        try:
            for peer in self.peers:
                sub = context.socket(zmq.SUB)
                self._subs[sub] = peer
                self._reconnector.sockets[peer] = sub
                sub.setsockopt(zmq.LINGER, 0)
                sub.setsockopt(zmq.RCVHWM, hwm)
                # ZeroMQ refuses (and disconnects) peers sending frames larger than
                # this before buffering them: the memory bound.  Oversized messages
                # below it are dropped by decode with the connection kept.
                sub.setsockopt(zmq.MAXMSGSIZE, MAX_FRAME_BYTES)
                connection_options(sub, heartbeat_ms, CONNECTING_PING_FACTOR)
                if curve is not None:
                    curve_client(sub, curve, curve.fleet[peer])
                monitor = Monitor(
                    sub,
                    self._log,
                    peer,
                    on_disconnect=self._reconnector.disconnected(peer),
                    on_retry=self._reconnector.retrying(peer),
                )
                self._monitors.append(monitor)
                self._reconnector.connect(peer, announced=peer not in wait_for)
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
        self._ledger = ReceiveLedger(self._log)
        self._thread = threading.Thread(target=self._run, name="eamos-inbridge", daemon=True)

    def _close_sockets(self) -> None:
        for monitor in self._monitors:
            monitor.close()
        for sock in (*self._subs, self._ctrl_rx, self._ctrl_tx):
            sock.close(linger=0)

    # -- lifecycle ---------------------------------------------------------

    def _close_timeout(self) -> None:
        self._log.warning("net.in.close_timeout")

    # -- subscriptions -----------------------------------------------------

    def add_subscription(self, topic: bytes) -> bool:
        """Also receive ``topic``; safe from any thread.  False if closed."""
        with self._lock:
            if self._closed or not self._tx_open:
                return False
            if not self._started:
                self._subscribe(topic)
            else:
                self._ctrl_tx.send_multipart([CMD_SUB, topic])
        return True

    def announce(self, peer: str) -> None:
        """``peer`` listens now: connect to it if it is one of ``announced``; any thread."""
        with self._lock:
            if self._closed or not self._tx_open:
                return
            if not self._started:
                self._reconnector.announced(peer)
            else:
                self._ctrl_tx.send_multipart([CMD_CONNECT, peer.encode("utf-8")])

    @property
    def unannounced(self) -> frozenset[str]:
        """The ``announced`` peers not connected yet (they have not subscribed to us)."""
        with self._lock:
            return self._reconnector.unannounced

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
        """Whether the receive thread runs (started and not stopped)."""
        return self._thread.is_alive()

    @property
    def auth_failures(self) -> int:
        """Handshakes with peers that failed (e.g. an impostor at a peer's address)."""
        return sum(m.failures for m in self._monitors)

    # -- receive thread ----------------------------------------------------

    def _run(self) -> None:
        ctrl = self._ctrl_rx
        subs = self._subs
        monitors = {m.socket: m for m in self._monitors}
        # Woken by the sockets that are ready, not by a walk over all of them: a fan-in
        # endpoint watches two sockets per peer (SocketWatch).
        watch = SocketWatch()
        for sock in (ctrl, *subs, *monitors):
            watch.add(sock)
        reconnector = self._reconnector
        try:
            while True:
                timeout = reconnector.poll_timeout_ms()
                ready = watch.wait(None if timeout is None else timeout / 1000)
                turn_began = time.monotonic()
                # A socket this thread connects or subscribes raises no signal for
                # what that brings at once: it is looked at again (SocketWatch).
                if ctrl in ready:
                    if not self._drain_control():
                        return
                    for sub in subs:
                        watch.again(sub)
                for again in reconnector.reconnect_due():
                    watch.again(reconnector.sockets[again])
                delivered = False
                for sock in ready:
                    peer = subs.get(sock)
                    if peer is not None:
                        drained, more = self._drain_sub(sock, peer)
                        delivered = drained or delivered
                        if more:
                            watch.again(sock)
                    elif sock is not ctrl:
                        monitors[sock].drain()
                if self._closed:
                    return  # close() was called from on_message
                if delivered and self._on_batch_end is not None:
                    try:
                        self._on_batch_end()
                    except BaseException as exc:  # see _handle
                        self._ledger.consumer_failed(exc, type="batch_end")
                self._ledger.turn_took(time.monotonic() - turn_began, self._on_stall)
        except zmq.ContextTerminated:
            self._log.warning("net.in.context_terminated")
        except zmq.ZMQError:
            self._log.exception("net.in.thread_error")
        finally:
            watch.close()
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
            if frames[0] == CMD_STOP:
                return False
            if frames[0] == CMD_SUB:
                self._subscribe(frames[1])
            elif frames[0] == CMD_CONNECT:
                self._reconnector.announced(frames[1].decode("utf-8"))

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
            msg = self._accepted(frames, peer)
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

    def _accepted(self, frames: list[bytes], peer: str) -> Message | None:
        """The message ``frames`` carry if it is for us (else None, counted and logged)."""
        if not self._wanted(frames[0]):
            self._ledger.ignored += 1
            return None
        try:
            msg = decode(frames)
        except WireError as exc:
            self._ledger.drop(exc.reason, frames[0], str(exc), peer=peer)
            return None
        if msg.mission != self.mission:
            self._ledger.drop("other_mission", frames[0], msg.mission, sender=msg.sender, peer=peer)
            return None
        if self._check_sender and msg.sender != peer:
            self._ledger.drop("sender", frames[0], f"{msg.sender!r} on {peer!r}'s link", peer=peer)
            return None
        return msg
