"""The reliability layer: exactly-once, in-order delivery over PUB/SUB, heartbeats, fresh telemetry.

ZeroMQ PUB/SUB over TCP delivers in order while a connection lasts, but drops
what is published while a subscriber is disconnected (a WiFi drop, a TCP
reconnect, a peer that has not subscribed yet).  :class:`Link` sits between a
participant's runtime and its two bridges and makes every cross-drone trigger
take effect exactly once:

* **Sequence numbers.**  Each reliable message gets ``seq`` = 1, 2, 3 ... per
  link (sender, dest) -- Trigger, Interrupt, Ready, Resolved, Report -- or per
  sender for the broadcasts Start, Abort, Complete (see
  :data:`~eamos.net.wire.RELIABLE_TO`, :data:`~eamos.net.wire.RELIABLE_BROADCAST`).
* **Acknowledgements** are cumulative (every seq up to ``upto`` arrived).
  Steady traffic is acknowledged by the receiver's next heartbeat (its
  ``acks``), which costs nothing per trigger; an explicit
  :class:`~eamos.net.wire.Ack` goes at once, at the end of the receive batch,
  when the receiver saw a gap (a nack), a duplicate (the sender is
  retransmitting, so it lacks the ack) or a final Report (its sender waits).
  A per-message ack, as a first version had, doubled the messages and cost a
  20-drone, 5000-action mission half its speed on two cores.
* **Retransmission.**  What is lost in a known way is resent at once: when
  the peer (re)subscribes (a reconnect or a late joiner: the XPUB socket
  dropped what was published meanwhile), when the peer is heard again after
  silence, and on a nack.  TCP recovers lost packets while a connection lasts.
  The safety net is a timer per link: after the retransmission timeout (RTO:
  smoothed round-trip time + 4 deviations, clamped to ``[rto_min_s,
  rto_max_s]``, Jacobson/Karn; above ``heartbeat_s``, which paces the acks)
  the unacknowledged messages are resent, the timeout doubling up to
  ``rto_max_s`` with +-20 % jitter, until acknowledged.
* **Duplicates and order.**  The receiver keeps, per link, the highest seq
  delivered in order; older seqs are duplicates (dropped, counted, re-acked),
  later ones wait in a bounded reorder buffer until the gap is filled.  So the
  runtime sees each message exactly once and in the order it was sent (node
  bookkeeping additionally ignores a second trigger for the same (source,
  activation), as it always did).
* **Heartbeats.**  Every participant publishes a
  :class:`~eamos.net.wire.Heartbeat` every ``heartbeat_s`` on ``hb/<name>``,
  followed by the peers watching it.  It carries the acks, and the highest seq
  sent on each link, so a receiver missing the tail of a link asks for it
  (nack) instead of waiting for the sender's timer.  A peer not
  heard from (any message) for ``peer_timeout_s`` is reported lost
  (``mission.peer.lost``, and a :class:`PeerStatus` event for the ground
  station); heard again, it is reported back.  A participant shutting down
  says so (``leaving``), and is then recorded as gone, not lost.
* **Telemetry is latest-value.**  Samples are not acknowledged.  Outgoing,
  they are capped at ``telemetry_max_hz`` (a burst is coalesced into its
  latest sample, which always goes out), and the latest one is repeated every
  ``heartbeat_s`` while nothing new is sent (adapters send only changes, so a
  drone at rest would otherwise look silent).  Incoming, a sample older than
  the latest one seen from that drone is dropped; a drone whose telemetry has
  not been heard for ``telemetry_stale_s`` is reported stale
  (:class:`TelemetryStale`): the runtime then withdraws its values, so a
  condition reading them waits (Unknown) rather than deciding on old data.

Threads: the In-Bridge's receive thread runs :meth:`Link._receive` and the
explicit acks; one timer thread per link (waiting on a Condition with a deadline, never
polling) sends heartbeats, retransmits, checks liveness and staleness.  All
state is guarded by one Condition; application callbacks run outside it.

Local events (never on the wire) are passed to ``on_message`` with the
messages: :class:`PeerStatus` and :class:`TelemetryStale`.
"""

from __future__ import annotations

import dataclasses
import random
import threading
import time
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any, Final

import zmq

from eamos.logs import make_logger
from eamos.net import wire
from eamos.net.bridges import DEFAULT_HEARTBEAT_MS, InBridge, OutBridge
from eamos.net.keys import FleetAuthenticator, FleetKeys

