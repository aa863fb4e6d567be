"""Per-peer bookkeeping of the reliable-delivery protocol: the sending and receiving halves.

A link (sender, dest), or one participant's broadcasts, has a :class:`Sending`
half at its sender (numbering, the messages waiting for their ack, the
retransmission timer) and a :class:`Receiving` half at each receiver (the
highest seq delivered in order, the reorder buffer).  :class:`Peer` holds
both halves of the links with one peer, its round-trip time and liveness.
Pure data with the arithmetic on it; :class:`~eamos.net.session.ReliableSession`
decides when.
"""

from __future__ import annotations

import random
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any, Final

from msgspec.structs import replace

import eamos.net.wire as wire
from eamos.net.settings import LinkSettings

__all__ = [
    "HEARTBEAT_ACK_REPEATS",
    "Peer",
    "Receiving",
    "Sending",
    "SessionCounters",
    "heartbeat",
    "should_log",
]

HEARTBEAT_ACK_REPEATS: Final = 3
"""A link's acknowledgements ride on this many heartbeats after they last changed
(then no more: a heartbeat carries news, not the whole fleet).  The retransmission
timeout is at least two heartbeats, so the sender normally has one of them first."""


@dataclass
class SessionCounters:
    """What the protocol did, for the run summary (``report()["net"]``)."""

    retransmissions: int = 0
    duplicates_dropped: int = 0
    reordered: int = 0
    acks_sent: int = 0
    nacks_sent: int = 0
    acks_received: int = 0
    heartbeats_sent: int = 0
    old_telemetry: int = 0
    abandoned: int = 0  # unacknowledged messages given up because their peer left
    restarts: int = 0  # peers seen with a new incarnation (a restarted process)
    old_incarnation: int = 0  # messages of a predecessor of a restarted peer, dropped
    late_ticks: int = 0  # timer calls this participant's own stalled loop made late
    stalled_s: float = 0.0  # their lateness, summed: not counted as the peers' silence


# Retransmissions and duplicates are logged one by one up to this count per
# peer, then every _LOG_EVERY-th: a long partition must not flood the log.
_LOG_FIRST: Final = 20
_LOG_EVERY: Final = 500


def should_log(count: int) -> bool:
    """Whether the ``count``-th retransmission (or duplicate) of a peer gets its log line."""
    return count <= _LOG_FIRST or count % _LOG_EVERY == 0


@dataclass
class _Out:
    """One reliable message waiting for its acknowledgement."""

    msg: wire.Message
    first_sent: float
    last_sent: float
    tries: int = 0  # retransmissions so far


@dataclass
class Sending:
    """The sending side of one link (or of this participant's broadcasts)."""

    backoff: float
    next_seq: int = 1
    pending: dict[int, _Out] = field(default_factory=dict)  # insertion order = seq order
    due: float | None = None  # when the retransmission timer fires
    # Every message sent, for a receiver that restarts and lost them all.  A few
    # hundred bytes per trigger, kept for the mission (as the node's records are).
    history: dict[int, wire.Message] = field(default_factory=dict)

    def number(self, msg: wire.Message, now: float, incarnation: int = 0) -> wire.Message:
        """``msg`` with the next seq (and the sender's ``incarnation``), kept until acknowledged."""
        seq = self.next_seq
        self.next_seq += 1
        numbered = replace(msg, seq=seq, incarnation=incarnation)
        self.pending[seq] = _Out(numbered, now, now)
        self.history[seq] = numbered
        return numbered

    def replay(self, now: float) -> None:
        """Everything ever sent is unacknowledged again, due now: a receiver restarted.

        Replayed messages count as retransmissions (``tries`` 1): they measure no
        round trip (Karn).
        """
        pending = self.pending
        self.pending = {
            seq: pending.get(seq) or _Out(msg, now, now, tries=1)
            for seq, msg in self.history.items()
        }
        if self.pending:
            self.due = now

    def acknowledge(self, upto: int, now: float | None) -> tuple[list[wire.Message], float | None]:
        """Forget every seq <= ``upto``: (the messages forgotten, a round-trip sample or None).

        Karn: only a message sent once measures the round trip (``now`` None: no sample).
        """
        sample: float | None = None
        acked: list[wire.Message] = []
        pending = self.pending
        while pending:
            seq = next(iter(pending))
            if seq > upto:
                break
            out = pending.pop(seq)
            acked.append(out.msg)
            if out.tries == 0 and now is not None:
                sample = now - out.first_sent
        return acked, sample

    def resend(
        self, now: float, window: int, *, recent: float = 0.0, after: int = 0
    ) -> list[wire.Message]:
        """Up to ``window`` unacknowledged messages with seq > ``after`` to send again.

        Messages sent within the last ``recent`` seconds are skipped (a nack
        may race with messages still in flight).
        """
        again: list[wire.Message] = []
        for seq, out in self.pending.items():
            if seq <= after:
                continue
            if len(again) >= window:
                break
            if recent and now - out.last_sent < recent:
                continue
            out.tries += 1
            out.last_sent = now
            again.append(out.msg)
        return again

    def back_off(self, now: float, rto_max: float, rng: random.Random) -> None:
        """After a timeout: double the timeout (up to ``rto_max``, +-20 % jitter)."""
        if not self.pending:
            self.due = None
            return
        self.backoff = min(self.backoff * 2, rto_max)
        self.due = now + self.backoff * rng.uniform(0.8, 1.2)


