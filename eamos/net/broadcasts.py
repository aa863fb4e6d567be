"""This participant's broadcasts in the reliable-delivery protocol: Start, Abort, Complete.

A broadcast goes to every peer on one sequence of this participant's
(:data:`~eamos.net.wire.RELIABLE_BROADCAST`), and each peer acknowledges it on its own
(``bupto`` in an Ack, ``backs`` in a heartbeat).  Pure: no thread, socket or clock.
"""

from __future__ import annotations

from collections.abc import Iterable

from eamos.net.sequence import Peer, Sending

__all__ = ["Broadcasts"]


class Broadcasts:
    """One sequence for every peer, kept until every peer still here acknowledged it.

    A peer that said goodbye (``left``) is not waited for; a message is resent after
    the slowest peer still here (:meth:`slowest`), or to one peer that nacked.
    """

    def __init__(self, rto_initial_s: float) -> None:
        self.tx = Sending(backoff=rto_initial_s)

    @property
    def sent(self) -> int:
        """The highest seq sent so far (0: none)."""
        return self.tx.next_seq - 1

    @staticmethod
    def still_here(peers: Iterable[Peer]) -> list[Peer]:
        """The peers a broadcast waits for: all but those that left."""
        return [p for p in peers if p.state != "left"]

    def acknowledged(self, peer: Peer, bupto: int, peers: Iterable[Peer]) -> None:
        """``peer`` has every broadcast up to ``bupto``; forget what all now have."""
        if bupto > peer.acked_b:
            peer.acked_b = bupto
            self.prune(peers)

    def prune(self, peers: Iterable[Peer]) -> None:
        """Forget the broadcasts every peer still here acknowledged."""
        acked = min((p.acked_b for p in self.still_here(peers)), default=self.sent)
        self.tx.acknowledge(acked, None)
        if not self.tx.pending:
            self.tx.due = None

    def slowest(self, peers: Iterable[Peer]) -> int:
        """What the slowest peer still here acknowledged (with none: nothing is resent)."""
        return min((p.acked_b for p in self.still_here(peers)), default=self.tx.next_seq)

    def behind(self, peer: Peer) -> bool:
        """Whether ``peer`` lacks broadcasts that are still kept."""
        return bool(self.tx.pending) and peer.acked_b < self.sent

    def flushed(self, peers: Iterable[Peer]) -> bool:
        """Whether every peer still here acknowledged every broadcast."""
        return not (self.tx.pending and self.still_here(peers))
