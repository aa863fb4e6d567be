"""The receiving half of the reliable-delivery protocol: each message once, in order, acknowledged.

Per link (sender, dest), and per sender for its broadcasts, the receiver keeps the
highest seq delivered in order; older seqs are duplicates (dropped, counted,
re-acknowledged), later ones wait in a bounded reorder buffer until the gap is filled
(:class:`~eamos.net.sequence.Receiving`).  Steady traffic is acknowledged by this
participant's heartbeats (:func:`~eamos.net.sequence.heartbeat`); an explicit
:class:`~eamos.net.wire.Ack` goes at the end of a receive batch when a peer needs one
now.  Pure: no thread, socket or clock.
"""

from __future__ import annotations

from typing import Final

import eamos.net.wire as wire
from eamos.logs import EventLog
from eamos.net.effects import Deliver, Send, SessionEffect
from eamos.net.sequence import Peer, Receiving, SessionCounters, should_log
from eamos.net.settings import LinkSettings

__all__ = ["NACK_INTERVAL_S", "Receiver"]

_ACK_AT_ONCE: Final = frozenset({wire.Ready, wire.Resolved, wire.Report, wire.ReportPart})
"""Delivered messages acknowledged at once rather than by the next heartbeat: the
final report's sender waits for its ack before it exits; Ready and Resolved reach
the ground station from the whole fleet at once (at the start, at the end), when
its heartbeat is most likely late: one Ack each spares a retransmission each."""

NACK_INTERVAL_S: Final = 0.02
"""At most one nack per peer per this interval: after a gap, every later arrival
would otherwise ask for the same messages again."""


class Receiver:
    """Delivers sequenced messages exactly once and in order; owes the explicit Acks.

    An Ack is owed when a message came after a gap (a nack: the sender resends the
    rest, at most one per :data:`NACK_INTERVAL_S`), when a duplicate came (the sender
    is retransmitting, so it lacks the ack) or when a message whose sender waits
    for it was delivered (:data:`_ACK_AT_ONCE`).  They go at the end of the receive
    batch (:meth:`acks`), one per peer.
    """

    def __init__(
        self,
        name: str,
        mission: str,
        incarnation: int,
        settings: LinkSettings,
        counters: SessionCounters,
        log: EventLog,
    ) -> None:
        self.name = name
        self.mission = mission
        self.incarnation = incarnation
        self.settings = settings
        self.counters = counters
        self.log = log
        self._owed: dict[str, Peer] = {}  # peers whose ack_now was set since the last batch

    def accept(
        self, peer: Peer, msg: wire.Message, rx: Receiving, actions: list[SessionEffect]
    ) -> None:
        """``msg`` (seq > 0) arrived on ``rx``, one of ``peer``'s sequences: deliver what may go."""
        got = rx.accept(msg, self.settings.reorder_limit)
        if got is None:
            peer.ack_now = True  # the sender is retransmitting: it lacks our ack
            self.counters.duplicates_dropped += 1
            peer.duplicates += 1
            if should_log(peer.duplicates):
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

    def owe(self, peer: Peer) -> None:
        """Remember ``peer`` if what came from it in this batch calls for an Ack."""
        if peer.ack_now:
            self._owed[peer.name] = peer

    def acks(self, now: float) -> list[SessionEffect]:
        """The end of a receive batch: the explicit Acks it called for (gaps, duplicates)."""
        # Only the peers this batch called for: the ground station has the whole fleet.
        owed, self._owed = self._owed, {}
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
