"""The link driver: runs the reliable-delivery protocol on threads, sockets and a clock.

:class:`~eamos.net.session.ReliableSession` is the protocol (sequence numbers,
acks, retransmission, duplicates and order, heartbeats, peer liveness,
latest-value telemetry; see :mod:`eamos.net.session`); it has no thread,
socket or clock.  :class:`LinkDriver` feeds it what happens and carries out
the actions it returns, and :class:`Link` is the driver on ZeroMQ (the
Out-/In-Bridges, CURVE with fleet keys), what a participant's runtime uses.

Threads: the In-Bridge's receive thread runs :meth:`LinkDriver._receive` and
the explicit acks at the end of each batch; the Out-Bridge's thread reports
(re)subscriptions; a timer thread per link
(:class:`~eamos.net.timers.LinkTimer`), or one for every link of a process
(:class:`~eamos.net.timers.TimerHost`), calls ``on_tick`` and then waits until
the session's next deadline (or until a send or a receive brings an earlier
one: a :class:`~eamos.net.session.Wake` action), never polling.  One lock serialises
every call into the session, and the wire messages it returns are handed to
the Out-Bridge under that lock, so a link's wire order is its seq order; the
application callback runs outside it.

Local events (never on the wire) are passed to ``on_message`` with the
messages: :class:`PeerStatus`, :class:`TelemetryStale` and :class:`TriggersAcknowledged`.

Neither thread stops for one message or one tick: an exception of the
application's callback is logged and counted (:attr:`LinkDriver.delivery_errors`),
and one of the timer's turn is logged and counted (:attr:`LinkDriver.timer_errors`),
after which the timer waits one heartbeat period and goes on (the In-Bridge
does the same for every received message: :class:`~eamos.net.in_bridge.InBridge`).
"""

from __future__ import annotations

import random
import threading
import time
from collections.abc import Callable, Iterable, Mapping
from typing import Any, Generic, TypeVar

import zmq

import eamos.net.wire as wire
from eamos.logs import EventLog, make_logger
from eamos.net.effects import (
    PeerChanged,
    PeerStatus,
    Send,
    SessionEffect,
    TelemetryStale,
    TriggersAcknowledged,
    Wake,
)
from eamos.net.in_bridge import InBridge
from eamos.net.keys import FleetAuthenticator, FleetKeys
from eamos.net.out_bridge import OutBridge
from eamos.net.receive_host import ReceiveHost
from eamos.net.reports import ReportJoiner
from eamos.net.session import ReliableSession
from eamos.net.settings import LinkSettings
from eamos.net.sockets import should_log
from eamos.net.timers import TimerHost, link_timer
from eamos.net.transport import InSide, OutSide, Transport, ZmqTransport
from eamos.net.zap import ZapHandler

__all__ = [
    "Delivered",
    "Link",
    "LinkDriver",
    "LinkSettings",
    "PeerStatus",
    "TelemetryStale",
    "TriggersAcknowledged",
]

OutT = TypeVar("OutT", bound=OutSide)
InT = TypeVar("InT", bound=InSide)

Clock = Callable[[], float]

#: What the link hands its participant: wire messages, and its local events.
Delivered = wire.Message | PeerStatus | TelemetryStale | TriggersAcknowledged