__all__ = ["Link", "LinkSettings", "PeerStatus", "TelemetryStale"]

# Retransmissions and duplicates are logged one by one up to this count per
# peer, then every _LOG_EVERY-th: a long partition must not flood the log.
_LOG_FIRST: Final = 20
_LOG_EVERY: Final = 500

_ACK_AT_ONCE: Final = frozenset({wire.Report})
"""Delivered messages acknowledged at once rather than by the next heartbeat:
the final report's sender waits for its ack before it exits."""

NACK_INTERVAL_S: Final = 0.02
"""At most one nack per peer per this interval: after a gap, every later arrival
would otherwise ask for the same messages again."""


@dataclass(frozen=True)
class LinkSettings:
    """Timing of the reliability layer (every field is a ``[net]`` config key too)."""

    heartbeat_s: float = 1.0
    """Heartbeat period; also how often the latest telemetry sample is repeated.

    Each heartbeat wakes every peer watching it (a few hundred microseconds of
    CPU there), so the period is a trade between detection time and load."""
    peer_timeout_s: float = 3.0
    """A peer not heard from for this long is reported lost."""
    telemetry_stale_s: float = 2.5
    """A drone's telemetry not heard for this long is stale: conditions wait."""
    telemetry_max_hz: float = 20.0
    """At most this many telemetry samples per second leave (the latest always does)."""
    rto_min_s: float = 0.0
    """Lower bound of the retransmission timeout; 0: twice ``heartbeat_s``.  It
    must exceed ``heartbeat_s``: steady traffic is acknowledged by the
    receiver's heartbeats.  The timer is the safety net: losses that are known
    (a reconnect, a late subscriber, a gap the receiver saw) are resent at once,
    and TCP recovers lost packets while a connection lasts."""
    rto_max_s: float = 0.0
    """Upper bound of the retransmission timeout; 0: five times ``heartbeat_s``."""
    rto_initial_s: float = 0.0
    """Retransmission timeout before any round trip was measured; 0: ``rto_min_s``."""
    window: int = 256
    """At most this many messages of one link are retransmitted per timeout."""
    reorder_limit: int = 65536
    """Out-of-order messages buffered per link (beyond, they are resent later)."""
    zmq_heartbeat_ms: int = DEFAULT_HEARTBEAT_MS
    """ZeroMQ's own connection heartbeat (drops dead TCP connections)."""

    def __post_init__(self) -> None:
        # Derived defaults (0 = derive); object.__setattr__ because frozen.
        if self.rto_min_s == 0:
            object.__setattr__(self, "rto_min_s", 2 * self.heartbeat_s)
        if self.rto_max_s == 0:
            object.__setattr__(self, "rto_max_s", max(5 * self.heartbeat_s, self.rto_min_s))
        if self.rto_initial_s == 0:
            object.__setattr__(self, "rto_initial_s", self.rto_min_s)
        for name in (
            "heartbeat_s",
            "peer_timeout_s",
            "telemetry_stale_s",
            "telemetry_max_hz",
            "rto_min_s",
            "rto_max_s",
            "rto_initial_s",
        ):
            value = getattr(self, name)
            if not value > 0:
                raise ValueError(f"{name}: must be > 0, got {value!r}")
        if self.rto_max_s < self.rto_min_s:
            raise ValueError("rto_max_s: must be >= rto_min_s")
        if self.rto_min_s <= self.heartbeat_s:
            raise ValueError(
                "rto_min_s: must be longer than heartbeat_s (heartbeats carry the acks)"
            )
        if self.peer_timeout_s <= self.heartbeat_s:
            raise ValueError("peer_timeout_s: must be longer than heartbeat_s")
        if self.telemetry_stale_s <= self.heartbeat_s:
            raise ValueError(
                "telemetry_stale_s: must be longer than heartbeat_s (the telemetry refresh)"
            )


@dataclass(frozen=True)
class PeerStatus:
    """Local event: peer ``sender`` went silent (``lost``), came ``back``, or ``left``.

    ``serial`` increases per link: a handler that sees events of one peer out
    of order (they come from two threads) keeps the highest.
    """

    sender: str
    state: str
    silent_s: float
    serial: int


@dataclass(frozen=True)
class TelemetryStale:
    """Local event: no telemetry from drone ``sender`` for ``age_s`` seconds."""

    sender: str
    age_s: float


@dataclass
class _Out:
    """One reliable message waiting for its acknowledgement."""

    msg: wire.Message
    first_sent: float
    last_sent: float
    tries: int = 0  # retransmissions so far


