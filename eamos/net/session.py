"""The reliable-delivery protocol, pure: exactly-once, in-order delivery over PUB/SUB.

ZeroMQ PUB/SUB over TCP delivers in order while a connection lasts, but drops
what is published while a subscriber is disconnected (a WiFi drop, a TCP
reconnect, a peer that has not subscribed yet).  :class:`ReliableSession` is
the protocol that makes every cross-drone trigger take effect exactly once.
It owns no thread, socket or clock: the driver (:class:`~eamos.net.link.Link`)
feeds it what happened -- a message to send (:meth:`~ReliableSession.on_send`),
a message received (:meth:`~ReliableSession.on_receive`), the end of a receive
batch, a (re)subscription, the time passing (:meth:`~ReliableSession.on_tick`)
-- each with the current time ``now``, and carries out the actions it returns
(:class:`Send`, :class:`Deliver`, :class:`PeerChanged`, :class:`Wake`).  So the
protocol is tested with a fake clock and messages passed in memory.

* **Sequence numbers.**  Each reliable message gets ``seq`` = 1, 2, 3 ... per
  link (sender, dest) -- Trigger, Interrupt, Ready, Resolved, Report(Part) -- or per
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
  followed by the peers watching it.  It carries the acks that changed lately,
  and the highest seq sent on each link with messages not yet acknowledged, so
  a receiver missing the tail of a link asks for it (nack) instead of waiting
  for the sender's timer; its size follows the traffic, not the fleet.  A peer not heard from
  (any message) for ``peer_timeout_s`` is reported lost (``mission.peer.lost``,
  and a :class:`PeerStatus` event for the ground station); heard again, it is
  reported back.  A participant shutting down says so (``leaving``), and is
  then recorded as gone, not lost.
* **Telemetry is latest-value.**  Samples are not acknowledged.  Outgoing,
  they are capped at ``telemetry_max_hz`` (a burst is coalesced into its
  latest sample, which always goes out), and the latest one is repeated every
  ``heartbeat_s`` while nothing new is sent (adapters send only changes, so a
  drone at rest would otherwise look silent).  Incoming, a sample older than
  the latest one seen from that drone is dropped; a drone whose telemetry has
  not been heard for ``telemetry_stale_s`` is reported stale
  (:class:`TelemetryStale`): the runtime then withdraws its values, so a
  condition reading them waits (Unknown) rather than deciding on old data.
"""

from __future__ import annotations

import random
from collections.abc import Iterable
from typing import Any, Final

from msgspec.structs import replace

import eamos.net.wire as wire
from eamos.logs import make_logger
from eamos.net.actions import (
    Action,
    Deliver,
    PeerChanged,
    PeerStatus,
    Send,
    TelemetryStale,
    Wake,
)
from eamos.net.incarnation import admit, mine, new_incarnation
from eamos.net.liveness import LATE_TICK_S, Liveness, TelemetryOut
from eamos.net.sequence import (
    HEARTBEAT_ACK_REPEATS,
    Peer,
    Receiving,
    Sending,
    SessionCounters,
    heartbeat,
)
from eamos.net.settings import LinkSettings

__all__ = [
    "HEARTBEAT_ACK_REPEATS",
    "LATE_TICK_S",
    "NACK_INTERVAL_S",
    "Action",
    "Deliver",
    "PeerChanged",
    "PeerStatus",
    "ReliableSession",
    "Send",
    "SessionCounters",
    "TelemetryStale",
    "Wake",
]

# Retransmissions and duplicates are logged one by one up to this count per
# peer, then every _LOG_EVERY-th: a long partition must not flood the log.
_LOG_FIRST: Final = 20
_LOG_EVERY: Final = 500

_ACK_AT_ONCE: Final = frozenset({wire.Ready, wire.Resolved, wire.Report, wire.ReportPart})
"""Delivered messages acknowledged at once rather than by the next heartbeat: the
final report's sender waits for its ack before it exits; Ready and Resolved reach
the ground station from the whole fleet at once (at the start, at the end), when
its heartbeat is most likely late: one Ack each spares a retransmission each."""

NACK_INTERVAL_S: Final = 0.02
"""At most one nack per peer per this interval: after a gap, every later arrival
would otherwise ask for the same messages again."""

_NEVER: Final = float("inf")