class LinkDriver(Generic[OutT, InT]):
    """Runs ``session`` over ``transport`` on threads, reading time from ``clock``.

    Build it (opens and starts the outgoing side), :meth:`connect` to the
    peers (incoming side, timer), :meth:`send` from any thread,
    :meth:`close` at the end.  ``out`` and ``inb`` are the transport's two sides.
    ``timers``: the process's shared timer thread (None: a thread of the link's own).
    """

    def __init__(
        self,
        session: ReliableSession,
        transport: Transport[OutT, InT],
        log: EventLog | None = None,
        *,
        clock: Clock = time.monotonic,
        timers: TimerHost | None = None,
    ) -> None:
        self.session = session
        self.name = session.name
        self.mission = session.mission
        self.settings = session.settings
        self.transport = transport
        self.log = log if log is not None else make_logger(None)
        self.clock = clock
        # One lock guards the session.  Two conditions on it: _cond for flush()
        # waiters, the timer's (see eamos.net.timers).
        lock = threading.RLock()
        self._cond = threading.Condition(lock)
        self._timer = link_timer(
            self, threading.Condition(lock), self.log, self.settings.heartbeat_s, timers
        )
        self._flush_waiters = 0
        self._on_message: Callable[[Delivered], None] = lambda msg: None
        self.delivery_errors = 0
        self.peer_events: list[dict[str, Any]] = []
        self._reports = ReportJoiner()  # ReportParts arrive on the receive thread only
        self.out: OutT = transport.open_out(self._on_subscription)
        self.inb: InT | None = None
        self._listening: set[str] = set()  # subscribed to us before connect()
        # Started after self.out is set: its thread reports subscriptions to us.
        self.out.start()

    @property
    def secure(self) -> bool:
        """Whether the links are encrypted and authenticated."""
        return self.transport.secure

    # -- set-up --------------------------------------------------------------------

    def connect(
        self,
        peers: Mapping[str, str],
        topics: Iterable[bytes],
        on_message: Callable[[Delivered], None],
        watch: Iterable[str] | None = None,
        announced: Iterable[str] = (),
    ) -> None:
        """Connect to ``peers`` (name -> endpoint), subscribe, start receiving and the timer.

        ``on_message`` receives every wire message exactly once, in order per
        sender, plus the local events :class:`PeerStatus` and
        :class:`TelemetryStale`; it runs on the receive or timer thread.
        ``watch`` names the peers whose heartbeats to follow (reported lost,
        back, left); default all.  Heartbeats cost every receiver a wake-up,
        so a drone watches only the peers it works with, while the ground
        station watches the whole fleet.  The peers in ``announced`` are
        connected when they subscribe to this participant (so they listen:
        no refused connection to retry), as the ground station does with the
        drones it waits for (:mod:`eamos.net.reconnect`).
        """
        names = [p for p in peers if p != self.name]
        watched = set(names) if watch is None else set(watch) & set(names)
        wanted = [wire.TOPIC_ALL, wire.topic_to(self.name)]
        wanted += [wire.topic_heartbeat(p) for p in sorted(watched)]
        wanted += [t for t in topics if t not in wanted]
        with self._cond:
            self._on_message = on_message
            self.session.add_peers(names, watched)
        with self._cond:  # a subscription read meanwhile waits for self.inb
            self.inb = self.transport.open_in(
                {p: e for p, e in peers.items() if p != self.name},
                wanted,
                self._receive,
                self._flush_acks,
                announced=[p for p in announced if p in names],
                on_stall=self._receive_stalled,
            )
            listening, self._listening = self._listening, set()
        for peer in listening:  # subscribed before the In-Bridge existed
            self.inb.announce(peer)
        self.inb.start()
        self._timer.start()

    def wait_subscribed(self, topics: Iterable[bytes], timeout_s: float) -> bool:
        """See :meth:`OutBridge.wait_subscribed`."""
        return self.out.wait_subscribed(topics, timeout_s)

    # -- carrying out the session's actions ----------------------------------------------

    def _execute(self, actions: list[SessionEffect]) -> tuple[bool, list[SessionEffect]]:
        """Send and schedule (lock held); return (every send accepted, what to deliver)."""
        ok = True
        later: list[SessionEffect] = []
        for action in actions:
            kind = type(action)
            if kind is Send:
                # Looked up each time: tests wrap ``out.send`` to lose messages.
                ok = self.out.send(action.message) and ok  # type: ignore[union-attr]
            elif kind is Wake:
                self._timer.kick(action.at)  # type: ignore[union-attr]
            else:
                if kind is PeerChanged:
                    status: PeerStatus = action.status  # type: ignore[union-attr]
                    self.peer_events.append(
                        {
                            "peer": status.sender,
                            "state": status.state,
                            "silent_s": status.silent_s,
                            "t": time.time(),  # a timestamp for the summary, not a timeout
                        }
                    )
                later.append(action)
        if self._flush_waiters:
            self._cond.notify_all()
        return ok, later

    def deliver(self, later: list[SessionEffect]) -> None:
        """Hand deliveries and peer events to the application (lock not held)."""
        for action in later:
            item = action.status if type(action) is PeerChanged else action.item  # type: ignore[union-attr]
            if type(item) is wire.ReportPart:
                # A report in parts reaches the application whole, as one Report.
                try:
                    item = self._reports.add(item)
                except wire.WireError as exc:
                    self.log.warning("net.report.parts_dropped", error=str(exc))
                    continue
                if item is None:
                    continue
            try:
                self._on_message(item)
            # A consumer's bug (whatever it raises, on this thread) must not cut
            # this participant off: logged, counted, and the next message goes on.
            except BaseException as exc:
                self.delivery_errors += 1
                if should_log(self.delivery_errors):
                    self.log.error(
                        "net.in.callback_error",
                        type=type(item).__name__,
                        error=f"{type(exc).__name__}: {exc}"[:300],
                        errors=self.delivery_errors,
                        exc_info=exc,
                    )

    # -- sending ------------------------------------------------------------------------

    def send(self, msg: wire.Message) -> bool:
        """Send ``msg``; reliable types get a sequence number and are retransmitted until acked.

        Thread-safe and non-blocking.  False if the link is closed.
        """
        now = self.clock()
        with self._cond:
            if self.session.closed:
                return False
            ok, _ = self._execute(self.session.on_send(msg, now))
            return ok

    def flush(self, timeout_s: float, peers: Iterable[str] | None = None) -> bool:
        """Wait until every reliable message sent so far was acknowledged (bounded).

        Only the links to ``peers`` if given; otherwise every link and the
        broadcasts.  Peers that left are not waited for.  Returns False on
        timeout.
        """
        only = None if peers is None else list(peers)
        with self._cond:
            self._flush_waiters += 1
            try:
                return self._cond.wait_for(lambda: self.session.flushed(only), timeout_s)
            finally:
                self._flush_waiters -= 1

    # -- receiving (In-/Out-Bridge threads) -------------------------------------------------

    def _receive(self, msg: wire.Message) -> None:
        now = self.clock()
        with self._cond:
            _, later = self._execute(self.session.on_receive(msg, now))
        if later:
            self.deliver(later)

    def _flush_acks(self) -> None:
        """In-Bridge batch end: the explicit Acks this batch called for (gaps, duplicates)."""
        now = self.clock()
        with self._cond:
            self._execute(self.session.on_batch_end(now))

    def _receive_stalled(self, stalled_s: float) -> None:
        """In-Bridge: one turn of its loop took ``stalled_s``
        (:meth:`~eamos.net.session.ReliableSession.on_receive_stall`)."""
        now = self.clock()
        with self._cond:
            self.session.on_receive_stall(stalled_s, now)

    def _on_subscription(self, topic: bytes, on: bool) -> None:
        # Out-Bridge thread: a peer (re)subscribed, e.g. after a reconnect.  What
        # it missed meanwhile was dropped by the XPUB socket: resend it now.
        if not on:
            return
        now = self.clock()
        with self._cond:
            self._execute(self.session.on_subscription(topic, now))
            inb = self.inb
            peer = _addressee(topic)
            if inb is None and peer:
                self._listening.add(peer)
        if inb is not None and peer:
            inb.announce(peer)  # a peer connected to us: it listens, connect to it

    # -- the timer's turn (eamos.net.timers) ------------------------------------------------

    @property
    def closed(self) -> bool:
        """Whether the link was closed (:meth:`close_receiving`)."""
        return self.session.closed

    def tick(self) -> tuple[list[SessionEffect], float]:
        """The session's tick carried out (lock held): what to deliver, the next deadline."""
        actions, deadline = self.session.on_tick(self.clock())
        _, later = self._execute(actions)
        return later, deadline

    @property
    def timer_errors(self) -> int:
        """Turns of the timer that raised (each logged, ``net.link.timer_error``)."""
        return self._timer.errors

    # -- results and shutdown ------------------------------------------------------------------

    @property
    def retransmissions(self) -> int:
        """Reliable messages sent again."""
        return self.session.counters.retransmissions

    @property
    def duplicates_dropped(self) -> int:
        """Reliable messages received again and dropped."""
        return self.session.counters.duplicates_dropped

    @property
    def reordered(self) -> int:
        """Reliable messages that arrived after a gap."""
        return self.session.counters.reordered

    @property
    def acks_sent(self) -> int:
        """Explicit Acks sent."""
        return self.session.counters.acks_sent

    @property
    def nacks_sent(self) -> int:
        """Acks sent that asked for a gap to be filled."""
        return self.session.counters.nacks_sent

    @property
    def acks_received(self) -> int:
        """Acknowledgements received (explicit or on heartbeats)."""
        return self.session.counters.acks_received

    @property
    def heartbeats_sent(self) -> int:
        """Heartbeats sent."""
        return self.session.counters.heartbeats_sent

    @property
    def old_telemetry(self) -> int:
        """Telemetry samples dropped for being older than one already seen."""
        return self.session.counters.old_telemetry

    @property
    def abandoned(self) -> int:
        """Unacknowledged messages given up because their peer left."""
        return self.session.counters.abandoned

    def stats(self) -> dict[str, Any]:
        """Counters for the run summary (``report()["net"]``)."""
        inb = self.inb
        with self._cond:
            c = self.session.counters
            dropped = dict(inb.dropped_by_reason) if inb is not None else {}
            if c.old_telemetry:
                dropped["old_telemetry"] = c.old_telemetry
            return {
                "secure": self.secure,
                "retransmissions": c.retransmissions,
                "duplicates_dropped": c.duplicates_dropped,
                "reordered": c.reordered,
                "acks_sent": c.acks_sent,
                "nacks_sent": c.nacks_sent,
                "acks_received": c.acks_received,
                "heartbeats_sent": c.heartbeats_sent,
                "late_ticks": c.late_ticks,
                "stalled_s": round(c.stalled_s, 3),
                "unacked": self.session.unacked(),
                "abandoned": c.abandoned,
                "dropped": dropped,
                "telemetry_superseded": int(getattr(inb, "superseded", 0)),
                # Messages (or turns) that raised and were skipped: each one logged.
                "receive_errors": int(getattr(inb, "message_errors", 0))
                + int(getattr(inb, "callback_errors", 0))
                + self.delivery_errors,
                "timer_errors": self.timer_errors,
                "auth_denied": self.transport.auth_denied,
                "auth_failures": self.out.auth_failures
                + (inb.auth_failures if inb is not None else 0),
                "peer_events": list(self.peer_events),
                "peers": self.session.peer_stats(),
                "messages_sent": self.out.sent_counts,
                "bytes_sent": self.out.sent_bytes,
                "bytes_sent_by_type": self.out.sent_bytes_by_type,
            }

    def close_receiving(self) -> None:
        """Say goodbye (a leaving heartbeat), stop the timer and the incoming side; idempotent.

        Nothing is delivered to ``on_message`` afterwards, and nothing more is
        sent (:meth:`send` returns False).
        """
        with self._cond:
            if not self.session.closed:
                self._execute(self.session.close())
                self._cond.notify_all()
                self._timer.wake_all()
        self._timer.join(5.0)
        if self.inb is not None:
            self.inb.close()

    def close(self) -> None:
        """:meth:`close_receiving`, then close the outgoing side and the transport; idempotent.

        The Out-Bridge hands what was sent before to its socket first; the
        socket's linger lets it leave before ``Context.term`` returns.
        """
        self.close_receiving()
        self.out.close()
        self.transport.close()