@dataclass
class _Tx:
    """The sending side of one link (or of this participant's broadcasts)."""

    backoff: float
    next_seq: int = 1
    pending: dict[int, _Out] = field(default_factory=dict)  # insertion order = seq order
    due: float | None = None  # when the retransmission timer fires


@dataclass
class _Peer:
    """Everything this participant knows about one peer."""

    name: str
    tx: _Tx
    rto: float
    watched: bool = True  # its heartbeats are followed: it can be lost, back, left
    rx_upto: int = 0  # every seq <= rx_upto of the link peer -> me was delivered
    rx_buffer: dict[int, wire.Message] = field(default_factory=dict)
    brx_upto: int = 0  # same for the peer's broadcasts
    brx_buffer: dict[int, wire.Message] = field(default_factory=dict)
    acked_b: int = 0  # my broadcasts this peer acknowledged
    ack_now: bool = False  # an explicit Ack at the end of this receive batch
    nack: bool = False
    last_nack: float = float("-inf")
    state: str = "unknown"  # unknown | up | lost | left
    heard: float | None = None
    srtt: float | None = None
    rttvar: float = 0.0
    tel_time: float | None = None  # sample time of the latest telemetry from it
    tel_heard: float | None = None
    tel_stale: bool = False
    retransmitted: int = 0
    duplicates: int = 0


