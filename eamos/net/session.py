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

Each part is a class of its own, in the module of that part:
:class:`~eamos.net.sending.Sender` (numbering, retransmission timers),
:class:`~eamos.net.receiving.Receiver` (in-order delivery, explicit Acks),
:class:`~eamos.net.broadcasts.Broadcasts` (one sequence for every peer),
:class:`~eamos.net.liveness.Liveness` and :class:`~eamos.net.liveness.TelemetryOut`
(who is up; this participant's own telemetry), :mod:`eamos.net.incarnation` (a
restarted peer).  :class:`ReliableSession` takes the driver's events and hands each
to its part.
"""

from __future__ import annotations

import random
from collections.abc import Iterable
from typing import Any

from msgspec.structs import replace

import eamos.net.wire as wire
from eamos.logs import EventLog, make_logger
from eamos.net.broadcasts import Broadcasts
from eamos.net.effects import (
    Deliver,
    PeerChanged,
    PeerStatus,
    Send,
    SessionEffect,
    TelemetryStale,
    TriggersAcknowledged,
    Wake,
)
from eamos.net.incarnation import admit, mine, new_incarnation
from eamos.net.liveness import LATE_TICK_S, Liveness, TelemetryOut
from eamos.net.receiving import NACK_INTERVAL_S, Receiver
from eamos.net.sending import Sender
from eamos.net.sequence import (
    HEARTBEAT_ACK_REPEATS,
    Peer,
    Sending,
    SessionCounters,
    heartbeat,
)
from eamos.net.settings import LinkSettings

__all__ = [
    "HEARTBEAT_ACK_REPEATS",
    "LATE_TICK_S",
    "NACK_INTERVAL_S",
    "Deliver",
    "PeerChanged",
    "PeerStatus",
    "ReliableSession",
    "Send",
    "SessionCounters",
    "SessionEffect",
    "TelemetryStale",
    "Wake",
]


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
        log: EventLog | None = None,
        rng: random.Random | None = None,
        incarnation: int | None = None,
    ) -> None:
        self.name = name
        self.incarnation = new_incarnation() if incarnation is None else incarnation
        self.mission = mission
        self.settings = s = settings or LinkSettings()
        self.log: EventLog = log if log is not None else make_logger(None)
        self.counters = SessionCounters()
        self._peers: dict[str, Peer] = {}
        self._live = Liveness(s, self.log)
        # The retransmission timers wait the margin the liveness deadlines get for load.
        self._sender = Sender(
            s, self.counters, self.log, rng or random.Random(), self._live.margin_s
        )
        self._receiver = Receiver(name, mission, self.incarnation, s, self.counters, self.log)
        self._broadcasts = Broadcasts(s.rto_initial_s)
        self._tel = TelemetryOut(1.0 / s.telemetry_max_hz, s.heartbeat_s)
        self._hb_due = float("-inf")
        self.closed = False

    def add_peers(self, names: Iterable[str], watched: Iterable[str] | None = None) -> None:
        """Open a link to each peer; follow the heartbeats of ``watched`` (default all)."""
        names = [n for n in names if n != self.name]
        follow = set(names) if watched is None else set(watched)
        rto = self.settings.rto_initial_s
        for peer in names:
            self._peers[peer] = Peer(peer, Sending(backoff=rto), rto, watched=peer in follow)

    # -- sending ---------------------------------------------------------------------

    def on_send(self, msg: wire.Message, now: float) -> list[SessionEffect]:
        """The application sends ``msg``: number it if reliable, rate-cap it if telemetry."""
        if self.closed:
            return []
        cls = type(msg)
        if cls in wire.RELIABLE_TO and msg.seq == 0:  # type: ignore[union-attr]
            peer = self._peers.get(msg.dest)  # type: ignore[union-attr]
            if peer is not None:
                return self._sender.send(peer.tx, msg, now, self.incarnation)
            self.log.warning("net.link.unknown_dest", dest=msg.dest, type=cls.__name__)  # type: ignore[union-attr]
        elif cls in wire.RELIABLE_BROADCAST and msg.seq == 0:  # type: ignore[union-attr]
            return self._sender.send(self._broadcasts.tx, msg, now, self.incarnation)
        if msg.incarnation != self.incarnation:
            msg = replace(msg, incarnation=self.incarnation)
        if cls is wire.TelemetrySample:
            return self._tel.offer(msg, now)  # type: ignore[arg-type]
        return [Send(msg)]

    # -- receiving -------------------------------------------------------------------

    def on_receive(self, msg: wire.Message, now: float) -> list[SessionEffect]:
        """A message arrived from the network (from a configured peer, or it is ignored)."""
        peer = self._peers.get(msg.sender)
        if peer is None:  # not a configured peer: the In-Bridge only connects to peers
            return []
        actions: list[SessionEffect] = []
        if msg.incarnation != peer.incarnation and not admit(
            peer, msg.incarnation, self._broadcasts.tx, self._live, self.counters, now, actions
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
            self._receiver.accept(peer, msg, peer.rx, actions)
        elif cls in wire.RELIABLE_BROADCAST and msg.seq > 0:  # type: ignore[union-attr]
            self._receiver.accept(peer, msg, peer.brx, actions)
        elif cls is wire.TelemetrySample:
            if self._live.fresh(peer, msg, now):  # type: ignore[arg-type]
                actions.append(Deliver(msg))
            else:
                self.counters.old_telemetry += 1  # latest-value: an older sample is no news
        else:
            actions.append(Deliver(msg))
        self._receiver.owe(peer)
        return actions

    def _heard(self, peer: Peer, now: float, actions: list[SessionEffect]) -> None:
        back = self._live.heard(peer, now)
        if back is not None:
            actions.append(back)
            # It is reachable again: whatever it has not acknowledged goes now.
            self._sender.expedite(peer.tx, now, actions)
            self._sender.expedite(self._broadcasts.tx, now, actions)

    def _acked(
        self,
        peer: Peer,
        upto: int,
        bupto: int,
        nack: bool,
        now: float,
        actions: list[SessionEffect],
    ) -> None:
        self.counters.acks_received += 1
        acked = self._sender.acknowledged(peer, upto, now)
        triggers = tuple(
            (m.src_node, m.dst_node, m.iteration) for m in acked if isinstance(m, wire.Trigger)
        )
        if triggers:
            actions.append(Deliver(TriggersAcknowledged(peer.name, triggers)))
        self._broadcasts.acknowledged(peer, bupto, self._peers.values())
        if nack:
            self._sender.nacked(peer, self._broadcasts, now, actions)

    def _heartbeat(
        self, peer: Peer, hb: wire.Heartbeat, now: float, actions: list[SessionEffect]
    ) -> None:
        if hb.leaving:
            left = self._live.goodbye(peer)
            if left is not None:
                actions.append(left)
                self._broadcasts.prune(self._peers.values())  # its acks are not waited for
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

    def on_batch_end(self, now: float) -> list[SessionEffect]:
        """The end of a receive batch: the explicit Acks it called for (gaps, duplicates)."""
        if self.closed:
            return []  # nothing may follow the goodbye heartbeat
        return self._receiver.acks(now)

    def on_receive_stall(self, stalled_s: float, now: float) -> None:
        """One turn of the receive loop took ``stalled_s``: not the peers' silence."""
        self._live.receive_stalled(now, self._peers.values(), stalled_s)

    def on_subscription(self, topic: bytes, now: float) -> list[SessionEffect]:
        """A peer (re)subscribed to ``topic``: what the socket dropped meanwhile goes now."""
        actions: list[SessionEffect] = []
        if topic == wire.TOPIC_ALL:
            self._sender.expedite(self._broadcasts.tx, now, actions)
        elif topic.startswith(b"to/"):
            peer = self._peers.get(topic[3:].decode("utf-8", "replace"))
            if peer is not None:
                peer.tx.backoff = peer.rto
                self._sender.expedite(peer.tx, now, actions)
        elif topic == wire.topic_telemetry(self.name):
            actions += self._tel.repeat(now)  # a new subscriber gets the latest value
        return actions

    # -- time ------------------------------------------------------------------------

    def on_tick(self, now: float) -> tuple[list[SessionEffect], float]:
        """Do what is due at ``now``; return the actions and when to be called next."""
        s = self.settings
        actions: list[SessionEffect] = []
        peers = self._peers.values()
        self._live.stalled(now, peers, self.counters, self._broadcasts.tx)  # late: our stall
        if now >= self._hb_due:
            self._hb_due = now + s.heartbeat_s
            actions.append(Send(self._heartbeat_message(leaving=False)))
        deadline = self._hb_due
        for peer in peers:
            # One peer's timers: retransmission, then liveness and telemetry staleness.
            deadline = min(deadline, self._sender.link_timer(peer, now, actions))
            deadline = min(deadline, self._live.check(peer, now, actions))
        deadline = min(
            deadline, self._sender.broadcast_timer(self._broadcasts, peers, now, actions)
        )
        sent, due = self._tel.tick(now)
        actions += sent
        self._live.tick_due = due = min(deadline, due)
        return actions, due

    def _heartbeat_message(self, leaving: bool) -> wire.Heartbeat:
        self.counters.heartbeats_sent += 1
        bsent, peers = self._broadcasts.sent, self._peers.values()
        return heartbeat(self.mission, self.name, self.incarnation, peers, bsent, leaving)

    # -- results and shutdown --------------------------------------------------------

    def close(self) -> list[SessionEffect]:
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
        if only is None and not self._broadcasts.flushed(self._peers.values()):
            return False
        return all(
            not p.tx.pending or p.state == "left"
            for p in self._peers.values()
            if only is None or p.name in only
        )

    def unacked(self) -> int:
        """Reliable messages sent and not acknowledged yet."""
        pending = sum(len(p.tx.pending) for p in self._peers.values())
        return pending + len(self._broadcasts.tx.pending)

    def peer_stats(self) -> dict[str, dict[str, Any]]:
        """Per peer: state (``unwatched`` if its heartbeats are not followed), RTT, counts."""
        return {p.name: p.stats() for p in self._peers.values()}