class ReliableSession:
    """One participant's side of the reliable-delivery protocol, without threads or clocks.

    Not thread-safe: the driver serialises the calls.  Every ``on_*`` method
    takes the current time and returns the actions to carry out, in order;
    :meth:`on_tick` also returns when it must be called next.  ``log``
    receives the protocol's events (peer lost/back/left/restarted, retransmissions,
    stale telemetry); ``rng`` draws the retransmission jitter; ``incarnation``
    tells this process from an earlier one of the same name
    (:mod:`eamos.net.incarnation`; default: drawn now).
    """

    def __init__(
        self,
        name: str,
        mission: str,
        settings: LinkSettings | None = None,
        *,
        log: Any = None,
        rng: random.Random | None = None,
        incarnation: int | None = None,
    ) -> None:
        self.name = name
        self.incarnation = new_incarnation() if incarnation is None else incarnation
        self.mission = mission
        self.settings = s = settings or LinkSettings()
        self.log = log if log is not None else make_logger(None)
        self._rng = rng or random.Random()
        self._peers: dict[str, Peer] = {}
        self._acks_owed: dict[str, Peer] = {}  # peers whose ack_now was set since the last batch
        self._btx = Sending(backoff=s.rto_initial_s)
        self._tel = TelemetryOut(1.0 / s.telemetry_max_hz, s.heartbeat_s)
        self._live = Liveness(s, self.log)
        self._hb_due = float("-inf")
        self.closed = False
        self.counters = SessionCounters()

    def add_peers(self, names: Iterable[str], watched: Iterable[str] | None = None) -> None:
        """Open a link to each peer; follow the heartbeats of ``watched`` (default all)."""
        names = [n for n in names if n != self.name]
        follow = set(names) if watched is None else set(watched)
        rto = self.settings.rto_initial_s
        for peer in names:
            self._peers[peer] = Peer(peer, Sending(backoff=rto), rto, watched=peer in follow)

    # -- sending ---------------------------------------------------------------------

    def on_send(self, msg: wire.Message, now: float) -> list[Action]:
        """The application sends ``msg``: number it if reliable, rate-cap it if telemetry."""
        if self.closed:
            return []
        cls = type(msg)
        if cls in wire.RELIABLE_TO and msg.seq == 0:  # type: ignore[union-attr]
            peer = self._peers.get(msg.dest)  # type: ignore[union-attr]
            if peer is not None:
                return self._send_reliable(peer.tx, msg, now)
            self.log.warning("net.link.unknown_dest", dest=msg.dest, type=cls.__name__)  # type: ignore[union-attr]
        elif cls in wire.RELIABLE_BROADCAST and msg.seq == 0:  # type: ignore[union-attr]
            return self._send_reliable(self._btx, msg, now)
        if msg.incarnation != self.incarnation:
            msg = replace(msg, incarnation=self.incarnation)
        if cls is wire.TelemetrySample:
            return self._tel.offer(msg, now)  # type: ignore[arg-type]
        return [Send(msg)]

    def _send_reliable(self, tx: Sending, msg: wire.Message, now: float) -> list[Action]:
        numbered = tx.number(msg, now, self.incarnation)
        if tx.due is None:
            tx.due = now + tx.backoff
            return [Send(numbered), Wake(tx.due)]
        return [Send(numbered)]

    # -- receiving -------------------------------------------------------------------

    def on_receive(self, msg: wire.Message, now: float) -> list[Action]:
        """A message arrived from the network (from a configured peer, or it is ignored)."""
        peer = self._peers.get(msg.sender)
        if peer is None:  # not a configured peer: the In-Bridge only connects to peers
            return []
        actions: list[Action] = []
        if msg.incarnation != peer.incarnation and not admit(
            peer, msg.incarnation, self._btx, self._live, self.counters, now, actions
        ):
            return []  # its predecessor's, still in flight
        self._heard(peer, now, actions)
        cls = type(msg)
        if cls is wire.Ack:
            if msg.dest == self.name and mine(self.incarnation, msg.dest_incarnation):  # type: ignore[union-attr]
                self._acked(peer, msg.upto, msg.bupto, msg.nack, now, actions)  # type: ignore[union-attr]
        elif cls is wire.Heartbeat:
            self._heartbeat(peer, msg, now, actions)  # type: ignore[arg-type]
        elif cls in wire.RELIABLE_TO and msg.seq > 0:  # type: ignore[union-attr]
            self._sequenced(peer, msg, peer.rx, actions)
        elif cls in wire.RELIABLE_BROADCAST and msg.seq > 0:  # type: ignore[union-attr]
            self._sequenced(peer, msg, peer.brx, actions)
        elif cls is wire.TelemetrySample:
            if self._live.fresh(peer, msg, now):  # type: ignore[arg-type]
                actions.append(Deliver(msg))
            else:
                self.counters.old_telemetry += 1  # latest-value: an older sample is no news
        else:
            actions.append(Deliver(msg))
        if peer.ack_now:
            self._acks_owed[peer.name] = peer
        return actions

    def _heard(self, peer: Peer, now: float, actions: list[Action]) -> None:
        back = self._live.heard(peer, now)
        if back is not None:
            actions.append(back)
            # It is reachable again: whatever it has not acknowledged goes now.
            self._expedite(peer.tx, now, actions)
            self._expedite(self._btx, now, actions)

    def _expedite(self, tx: Sending, now: float, actions: list[Action]) -> None:
        if tx.pending:
            tx.due = now
            actions.append(Wake(now))

    def _sequenced(
        self, peer: Peer, msg: wire.Message, rx: Receiving, actions: list[Action]
    ) -> None:
        got = rx.accept(msg, self.settings.reorder_limit)
        if got is None:
            peer.ack_now = True  # the sender is retransmitting: it lacks our ack
            self.counters.duplicates_dropped += 1
            peer.duplicates += 1
            if _should_log(peer.duplicates):
                seq = msg.seq  # type: ignore[union-attr]
                self.log.info(
                    "net.link.duplicate", peer=peer.name, seq=seq, type=type(msg).__name__
                )
            return
        if not got:
            # A gap: something before it was lost (a reconnection).  It waits in the
            # buffer until the gap is filled; ask for the rest now.
            self.counters.reordered += 1
            peer.nack = peer.ack_now = True
            return
        if rx.buffer:
            peer.nack = peer.ack_now = True
        elif any(type(m) in _ACK_AT_ONCE for m in got):
            peer.ack_now = True  # its sender waits for this one (then exits)
        actions.extend(Deliver(m) for m in got)

    def _acked(
        self, peer: Peer, upto: int, bupto: int, nack: bool, now: float, actions: list[Action]
    ) -> None:
        self.counters.acks_received += 1
        tx = peer.tx
        progressed, sample = tx.acknowledge(upto, now)
        if sample is not None:
            peer.measure(sample, self.settings)
        if progressed:
            tx.backoff = peer.rto
            tx.due = now + peer.rto if tx.pending else None
        if bupto > peer.acked_b:
            peer.acked_b = bupto
            self._prune_broadcasts()
        if nack:
            # Not what is probably still in flight (sent within about a round trip).
            recent = peer.in_flight_window(self.settings)
            self._retransmit(peer, tx, now, actions, recent=recent)
            if self._btx.pending and peer.acked_b < self._btx.next_seq - 1:
                self._retransmit(None, self._btx, now, actions, recent=recent, after=peer.acked_b)

    def _broadcast_peers(self) -> list[Peer]:
        return [p for p in self._peers.values() if p.state != "left"]

    def _prune_broadcasts(self) -> None:
        acked = min((p.acked_b for p in self._broadcast_peers()), default=self._btx.next_seq - 1)
        self._btx.acknowledge(acked, None)
        if not self._btx.pending:
            self._btx.due = None

    def _heartbeat(self, peer: Peer, hb: wire.Heartbeat, now: float, actions: list[Action]) -> None:
        if hb.leaving:
            left = self._live.goodbye(peer)
            if left is not None:
                actions.append(left)
                self._prune_broadcasts()  # its acknowledgements are not waited for
            return
        self._live.alive(peer)
        if (self.name in hb.acks or self.name in hb.backs) and mine(
            self.incarnation, hb.known.get(self.name)
        ):
            # The acknowledgements of steady traffic ride on heartbeats.
            upto, bupto = hb.acks.get(self.name, 0), hb.backs.get(self.name, 0)
            self._acked(peer, upto, bupto, False, now, actions)
        if hb.sent.get(self.name, 0) > peer.rx.upto or hb.bsent > peer.brx.upto:
            # The tail of a link was lost and nothing came after it: ask for it.
            peer.ack_now = peer.nack = True

    def on_batch_end(self, now: float) -> list[Action]:
        """The end of a receive batch: the explicit Acks it called for (gaps, duplicates)."""
        if self.closed:
            return []  # nothing may follow the goodbye heartbeat
        # Only the peers this batch called for: the ground station has the whole fleet.
        owed, self._acks_owed = self._acks_owed, {}
        return [self._ack(peer, now) for peer in owed.values() if peer.ack_now]

    def _ack(self, peer: Peer, now: float) -> Send:
        """One cumulative Ack to ``peer``; a nack if a gap is known."""
        nack = peer.nack and now - peer.last_nack >= NACK_INTERVAL_S
        if nack:
            # Rate-limited: after a gap every later arrival would ask again.
            peer.nack = False
            peer.last_nack = now
            self.counters.nacks_sent += 1
        peer.ack_now = False
        self.counters.acks_sent += 1
        acked, inc = (peer.rx.upto, peer.brx.upto, nack, peer.incarnation), self.incarnation
        return Send(wire.Ack(self.mission, self.name, peer.name, *acked, incarnation=inc))

    def on_subscription(self, topic: bytes, now: float) -> list[Action]:
        """A peer (re)subscribed to ``topic``: what the socket dropped meanwhile goes now."""
        actions: list[Action] = []
        if topic == wire.TOPIC_ALL:
            self._expedite(self._btx, now, actions)
        elif topic.startswith(b"to/"):
            peer = self._peers.get(topic[3:].decode("utf-8", "replace"))
            if peer is not None:
                peer.tx.backoff = peer.rto
                self._expedite(peer.tx, now, actions)
        elif topic == wire.topic_telemetry(self.name):
            actions += self._tel.repeat(now)  # a new subscriber gets the latest value
        return actions

    # -- time ------------------------------------------------------------------------

    def on_tick(self, now: float) -> tuple[list[Action], float]:
        """Do what is due at ``now``; return the actions and when to be called next."""
        s = self.settings
        actions: list[Action] = []
        self._live.stalled(now, self._peers.values(), self.counters, self._btx)  # late: our stall
        if now >= self._hb_due:
            self._hb_due = now + s.heartbeat_s
            actions.append(Send(self._heartbeat_message(leaving=False)))
        deadline = self._hb_due
        for peer in self._peers.values():
            deadline = min(deadline, self._tick_peer(peer, now, actions))
        btx = self._btx
        if btx.due is not None and now >= btx.due:
            acked = min((p.acked_b for p in self._broadcast_peers()), default=btx.next_seq)
            self._retransmit(None, btx, now, actions, after=acked)
            btx.back_off(now, s.rto_max_s, self._rng)
        if btx.due is not None:
            deadline = min(deadline, btx.due)
        sent, due = self._tel.tick(now)
        actions += sent
        self._live.tick_due = due = min(deadline, due)
        return actions, due

    def _tick_peer(self, peer: Peer, now: float, actions: list[Action]) -> float:
        """One peer's timers: retransmission, liveness, telemetry staleness."""
        deadline = _NEVER
        tx = peer.tx
        if tx.due is not None and now >= tx.due:
            if peer.state == "left":
                self.counters.abandoned += len(tx.pending)
                tx.pending.clear()
                tx.due = None
            else:
                self._retransmit(peer, tx, now, actions)
                tx.back_off(now, self.settings.rto_max_s, self._rng)
        if tx.due is not None:
            deadline = tx.due
        return min(deadline, self._live.check(peer, now, actions))

    def _retransmit(
        self,
        peer: Peer | None,
        tx: Sending,
        now: float,
        actions: list[Action],
        *,
        recent: float = 0.0,
        after: int = 0,
    ) -> None:
        """Resend up to ``window`` unacknowledged messages of ``tx`` (seq > ``after``).

        Messages sent within the last ``recent`` seconds are skipped (a nack
        may race with messages still in flight).
        """
        again = tx.resend(now, self.settings.window, recent=recent, after=after)
        if not again:
            return
        actions.extend(Send(m) for m in again)
        sent = len(again)
        self.counters.retransmissions += sent
        if peer is not None:
            peer.retransmitted += sent
            count = peer.retransmitted
        else:
            count = self.counters.retransmissions
        if _should_log(count):
            self.log.info(
                "net.link.retransmit",
                peer=peer.name if peer is not None else "*",
                messages=sent,
                first_seq=next(iter(tx.pending)),
                total=count,
            )

    def _heartbeat_message(self, leaving: bool) -> wire.Heartbeat:
        self.counters.heartbeats_sent += 1
        bsent, peers = self._btx.next_seq - 1, self._peers.values()
        return heartbeat(self.mission, self.name, self.incarnation, peers, bsent, leaving)

    # -- results and shutdown --------------------------------------------------------

    def close(self) -> list[Action]:
        """Say goodbye (a leaving heartbeat, if there are peers); nothing is sent afterwards."""
        if self.closed:
            return []
        self.closed = True
        if not self._peers:
            return []
        return [Send(self._heartbeat_message(leaving=True))]

    def flushed(self, peers: Iterable[str] | None = None) -> bool:
        """Whether every reliable message sent so far was acknowledged.

        Only the links to ``peers`` if given; otherwise every link and the
        broadcasts.  Peers that left are not waited for; a closed session has
        nothing left to wait for.
        """
        if self.closed:
            return True
        only = None if peers is None else set(peers)
        if only is None and self._btx.pending and self._broadcast_peers():
            return False
        return all(
            not p.tx.pending or p.state == "left"
            for p in self._peers.values()
            if only is None or p.name in only
        )

    def unacked(self) -> int:
        """Reliable messages sent and not acknowledged yet."""
        return sum(len(p.tx.pending) for p in self._peers.values()) + len(self._btx.pending)

    def peer_stats(self) -> dict[str, dict[str, Any]]:
        """Per peer: state (``unwatched`` if its heartbeats are not followed), RTT, counts."""
        return {p.name: p.stats() for p in self._peers.values()}


def _should_log(count: int) -> bool:
    return count <= _LOG_FIRST or count % _LOG_EVERY == 0