class Link:
    """One participant's reliable, authenticated connection to the rest of the fleet.

    Build it (binds the Out-Bridge and, with ``keys``, starts the ZAP
    authenticator first), :meth:`connect` to the peers (In-Bridge, timer
    thread), :meth:`send` from any thread, :meth:`close` at the end.
    ``out`` and ``inb`` are the two bridges.
    """

    def __init__(
        self,
        context: zmq.Context[Any],
        name: str,
        mission: str,
        bind: str,
        log: Any = None,
        *,
        keys: FleetKeys | None = None,
        settings: LinkSettings | None = None,
    ) -> None:
        self.name = name
        self.mission = mission
        self.context = context
        self.keys = keys
        self.settings = settings or LinkSettings()
        self.log = log if log is not None else make_logger(None)
        self._rng = random.Random()
        # One lock guards all state.  Two conditions on it: _cond for flush()
        # waiters (notified when acks arrive), _wake for the timer thread,
        # notified only when a deadline earlier than its planned wake-up appears:
        # a busy link must not wake the timer for every message.
        lock = threading.RLock()
        self._cond = threading.Condition(lock)
        self._wake = threading.Condition(lock)
        self._next_wake = float("inf")
        self._peers: dict[str, _Peer] = {}
        self._btx = _Tx(backoff=self.settings.rto_initial_s)
        self._on_message: Callable[[Any], None] = lambda msg: None
        self._closed = False
        self._serial = 0
        # telemetry going out
        self._tel_latest: wire.TelemetrySample | None = None
        self._tel_sent_at = float("-inf")
        self._tel_pending = False
        self._hb_due = 0.0
        # counters
        self.retransmissions = 0
        self.duplicates_dropped = 0
        self.reordered = 0
        self.acks_sent = 0
        self.nacks_sent = 0
        self.acks_received = 0
        self.heartbeats_sent = 0
        self.old_telemetry = 0
        self.abandoned = 0
        self.delivery_errors = 0
        self.peer_events: list[dict[str, Any]] = []
        self.auth: FleetAuthenticator | None = None
        if keys is not None:
            # Before the CURVE server binds: no handshake may happen unauthenticated.
            self.auth = FleetAuthenticator(context, keys, self.log)
        try:
            self.out = OutBridge(
                context,
                bind,
                self.log,
                curve=keys,
                heartbeat_ms=self.settings.zmq_heartbeat_ms,
                on_subscription=self._on_subscription,
            )
        except BaseException:
            if self.auth is not None:
                self.auth.stop()
            raise
        self.out.start()
        self.inb: InBridge | None = None
        self._thread = threading.Thread(target=self._run, name=f"eamos-link-{name}", daemon=True)

    @property
    def secure(self) -> bool:
        """Whether the links are CURVE-encrypted and authenticated."""
        return self.keys is not None

    # -- set-up --------------------------------------------------------------------

    def connect(
        self,
        peers: Mapping[str, str],
        topics: Iterable[bytes],
        on_message: Callable[[Any], None],
        watch: Iterable[str] | None = None,
    ) -> None:
        """Connect to ``peers`` (name -> endpoint), subscribe, start receiving and the timer.

        ``on_message`` receives every wire message exactly once, in order per
        sender, plus the local events :class:`PeerStatus` and
        :class:`TelemetryStale`; it runs on the receive or timer thread.
        ``watch`` names the peers whose heartbeats to follow (reported lost,
        back, left); default all.  Heartbeats cost every receiver a wake-up,
        so a drone watches only the peers it works with, while the ground
        station watches the whole fleet.
        """
        names = [p for p in peers if p != self.name]
        watched = set(names) if watch is None else set(watch) & set(names)
        wanted = [wire.TOPIC_ALL, wire.topic_to(self.name)]
        wanted += [wire.topic_heartbeat(p) for p in sorted(watched)]
        wanted += [t for t in topics if t not in wanted]
        rto = self.settings.rto_initial_s
        with self._cond:
            self._on_message = on_message
            for peer in names:
                self._peers[peer] = _Peer(peer, _Tx(backoff=rto), rto, watched=peer in watched)
        self.inb = InBridge(
            self.context,
            {p: e for p, e in peers.items() if p != self.name},
            wanted,
            self._receive,
            self.mission,
            self.log,
            curve=self.keys,
            check_sender=True,
            heartbeat_ms=self.settings.zmq_heartbeat_ms,
            on_batch_end=self._flush_acks,
        )
        self.inb.start()
        self._thread.start()

    def wait_subscribed(self, topics: Iterable[bytes], timeout_s: float) -> bool:
        """See :meth:`OutBridge.wait_subscribed`."""
        return self.out.wait_subscribed(topics, timeout_s)

    # -- sending ------------------------------------------------------------------------

    def send(self, msg: wire.Message) -> bool:
        """Send ``msg``; reliable types get a sequence number and are retransmitted until acked.

        Thread-safe and non-blocking.  False if the link is closed.
        """
        cls = type(msg)
        now = time.monotonic()
        with self._cond:
            if self._closed:
                return False
            if cls in wire.RELIABLE_TO and msg.seq == 0:  # type: ignore[union-attr]
                peer = self._peers.get(msg.dest)  # type: ignore[union-attr]
                if peer is not None:
                    return self._send_reliable(peer.tx, msg, now)
                self.log.warning("net.link.unknown_dest", dest=msg.dest, type=cls.__name__)  # type: ignore[union-attr]
            elif cls in wire.RELIABLE_BROADCAST and msg.seq == 0:  # type: ignore[union-attr]
                return self._send_reliable(self._btx, msg, now)
            elif cls is wire.TelemetrySample:
                return self._send_telemetry(msg, now)  # type: ignore[arg-type]
            # Sent inside the lock like the rest, so per-sender order is kept.
            return self.out.send(msg)

    def _send_reliable(self, tx: _Tx, msg: wire.Message, now: float) -> bool:
        seq = tx.next_seq
        tx.next_seq += 1
        msg = dataclasses.replace(msg, seq=seq)  # type: ignore[call-arg,arg-type]
        tx.pending[seq] = _Out(msg, now, now)
        if tx.due is None:
            tx.due = now + tx.backoff
            self._kick(tx.due)
        # Inside the lock: the wire order of one link is its seq order.
        return self.out.send(msg)

    def _send_telemetry(self, msg: wire.TelemetrySample, now: float) -> bool:
        self._tel_latest = msg
        if now - self._tel_sent_at >= 1.0 / self.settings.telemetry_max_hz:
            self._tel_sent_at = now
            self._tel_pending = False
            return self.out.send(msg)
        if not self._tel_pending:
            self._tel_pending = True  # the timer sends the latest at the end of the interval
            self._kick(self._tel_sent_at + 1.0 / self.settings.telemetry_max_hz)
        return True

    def _kick(self, due: float) -> None:
        """Wake the timer thread if ``due`` is before its planned wake-up (lock held)."""
        if due < self._next_wake:
            self._next_wake = due
            self._wake.notify()

    def flush(self, timeout_s: float, peers: Iterable[str] | None = None) -> bool:
        """Wait until every reliable message sent so far was acknowledged (bounded).

        Only the links to ``peers`` if given; otherwise every link and the
        broadcasts.  Peers that left are not waited for.  Returns False on
        timeout.
        """
        only = None if peers is None else set(peers)

        def done() -> bool:
            if self._closed:
                return True
            if only is None and self._btx.pending and self._broadcast_peers():
                return False
            return all(
                not p.tx.pending or p.state == "left"
                for p in self._peers.values()
                if only is None or p.name in only
            )

        with self._cond:
            return self._cond.wait_for(done, timeout_s)

    # -- receiving (In-Bridge thread) ------------------------------------------------------

    def _receive(self, msg: wire.Message) -> None:
        now = time.monotonic()
        deliver: list[Any] = []
        events: list[Any] = []
        with self._cond:
            peer = self._peers.get(msg.sender)
            if peer is None:  # not a configured peer: the In-Bridge only connects to peers
                return
            self._heard(peer, now, events)
            cls = type(msg)
            if cls is wire.Ack:
                if msg.dest == self.name:  # type: ignore[union-attr]
                    self._acked(peer, msg, now)  # type: ignore[arg-type]
            elif cls is wire.Heartbeat:
                self._heartbeat(peer, msg, now, events)  # type: ignore[arg-type]
            elif cls in wire.RELIABLE_TO and msg.seq > 0:  # type: ignore[union-attr]
                deliver = self._sequenced(peer, msg, broadcast=False)
            elif cls in wire.RELIABLE_BROADCAST and msg.seq > 0:  # type: ignore[union-attr]
                deliver = self._sequenced(peer, msg, broadcast=True)
            elif cls is wire.TelemetrySample:
                if peer.tel_time is not None and msg.time_s < peer.tel_time:  # type: ignore[union-attr]
                    self.old_telemetry += 1  # latest-value: an older sample is no news
                else:
                    peer.tel_time = msg.time_s  # type: ignore[union-attr]
                    peer.tel_heard = now
                    if peer.tel_stale:
                        peer.tel_stale = False
                        self.log.info("mission.telemetry.fresh", drone=peer.name)
                    deliver = [msg]
            else:
                deliver = [msg]
        for item in (*events, *deliver):
            self._deliver(item)

    def _deliver(self, item: Any) -> None:
        try:
            self._on_message(item)
        except Exception:  # a consumer bug must not cut this participant off
            self.delivery_errors += 1
            self.log.exception("net.in.callback_error", type=type(item).__name__)

    def _heard(self, peer: _Peer, now: float, events: list[Any]) -> None:
        silent = 0.0 if peer.heard is None else now - peer.heard
        peer.heard = now
        if not peer.watched:
            return  # no heartbeats from it: its silence would mean nothing
        if peer.state == "left":
            return  # stragglers after its goodbye (a heartbeat from a restart revives it)
        if peer.state == "lost":
            peer.state = "up"
            events.append(self._peer_event(peer, "back", silent))
            # It is reachable again: whatever it has not acknowledged goes now.
            self._expedite(peer.tx, now)
            self._expedite(self._btx, now)
        elif peer.state != "up":
            peer.state = "up"
            self.log.debug("net.peer.up", peer=peer.name)

    def _peer_event(self, peer: _Peer, state: str, silent_s: float) -> PeerStatus:
        self._serial += 1
        event = PeerStatus(peer.name, state, round(silent_s, 3), self._serial)
        self.peer_events.append(
            {"peer": peer.name, "state": state, "silent_s": event.silent_s, "t": time.time()}
        )
        level = self.log.warning if state == "lost" else self.log.info
        level(f"mission.peer.{state}", peer=peer.name, silent_s=event.silent_s)
        return event

    def _expedite(self, tx: _Tx, now: float) -> None:
        if tx.pending:
            tx.due = now
            self._kick(now)

    def _sequenced(self, peer: _Peer, msg: wire.Message, broadcast: bool) -> list[Any]:
        seq: int = msg.seq  # type: ignore[union-attr]
        upto = peer.brx_upto if broadcast else peer.rx_upto
        buffer = peer.brx_buffer if broadcast else peer.rx_buffer
        if seq <= upto or seq in buffer:
            peer.ack_now = True  # the sender is retransmitting: it lacks our ack
            self.duplicates_dropped += 1
            peer.duplicates += 1
            if _should_log(peer.duplicates):
                self.log.info(
                    "net.link.duplicate", peer=peer.name, seq=seq, type=type(msg).__name__
                )
            return []
        if seq > upto + 1:
            # A gap: something before it was lost (a reconnection).  Keep this one
            # until the gap is filled, and ask for the rest now.
            self.reordered += 1
            if len(buffer) < self.settings.reorder_limit:
                buffer[seq] = msg
            peer.nack = peer.ack_now = True
            return []
        out = [msg]
        upto = seq
        while upto + 1 in buffer:
            upto += 1
            out.append(buffer.pop(upto))
        if buffer:
            peer.nack = peer.ack_now = True
        elif any(type(m) in _ACK_AT_ONCE for m in out):
            peer.ack_now = True  # its sender waits for this one (then exits)
        if broadcast:
            peer.brx_upto = upto
        else:
            peer.rx_upto = upto
        return out

    def _acked(self, peer: _Peer, ack: wire.Ack, now: float) -> None:
        self.acks_received += 1
        tx = peer.tx
        sample: float | None = None
        progressed = False
        while tx.pending:
            seq = next(iter(tx.pending))
            if seq > ack.upto:
                break
            out = tx.pending.pop(seq)
            progressed = True
            if out.tries == 0:  # Karn: only messages sent once measure the round trip
                sample = now - out.first_sent
        if sample is not None:
            self._rtt(peer, sample)
        if progressed:
            tx.backoff = peer.rto
            tx.due = now + peer.rto if tx.pending else None
            self._cond.notify_all()  # flush() waiters
        if ack.bupto > peer.acked_b:
            peer.acked_b = ack.bupto
            self._prune_broadcasts()
        if ack.nack:
            # Not what is probably still in flight (sent within about a round trip).
            recent = self._in_flight_window(peer)
            self._retransmit(peer, tx, now, recent=recent)
            if self._btx.pending and peer.acked_b < self._btx.next_seq - 1:
                self._retransmit(None, self._btx, now, recent=recent, after=peer.acked_b)

    def _in_flight_window(self, peer: _Peer) -> float:
        if peer.srtt is None:
            return self.settings.rto_min_s
        return max(0.005, 1.5 * peer.srtt)

    def _rtt(self, peer: _Peer, sample: float) -> None:
        if peer.srtt is None:
            peer.srtt, peer.rttvar = sample, sample / 2
        else:
            peer.rttvar = 0.75 * peer.rttvar + 0.25 * abs(peer.srtt - sample)
            peer.srtt = 0.875 * peer.srtt + 0.125 * sample
        s = self.settings
        peer.rto = min(max(peer.srtt + 4 * peer.rttvar, s.rto_min_s), s.rto_max_s)

    def _broadcast_peers(self) -> list[_Peer]:
        return [p for p in self._peers.values() if p.state != "left"]

    def _prune_broadcasts(self) -> None:
        peers = self._broadcast_peers()
        acked = min((p.acked_b for p in peers), default=self._btx.next_seq - 1)
        tx = self._btx
        while tx.pending and next(iter(tx.pending)) <= acked:
            del tx.pending[next(iter(tx.pending))]
        if not tx.pending:
            tx.due = None
        self._cond.notify_all()

    def _heartbeat(self, peer: _Peer, hb: wire.Heartbeat, now: float, events: list[Any]) -> None:
        if hb.leaving:
            if peer.state != "left":
                peer.state = "left"
                events.append(self._peer_event(peer, "left", 0.0))
                self._prune_broadcasts()
            return
        if peer.state == "left":
            peer.state = "up"  # it left and started again
            self.log.info("net.peer.up", peer=peer.name, rejoined=True)
        if self.name in hb.acks or self.name in hb.backs:
            # The acknowledgements of steady traffic ride on heartbeats.
            self._acked(
                peer,
                wire.Ack(
                    mission=self.mission,
                    sender=peer.name,
                    dest=self.name,
                    upto=hb.acks.get(self.name, 0),
                    bupto=hb.backs.get(self.name, 0),
                ),
                now,
            )
        if hb.sent.get(self.name, 0) > peer.rx_upto or hb.bsent > peer.brx_upto:
            # The tail of a link was lost and nothing came after it: ask for it.
            peer.ack_now = peer.nack = True

    def _flush_acks(self) -> None:
        """In-Bridge batch end: the explicit Acks this batch called for (gaps, duplicates)."""
        now = time.monotonic()
        with self._cond:
            if self._closed:
                return  # nothing may follow the goodbye heartbeat
            for peer in self._peers.values():
                if peer.ack_now:
                    self._send_ack(peer, now)

    def _send_ack(self, peer: _Peer, now: float) -> None:
        """One cumulative Ack to ``peer`` (lock held); a nack if a gap is known."""
        nack = peer.nack and now - peer.last_nack >= NACK_INTERVAL_S
        if nack:
            # Rate-limited: after a gap every later arrival would ask again.
            peer.nack = False
            peer.last_nack = now
            self.nacks_sent += 1
        peer.ack_now = False
        self.acks_sent += 1
        self.out.send(
            wire.Ack(
                mission=self.mission,
                sender=self.name,
                dest=peer.name,
                upto=peer.rx_upto,
                bupto=peer.brx_upto,
                nack=nack,
            )
        )

    def _on_subscription(self, topic: bytes, on: bool) -> None:
        # Out-Bridge thread: a peer (re)subscribed, e.g. after a reconnect.  What
        # it missed meanwhile was dropped by the XPUB socket: resend it now.
        if not on:
            return
        now = time.monotonic()
        with self._cond:
            if topic == wire.TOPIC_ALL:
                self._expedite(self._btx, now)
            elif topic.startswith(b"to/"):
                peer = self._peers.get(topic[3:].decode("utf-8", "replace"))
                if peer is not None:
                    peer.tx.backoff = peer.rto
                    self._expedite(peer.tx, now)
            elif topic == wire.topic_telemetry(self.name) and self._tel_latest is not None:
                self._tel_sent_at = now
                self.out.send(self._tel_latest)  # a new subscriber gets the latest value

    # -- timer thread --------------------------------------------------------------------

    def _run(self) -> None:
        try:
            while True:
                events: list[Any] = []
                with self._cond:
                    if self._closed:
                        return
                    now = time.monotonic()
                    deadline = self._tick(now, events)
                    if not events:
                        self._next_wake = deadline
                        self._wake.wait(max(0.0, deadline - time.monotonic()))
                        self._next_wake = float("-inf")  # awake: nobody needs to kick
                for event in events:
                    self._deliver(event)
        except Exception:  # pragma: no cover - a bug; say so rather than die silently
            self.log.exception("net.link.timer_error")

    def _tick(self, now: float, events: list[Any]) -> float:
        """Do what is due (lock held); return when to wake up next."""
        s = self.settings
        if now >= self._hb_due:
            self._hb_due = now + s.heartbeat_s
            self._send_heartbeat(leaving=False)
        deadline = self._hb_due
        for peer in self._peers.values():
            tx = peer.tx
            if tx.due is not None and now >= tx.due:
                if peer.state == "left":
                    self.abandoned += len(tx.pending)
                    tx.pending.clear()
                    tx.due = None
                    self._cond.notify_all()
                else:
                    self._retransmit(peer, tx, now)
                    self._backoff(tx, now)
            if tx.due is not None:
                deadline = min(deadline, tx.due)
            if peer.watched and peer.state == "up" and peer.heard is not None:
                silent = now - peer.heard
                if silent > s.peer_timeout_s:
                    peer.state = "lost"
                    events.append(self._peer_event(peer, "lost", silent))
                else:
                    deadline = min(deadline, peer.heard + s.peer_timeout_s + 1e-3)
            if peer.tel_heard is not None and not peer.tel_stale:
                age = now - peer.tel_heard
                if age > s.telemetry_stale_s:
                    peer.tel_stale = True
                    self.log.warning(
                        "mission.telemetry.stale", drone=peer.name, age_s=round(age, 3)
                    )
                    events.append(TelemetryStale(peer.name, round(age, 3)))
                else:
                    deadline = min(deadline, peer.tel_heard + s.telemetry_stale_s + 1e-3)
        btx = self._btx
        if btx.due is not None and now >= btx.due:
            acked = min((p.acked_b for p in self._broadcast_peers()), default=btx.next_seq)
            self._retransmit(None, btx, now, after=acked)
            self._backoff(btx, now)
        if btx.due is not None:
            deadline = min(deadline, btx.due)
        if self._tel_latest is not None:
            interval = 1.0 / s.telemetry_max_hz
            if self._tel_pending and now - self._tel_sent_at >= interval:
                self._tel_pending = False
                self._tel_sent_at = now
                self.out.send(self._tel_latest)
            elif not self._tel_pending and now - self._tel_sent_at >= s.heartbeat_s:
                # Nothing new: repeat the latest, so peers know it is still current.
                self._tel_sent_at = now
                self.out.send(self._tel_latest)
            deadline = min(
                deadline,
                self._tel_sent_at + (interval if self._tel_pending else s.heartbeat_s),
            )
        return deadline

    def _backoff(self, tx: _Tx, now: float) -> None:
        if not tx.pending:
            tx.due = None
            return
        tx.backoff = min(tx.backoff * 2, self.settings.rto_max_s)
        tx.due = now + tx.backoff * self._rng.uniform(0.8, 1.2)

    def _retransmit(
        self,
        peer: _Peer | None,
        tx: _Tx,
        now: float,
        *,
        recent: float = 0.0,
        after: int = 0,
    ) -> None:
        """Resend up to ``window`` unacknowledged messages of ``tx`` (seq > ``after``).

        Messages sent within the last ``recent`` seconds are skipped (a nack
        may race with messages still in flight).
        """
        sent = 0
        for seq, out in tx.pending.items():
            if seq <= after:
                continue
            if sent >= self.settings.window:
                break
            if recent and now - out.last_sent < recent:
                continue
            out.tries += 1
            out.last_sent = now
            self.out.send(out.msg)
            sent += 1
        if not sent:
            return
        self.retransmissions += sent
        if peer is not None:
            peer.retransmitted += sent
            count = peer.retransmitted
        else:
            count = self.retransmissions
        if _should_log(count):
            self.log.info(
                "net.link.retransmit",
                peer=peer.name if peer is not None else "*",
                messages=sent,
                first_seq=next(iter(tx.pending)),
                total=count,
            )

    def _send_heartbeat(self, leaving: bool) -> None:
        peers = self._peers.values()
        self.heartbeats_sent += 1
        self.out.send(
            wire.Heartbeat(
                mission=self.mission,
                sender=self.name,
                sent={p.name: p.tx.next_seq - 1 for p in peers if p.tx.next_seq > 1},
                bsent=self._btx.next_seq - 1,
                leaving=leaving,
                acks={p.name: p.rx_upto for p in peers if p.rx_upto},
                backs={p.name: p.brx_upto for p in peers if p.brx_upto},
            )
        )

    # -- results and shutdown ------------------------------------------------------------------

    def stats(self) -> dict[str, Any]:
        """Counters for the run summary (``report()["net"]``)."""
        inb = self.inb
        with self._cond:
            dropped = dict(inb.dropped_by_reason) if inb is not None else {}
            if self.old_telemetry:
                dropped["old_telemetry"] = self.old_telemetry
            return {
                "secure": self.secure,
                "retransmissions": self.retransmissions,
                "duplicates_dropped": self.duplicates_dropped,
                "reordered": self.reordered,
                "acks_sent": self.acks_sent,
                "nacks_sent": self.nacks_sent,
                "acks_received": self.acks_received,
                "heartbeats_sent": self.heartbeats_sent,
                "unacked": sum(len(p.tx.pending) for p in self._peers.values())
                + len(self._btx.pending),
                "abandoned": self.abandoned,
                "dropped": dropped,
                "auth_denied": self.auth.denied if self.auth is not None else 0,
                "auth_failures": self.out.auth_failures
                + (inb.auth_failures if inb is not None else 0),
                "peer_events": list(self.peer_events),
                "peers": {
                    p.name: {
                        "state": p.state if p.watched else "unwatched",
                        "rtt_ms": None if p.srtt is None else round(p.srtt * 1e3, 3),
                        "retransmitted": p.retransmitted,
                        "duplicates": p.duplicates,
                    }
                    for p in self._peers.values()
                },
                "messages_sent": self.out.sent_counts,
                "bytes_sent": self.out.sent_bytes,
                "bytes_sent_by_type": self.out.sent_bytes_by_type,
            }

    def close_receiving(self) -> None:
        """Say goodbye (a leaving heartbeat), stop the timer and the In-Bridge; idempotent.

        Nothing is delivered to ``on_message`` afterwards, and nothing more is
        sent (:meth:`send` returns False).
        """
        with self._cond:
            if not self._closed:
                if self._peers:
                    self._send_heartbeat(leaving=True)
                self._closed = True
                self._cond.notify_all()
                self._wake.notify_all()
        if self._thread.is_alive() and threading.current_thread() is not self._thread:
            self._thread.join(5.0)
        if self.inb is not None:
            self.inb.close()

    def close(self) -> None:
        """:meth:`close_receiving`, then close the Out-Bridge and the authenticator; idempotent.

        The Out-Bridge hands what was sent before to its socket first; the
        socket's linger lets it leave before ``Context.term`` returns.
        """
        self.close_receiving()
        self.out.close()
        if self.auth is not None:
            self.auth.stop()


def _should_log(count: int) -> bool:
    return count <= _LOG_FIRST or count % _LOG_EVERY == 0