class Link(LinkDriver[OutBridge, InBridge]):
    """One participant's reliable, authenticated connection to the rest of the fleet.

    The driver on ZeroMQ: binds the Out-Bridge at ``bind`` on ``context``
    (with ``keys``, starting the ZAP authenticator first) and connects the
    In-Bridge in :meth:`connect`.  ``clock`` (default :func:`time.monotonic`)
    and ``rng`` (the retransmission jitter) are injectable, as is the
    ``transport`` (default :class:`~eamos.net.transport.ZmqTransport`).  ``zap``: the
    context's ZAP handler when participants share the context (else one of its own);
    ``timers``, ``receivers``: the process's link timer and receive threads when
    participants share them (else threads of the link's own).
    """

    def __init__(
        self,
        context: zmq.Context[Any],
        name: str,
        mission: str,
        bind: str,
        log: EventLog | None = None,
        *,
        keys: FleetKeys | None = None,
        settings: LinkSettings | None = None,
        transport: Transport[OutBridge, InBridge] | None = None,
        clock: Clock = time.monotonic,
        rng: random.Random | None = None,
        zap: ZapHandler | None = None,
        timers: TimerHost | None = None,
        receivers: ReceiveHost | None = None,
    ) -> None:
        settings = settings or LinkSettings()
        log = log if log is not None else make_logger(None)
        self.context = context
        self.keys = keys
        if transport is None:
            transport = ZmqTransport(
                context,
                bind,
                mission,
                log,
                keys=keys,
                heartbeat_ms=settings.zmq_heartbeat_ms,
                zap=zap,
                receivers=receivers,
            )
        session = ReliableSession(name, mission, settings, log=log, rng=rng)
        super().__init__(session, transport, log, clock=clock, timers=timers)

    @property
    def auth(self) -> FleetAuthenticator | None:
        """The ZAP authenticator (with keys and the default transport)."""
        return getattr(self.transport, "auth", None)


def _addressee(topic: bytes) -> str:
    """The participant a ``to/<participant>`` subscription comes from ("" for other topics)."""
    prefix = wire.topic_to("")
    if not topic.startswith(prefix):
        return ""
    return topic[len(prefix) :].decode("utf-8", "replace")
