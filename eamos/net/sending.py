"""The sending half of the reliable-delivery protocol: numbering, and resending what is lost.

Each reliable message gets the next seq of its sequence (a link's, or this
participant's broadcasts') and is kept until acknowledged
(:class:`~eamos.net.sequence.Sending`).  What is lost in a known way is resent at
once: when the peer (re)subscribes, when it is heard again after silence, and on a
nack.  The safety net is a timer per sequence: after the retransmission timeout
(RTO: smoothed round-trip time + 4 deviations, clamped to ``[rto_min_s, rto_max_s]``,
Jacobson/Karn) the unacknowledged messages are resent, the timeout doubling up to
``rto_max_s`` with +-20 % jitter, until acknowledged.  A timer that comes due while
this machine runs late waits a grace in proportion (``grace``: the session's
:meth:`~eamos.net.liveness.Liveness.margin_s`, the margin its liveness deadlines get):
the receiver, as busy, acknowledges as late, and resending then repeats what arrived.
Pure: time is passed in.
"""

from __future__ import annotations

import random
from collections.abc import Callable, Iterable
from typing import Final

import eamos.net.wire as wire
from eamos.logs import EventLog
from eamos.net.broadcasts import Broadcasts
from eamos.net.effects import Send, SessionEffect, Wake
from eamos.net.sequence import Peer, Sending, SessionCounters, should_log
from eamos.net.settings import LinkSettings

__all__ = ["Sender"]

_NEVER: Final = float("inf")

Grace = Callable[[float, float], float]
"""``(timeout_s, now)``: how much longer a retransmission timeout of so many seconds waits
at ``now``, the machine as busy as it is (:meth:`eamos.net.liveness.Liveness.margin_s`)."""


class Sender:
    """Numbers reliable messages and decides when the unacknowledged ones go again.

    It works on the :class:`~eamos.net.sequence.Sending` half of each link and of the
    broadcasts; ``rng`` draws the back-off's jitter, ``grace`` the load's margin.
    """

    def __init__(
        self,
        settings: LinkSettings,
        counters: SessionCounters,
        log: EventLog,
        rng: random.Random,
        grace: Grace,
    ) -> None:
        self.settings = settings
        self.counters = counters
        self.log = log
        self._rng = rng
        self._grace = grace

    def send(
        self, tx: Sending, msg: wire.Message, now: float, incarnation: int
    ) -> list[SessionEffect]:
        """Number ``msg`` on ``tx`` and send it; start ``tx``'s timer if it was idle."""
        numbered = tx.number(msg, now, incarnation)
        if tx.due is None:
            tx.due = now + tx.backoff
            return [Send(numbered), Wake(tx.due)]
        return [Send(numbered)]

    def acknowledged(self, peer: Peer, upto: int, now: float) -> list[wire.Message]:
        """``peer`` has everything up to ``upto`` on our link: a round-trip sample (Karn),
        and the timer restarted from the RTO (stopped when nothing is left).  The
        messages it acknowledged now."""
        tx = peer.tx
        acked, sample = tx.acknowledge(upto, now)
        if sample is not None:
            peer.measure(sample, self.settings)
        if acked:
            tx.backoff = peer.rto
            tx.due = now + peer.rto if tx.pending else None
        return acked

    def nacked(
        self, peer: Peer, broadcasts: Broadcasts, now: float, actions: list[SessionEffect]
    ) -> None:
        """``peer`` saw a gap: resend what it lacks, of the link and of the broadcasts."""
        # Not what is probably still in flight (sent within about a round trip).
        recent = peer.in_flight_window(self.settings)
        self.resend(peer, peer.tx, now, actions, recent=recent)
        if broadcasts.behind(peer):
            self.resend(None, broadcasts.tx, now, actions, recent=recent, after=peer.acked_b)

    def expedite(self, tx: Sending, now: float, actions: list[SessionEffect]) -> None:
        """Resend ``tx``'s unacknowledged messages now (the peer is reachable again)."""
        if tx.pending:
            tx.due = now
            actions.append(Wake(now))

    def link_timer(self, peer: Peer, now: float, actions: list[SessionEffect]) -> float:
        """``peer``'s link timer at ``now``: resend if due, the load's grace included (or
        give up: it left); when it is due next."""
        tx = peer.tx
        if tx.due is None:
            return _NEVER
        if peer.state == "left":
            if now < tx.due:
                return tx.due
            self.counters.abandoned += len(tx.pending)
            tx.pending.clear()
            tx.due = None
            return _NEVER
        waits = tx.due + self._grace(tx.backoff, now)
        if now < waits:
            return waits
        self.resend(peer, tx, now, actions)
        tx.back_off(now, self.settings.rto_max_s, self._rng)
        return _NEVER if tx.due is None else tx.due

    def broadcast_timer(
        self,
        broadcasts: Broadcasts,
        peers: Iterable[Peer],
        now: float,
        actions: list[SessionEffect],
    ) -> float:
        """The broadcasts' timer at ``now``: resend past the slowest peer if due, the load's
        grace included; when it is due next."""
        btx = broadcasts.tx
        if btx.due is not None:
            waits = btx.due + self._grace(btx.backoff, now)
            if now < waits:
                return waits
            self.resend(None, btx, now, actions, after=broadcasts.slowest(peers))
            btx.back_off(now, self.settings.rto_max_s, self._rng)
        return _NEVER if btx.due is None else btx.due

    def resend(
        self,
        peer: Peer | None,
        tx: Sending,
        now: float,
        actions: list[SessionEffect],
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
        if should_log(count):
            self.log.info(
                "net.link.retransmit",
                peer=peer.name if peer is not None else "*",
                messages=sent,
                first_seq=next(iter(tx.pending)),
                total=count,
            )
