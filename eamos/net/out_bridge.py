"""The Out-Bridge: a participant's one bound XPUB socket, written by any thread under a lock.

See :mod:`eamos.net.bridges` for the threading model, the lifecycle and security.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Iterable
from typing import TYPE_CHECKING, Any

import zmq

from eamos.logs import EventLog, make_logger
from eamos.net.descriptors import connection_budget
from eamos.net.sockets import (
    BOUND_HEARTBEAT_FACTOR,
    CMD_STOP,
    CMD_WAKE,
    DEFAULT_HEARTBEAT_MS,
    DEFAULT_HWM,
    DEFAULT_LINGER_MS,
    EVENTS_OPT,
    POLLIN_BIT,
    BridgeThread,
    Monitor,
    connection_options,
    control_pair,
    curve_server,
    send_message,
)
from eamos.net.wire import Message, encode

if TYPE_CHECKING:
    from eamos.net.keys import FleetKeys

__all__ = ["FLOOD_PAUSE_S", "OutBridge"]

FLOOD_PAUSE_S = 1.0
"""How long the Out-Bridge stops listening when its connections reach the budget."""


class OutBridge(BridgeThread):
    """The participant's outgoing side: one bound XPUB socket, fed by any thread.

    ``bind`` is a ZeroMQ endpoint such as ``tcp://127.0.0.1:6001``; port 0
    (``tcp://127.0.0.1:0``, ``tcp://*:0``) picks a free port, and the actual
    endpoint is available as :attr:`endpoint`.

    Connections are accepted before they authenticate, each holding a
    descriptor.  Should the accepted connections reach ``budget`` (default
    :func:`~eamos.net.descriptors.connection_budget`: the descriptor limit less
    a reserve for the node's own files), the bridge stops listening for
    :data:`FLOOD_PAUSE_S` (``net.out.flooded``): unbinding closes every
    accepted connection and frees their descriptors; the fleet's peers
    reconnect when it listens again, and what they missed is resent.
    """

    def __init__(
        self,
        context: zmq.Context[Any],
        bind: str,
        log: EventLog | None = None,
        *,
        hwm: int = DEFAULT_HWM,
        linger_ms: int = DEFAULT_LINGER_MS,
        curve: FleetKeys | None = None,
        heartbeat_ms: int = DEFAULT_HEARTBEAT_MS,
        on_subscription: Callable[[bytes, bool], None] | None = None,
        budget: int | None = None,
    ) -> None:
        self._log = log if log is not None else make_logger(None)
        self._budget = connection_budget() if budget is None else budget
        self._paused_until: float | None = None
        self.pauses = 0
        self._on_subscription = on_subscription
        self.secure = curve is not None
        self._xpub = context.socket(zmq.XPUB)
        self._xpub.setsockopt(zmq.LINGER, linger_ms)
        self._xpub.setsockopt(zmq.SNDHWM, hwm)
        # VERBOSE: pass every subscription up, not only the first per topic, so a
        # peer that reconnects (or a second peer) is seen too.
        self._xpub.setsockopt(zmq.XPUB_VERBOSE, 1)
        connection_options(self._xpub, heartbeat_ms * BOUND_HEARTBEAT_FACTOR)
        self._monitor: Monitor | None = None
        try:
            if curve is not None:
                curve_server(self._xpub, curve)
            self._monitor = Monitor(self._xpub, self._log, "*")
            self._xpub.bind(bind)
        except zmq.ZMQError:
            if self._monitor is not None:
                self._monitor.close()
            self._xpub.close(linger=0)
            raise
        self.endpoint: str = self._xpub.getsockopt(zmq.LAST_ENDPOINT).decode()
        self._ctrl_rx, self._ctrl_tx = control_pair(context, "out")

        # _lock guards every use of _xpub (senders write to it directly, the
        # bridge thread reads subscriptions and rebinds it: ZeroMQ allows a
        # socket to change threads behind a full memory barrier, which the lock
        # is), _ctrl_tx, the lifecycle flags and the send counters.
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

    def _on_start(self) -> None:
        with self._cond:
            self._running = True

    def _close_sockets(self) -> None:
        self._ctrl_tx.close()
        self._ctrl_rx.close()
        if self._monitor is not None:
            self._monitor.close()
        self._xpub.close()

    def _close_timeout(self) -> None:
        self._log.warning("net.out.close_timeout", endpoint=self.endpoint)

    # -- sending -----------------------------------------------------------

    def send(self, msg: Message) -> bool:
        """Publish ``msg``; thread-safe and non-blocking.

        The calling thread writes to the XPUB socket itself, under the bridge's
        lock (no hand-over to the bridge thread: that cost every message a
        context switch).  Returns False (and logs) if the bridge is closed.
        Raises :class:`~eamos.net.wire.WireError` if ``msg`` cannot be encoded.
        Messages sent before :meth:`start` go out too (the socket is bound).
        """
        frames = encode(msg)
        return self.send_frames(frames, type(msg).__name__)

    def send_frames(self, frames: list[bytes], name: str = "raw") -> bool:
        """Publish already encoded ``frames`` (``[topic, payload]``, or any multipart message
        a test sends raw), counted under ``name``."""
        with self._lock:
            if self._closed or not self._tx_open:
                self._log.info("net.out.send_after_close", type=name)
                return False
            # XPUB never blocks: it drops for a peer whose queue is at the HWM
            # (hence the large HWM).
            send_message(self._xpub, frames)
            # The send may have consumed the socket's wake-up signal (ZMQ_FD is
            # edge-triggered) with a subscription waiting: hand it to the thread.
            if self._started and self._xpub.getsockopt(EVENTS_OPT) & POLLIN_BIT:
                self._ctrl_tx.send(CMD_WAKE)
            size = sum(len(frame) for frame in frames)  # raw frames may be any number
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
        # The socket's own descriptor, not the socket: polling a descriptor is
        # safe while other threads send; what it signals is read under the lock.
        with self._lock:
            xpub_fd = self._xpub.getsockopt(zmq.FD)
        poller.register(xpub_fd, zmq.POLLIN)
        monitor = self._monitor
        if monitor is not None:
            poller.register(monitor.socket, zmq.POLLIN)
        try:
            while True:
                self._read_subscriptions()
                events = dict(poller.poll(self._poll_timeout_ms()))
                if monitor is not None and monitor.socket in events:
                    monitor.drain()
                if monitor is not None:
                    self._guard(monitor)
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
                if monitor is not None:
                    monitor.close()  # before its socket (see Monitor.close)
                self._xpub.close()
            self._ctrl_rx.close()
            with self._cond:
                self._running = False
                self._cond.notify_all()

    # -- descriptor guard (bridge thread) -----------------------------------

    def _poll_timeout_ms(self) -> int | None:
        if self._paused_until is None:
            return None
        return max(0, int((self._paused_until - time.monotonic()) * 1e3) + 1)

    def _guard(self, monitor: Monitor) -> None:
        """Stop listening while flooded with connections; listen again after a pause."""
        now = time.monotonic()
        if self._paused_until is None:
            if len(monitor.accepted) < self._budget:
                return
            self.pauses += 1
            self._log.warning(
                "net.out.flooded",
                endpoint=self.endpoint,
                connections=len(monitor.accepted),
                budget=self._budget,
                pause_s=FLOOD_PAUSE_S,
                count=self.pauses,
            )
            with self._lock:
                self._xpub.unbind(self.endpoint)  # closes every accepted connection
            monitor.accepted.clear()
            self._paused_until = now + FLOOD_PAUSE_S
        elif now >= self._paused_until:
            try:
                with self._lock:
                    self._xpub.bind(self.endpoint)
            except zmq.ZMQError as exc:
                self._log.warning("net.out.rebind_failed", endpoint=self.endpoint, error=str(exc))
                self._paused_until = now + FLOOD_PAUSE_S
                return
            self._paused_until = None
            self._log.info("net.out.listening", endpoint=self.endpoint)

    def _drain_control(self) -> bool:
        """Read every queued command (wake-ups); False once the stop command is seen."""
        while True:
            try:
                frames = self._ctrl_rx.recv_multipart(zmq.NOBLOCK)
            except zmq.Again:
                return True
            if frames[0] == CMD_STOP:
                return False

    def _read_subscriptions(self) -> None:
        frames: list[bytes] = []
        with self._lock:
            if not self._tx_open:
                return
            # ZMQ_EVENTS also re-arms the descriptor the thread polls.
            while self._xpub.getsockopt(EVENTS_OPT) & POLLIN_BIT:
                try:
                    frames.append(self._xpub.recv(zmq.NOBLOCK))
                except zmq.Again:
                    break
        changed: list[tuple[bytes, bool]] = []
        for frame in frames:
            if not frame or frame[0] not in (0, 1):
                continue  # not a (un)subscription frame; SUB peers send nothing else
            changed.append((frame[1:], frame[0] == 1))
            self._log.debug(
                "net.out.subscription", topic=frame[1:].decode("utf-8", "replace"), on=frame[0] == 1
            )
        if not changed:
            return
        # The callbacks first (without the lock: they send; the lock order is link, then
        # bridge), and only then is a waiter told: a drone waiting for its peers to
        # subscribe sends Ready after the callback resent what the socket had dropped,
        # not before it (which made the callback resend the Ready itself).
        if self._on_subscription is not None:
            for topic, on in changed:
                try:
                    self._on_subscription(topic, on)
                except Exception:  # the bridge thread must survive its callback
                    self._log.exception("net.out.callback_error")
        with self._cond:
            for topic, on in changed:
                if on:
                    self._subscriptions.add(topic)
                else:
                    # Without XPUB_VERBOSER, an unsubscribe only arrives once the
                    # last subscriber of this topic is gone.
                    self._subscriptions.discard(topic)
            self._cond.notify_all()