@dataclass
class Receiving:
    """The receiving side of one sequence: a link's, or one peer's broadcasts."""

    upto: int = 0  # every seq <= upto was delivered, in order
    buffer: dict[int, wire.Message] = field(default_factory=dict)  # arrived early

    def accept(self, msg: wire.Message, limit: int) -> list[wire.Message] | None:
        """``msg`` (with ``seq`` > 0) arrived: what may be delivered now, in order.

        None: a duplicate.  ``[]``: it came after a gap and waits in the buffer
        (at most ``limit`` wait; beyond, the sender resends it later).
        """
        seq: int = msg.seq  # type: ignore[union-attr]
        if seq <= self.upto or seq in self.buffer:
            return None
        if seq > self.upto + 1:
            if len(self.buffer) < limit:
                self.buffer[seq] = msg
            return []
        got = [msg]
        upto = seq
        while upto + 1 in self.buffer:
            upto += 1
            got.append(self.buffer.pop(upto))
        self.upto = upto
        return got


@dataclass
class Peer:
    """Everything this participant knows about one peer."""

    name: str
    tx: Sending
    rto: float
    watched: bool = True  # its heartbeats are followed: it can be lost, back, left
    incarnation: int = 0  # of the peer's process, from its messages (0: not heard yet)
    rx: Receiving = field(default_factory=Receiving)  # the link peer -> me
    brx: Receiving = field(default_factory=Receiving)  # the peer's broadcasts
    acked_b: int = 0  # my broadcasts this peer acknowledged
    ack_now: bool = False  # an explicit Ack at the end of this receive batch
    nack: bool = False
    last_nack: float = float("-inf")
    state: str = "unknown"  # unknown | up | lost | left
    heard: float | None = None
    # Receive-loop stalls credited to its silence since it was last heard (bounded).
    forgiven_s: float = 0.0
    srtt: float | None = None
    rttvar: float = 0.0
    tel_time: float | None = None  # sample time of the latest telemetry from it
    tel_heard: float | None = None
    tel_stale: bool = False
    retransmitted: int = 0
    duplicates: int = 0
    # The acknowledgements last shown on heartbeats (rx.upto, brx.upto, incarnation)
    # and how many more heartbeats show them: see ReliableSession._heartbeat_message.
    shown_acks: tuple[int, int, int] = (0, 0, 0)
    ack_repeats: int = 0

    def stats(self) -> dict[str, Any]:
        """State (``unwatched`` if its heartbeats are not followed), RTT, counts."""
        return {
            "state": self.state if self.watched else "unwatched",
            "rtt_ms": None if self.srtt is None else round(self.srtt * 1e3, 3),
            "retransmitted": self.retransmitted,
            "duplicates": self.duplicates,
        }

    def measure(self, sample: float, s: LinkSettings) -> None:
        """Fold a round-trip sample into the RTO (Jacobson)."""
        if self.srtt is None:
            self.srtt, self.rttvar = sample, sample / 2
        else:
            self.rttvar = 0.75 * self.rttvar + 0.25 * abs(self.srtt - sample)
            self.srtt = 0.875 * self.srtt + 0.125 * sample
        self.rto = min(max(self.srtt + 4 * self.rttvar, s.rto_min_s), s.rto_max_s)

    def in_flight_window(self, s: LinkSettings) -> float:
        """How recently sent a message may still be on its way (not resent on a nack)."""
        if self.srtt is None:
            return s.rto_min_s
        return max(0.005, 1.5 * self.srtt)


def heartbeat(
    mission: str, name: str, incarnation: int, peers: Iterable[Peer], bsent: int, leaving: bool
) -> wire.Heartbeat:
    """``name``'s heartbeat, naming only the links with news: its size follows the traffic.

    ``sent`` lists the links with messages not yet acknowledged (a receiver of
    an acknowledged link has everything); ``acks``/``backs``/``known`` a peer's
    acknowledgements for :data:`HEARTBEAT_ACK_REPEATS` heartbeats after they
    last changed (counted here: call it once per heartbeat sent).  A heartbeat
    naming every peer grew with the fleet on every receiver (the ground
    station's reached every drone).  Should all the repeats be lost, the sender
    retransmits and the duplicate is acknowledged at once.
    """
    sent: dict[str, int] = {}
    acks: dict[str, int] = {}
    backs: dict[str, int] = {}
    known: dict[str, int] = {}
    for p in peers:
        if p.tx.pending:
            sent[p.name] = p.tx.next_seq - 1
        shown = (p.rx.upto, p.brx.upto, p.incarnation)
        if shown != p.shown_acks:
            p.shown_acks, p.ack_repeats = shown, HEARTBEAT_ACK_REPEATS
        if p.ack_repeats > 0 and (p.rx.upto or p.brx.upto):
            p.ack_repeats -= 1
            if p.rx.upto:
                acks[p.name] = p.rx.upto
            if p.brx.upto:
                backs[p.name] = p.brx.upto
            known[p.name] = p.incarnation
    return wire.Heartbeat(
        mission, name, sent, bsent, leaving, acks, backs, known, incarnation=incarnation
    )
