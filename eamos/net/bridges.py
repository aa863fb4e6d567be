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

Seam for the reliability/security issue
---------------------------------------
Messages become bytes only in :func:`~eamos.net.wire.encode` and
:func:`~eamos.net.wire.decode`; frames touch the network only in
``OutBridge._forward`` and ``InBridge._handle``.  Acks, retransmission,
heartbeats and CURVE keys belong there (and in the socket set-up in the two
constructors), without changing the callers' API.
"""

from __future__ import annotations

import threading
import uuid
from collections.abc import Callable, Iterable, Mapping
from typing import Any, Final

import zmq

from eamos.logs import make_logger
from eamos.net.wire import MAX_PAYLOAD_BYTES, Message, WireError, decode, encode

__all__ = ["DEFAULT_HWM", "DEFAULT_LINGER_MS", "InBridge", "OutBridge"]

DEFAULT_HWM: Final = 100_000
"""Per-peer queue limit (messages).  ZeroMQ PUB sockets silently drop beyond it,
so it is set far above any burst a mission produces (the default 1000 is not)."""

DEFAULT_LINGER_MS: Final = 500
"""How long ``Context.term()`` may wait to flush messages after ``close()``."""

JOIN_TIMEOUT_S: Final = 5.0
"""Upper bound on how long ``close()`` waits for a bridge thread to finish."""

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
    ) -> None:
        self._log = log if log is not None else make_logger(None)
        self._xpub = context.socket(zmq.XPUB)
        self._xpub.setsockopt(zmq.LINGER, linger_ms)
        self._xpub.setsockopt(zmq.SNDHWM, hwm)
        # VERBOSE: pass every subscription up, not only the first per topic, so a
        # peer that reconnects (or a second peer) is seen too.
        self._xpub.setsockopt(zmq.XPUB_VERBOSE, 1)
        try:
            self._xpub.bind(bind)
        except zmq.ZMQError:
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
            self._sent_counts[name] = self._sent_counts.get(name, 0) + 1
            self._sent_bytes += len(frames[0]) + len(frames[1])
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
        try:
            while True:
                events = dict(poller.poll())
                if self._xpub in events:
                    self._read_subscriptions()
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
        changed = False
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
                changed = True
            self._log.debug(
                "net.out.subscription", topic=topic.decode("utf-8", "replace"), on=frame[0] == 1
            )
        if changed:
            with self._cond:
                self._cond.notify_all()


class InBridge:
    """The participant's incoming side: one SUB socket connected to its peers.

    ``connect`` maps peer names to their Out-Bridge endpoints; ``subscribe``
    lists the topics to receive (see :func:`~eamos.net.wire.topic_to`,
    :func:`~eamos.net.wire.topic_telemetry`, :data:`~eamos.net.wire.TOPIC_ALL`).
    Topics are matched exactly, because ZeroMQ's prefix matching would deliver
    ``to/D10`` to a subscriber of ``to/D1``; a topic ending in ``/`` (or empty)
    is a deliberate prefix subscription.

    Every message that decodes, whose topic was subscribed and whose mission is
    ``mission`` is passed to ``on_message`` on the receive thread.  Malformed
    messages and those of other missions are dropped, logged and counted in
    :attr:`dropped`.
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
    ) -> None:
        self.mission = mission
        self.peers: dict[str, str] = dict(connect)
        self._on_message = on_message
        self._log = log if log is not None else make_logger(None)
        self._sub = context.socket(zmq.SUB)
        self._sub.setsockopt(zmq.LINGER, 0)
        self._sub.setsockopt(zmq.RCVHWM, hwm)
        # ZeroMQ refuses (and disconnects) peers sending frames larger than any
        # valid message, before they are buffered in full.
        self._sub.setsockopt(zmq.MAXMSGSIZE, MAX_PAYLOAD_BYTES)
        self._ctrl_rx, self._ctrl_tx = _control_pair(context, "in")
        # Owned by the receive thread once started; before that, by the caller
        # under _lock (the thread start is the hand-over).
        self._exact: set[bytes] = set()
        self._prefixes: set[bytes] = set()
        try:
            for topic in subscribe:
                self._subscribe(topic)
            for endpoint in self.peers.values():
                self._sub.connect(endpoint)
        except zmq.ZMQError:
            # A bad endpoint must not leak three sockets (and block Context.term).
            for sock in (self._sub, self._ctrl_rx, self._ctrl_tx):
                sock.close(linger=0)
            raise

        self._lock = threading.Lock()  # guards _ctrl_tx and the lifecycle flags
        self._started = False
        self._closed = False
        self._tx_open = True
        # Written only by the receive thread; plain ints are safe to read elsewhere.
        self._received = 0
        self._dropped = 0
        self._ignored = 0
        self._callback_errors = 0
        self._thread = threading.Thread(target=self._run, name="eamos-inbridge", daemon=True)

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
                self._ctrl_tx.close()
                self._tx_open = False
                self._ctrl_rx.close()
                self._sub.close()
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
        self._sub.setsockopt(zmq.SUBSCRIBE, topic)
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
        """Messages dropped as malformed or belonging to another mission."""
        return self._dropped

    @property
    def ignored(self) -> int:
        """Messages on topics that only share a prefix with a subscription."""
        return self._ignored

    @property
    def callback_errors(self) -> int:
        """Calls of ``on_message`` that raised."""
        return self._callback_errors

    # -- receive thread ----------------------------------------------------

    def _run(self) -> None:
        poller = zmq.Poller()
        poller.register(self._ctrl_rx, zmq.POLLIN)
        poller.register(self._sub, zmq.POLLIN)
        try:
            while True:
                events = dict(poller.poll())
                if self._ctrl_rx in events and not self._drain_control():
                    return
                if self._sub in events:
                    self._drain_sub()
        except zmq.ContextTerminated:
            self._log.warning("net.in.context_terminated")
        except zmq.ZMQError:
            self._log.exception("net.in.thread_error")
        finally:
            with self._lock:
                self._ctrl_tx.close()
                self._tx_open = False
            self._ctrl_rx.close()
            self._sub.close()

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

    def _drain_sub(self) -> None:
        # Bounded batch so a stop or subscribe command is not starved by a flood.
        for _ in range(256):
            if self._closed:
                return  # close() was called from on_message: deliver nothing more
            try:
                frames = self._sub.recv_multipart(zmq.NOBLOCK)
            except zmq.Again:
                return
            self._handle(frames)

    def _handle(self, frames: list[bytes]) -> None:
        """Filter, decode and deliver one received multipart message."""
        if not self._wanted(frames[0]):
            self._ignored += 1
            return
        try:
            msg = decode(frames)
        except WireError as exc:
            self._drop("malformed", frames[0], str(exc))
            return
        if msg.mission != self.mission:
            self._drop("other_mission", frames[0], msg.mission, sender=msg.sender)
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
        if _should_log(self._dropped):
            self._log.warning(
                "net.in.drop",
                reason=reason,
                topic=topic.decode("utf-8", "replace"),
                detail=detail,
                dropped=self._dropped,
                **extra,
            )
