"""Connecting an In-Bridge's peer sockets when libzmq would not, or not yet.

Owned by the In-Bridge's receive thread (every method runs there, as the
sockets do; before the thread starts, by the caller under the bridge's lock).

A peer may be *announced*: its socket connects only when the peer is known to
listen (:meth:`Reconnector.announced`).  The ground station starts first and
waits for every drone; a connection to a drone that is not up yet is refused,
and libzmq retries only every :data:`~eamos.net.sockets.RECONNECT_IVL_MS`, so a
drone that came up just after a refusal waited up to that long for the ground
station's connection, and so for its Ready to count.  Instead, the ground
station connects to a drone when the drone's own connection subscribes to the
ground station's Out-Bridge: then the drone has bound its socket, and the
connection succeeds at once.

After a protocol error (an oversized frame, a failed handshake) libzmq never
reconnects: :meth:`Reconnector.disconnected` schedules our own reconnect for
when libzmq has not started its own retry within :data:`RECONNECT_GRACE_S`, and
then at most every :data:`OWN_RECONNECT_EVERY_S`.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Any

import zmq

from eamos.net.sockets import should_log

if TYPE_CHECKING:
    from eamos.logs import EventLog

__all__ = ["OWN_RECONNECT_EVERY_S", "RECONNECT_GRACE_S", "Reconnector"]

#: After a disconnect, how long the bridge leaves libzmq to start its own
#: reconnect (it retries within RECONNECT_IVL_MS after a normal disconnect)
#: before it reconnects the socket itself.
RECONNECT_GRACE_S = 0.5
#: Our own reconnects of one peer come at most this often (a peer sending oversized
#: frames again and again is not reconnected in a tight loop).
OWN_RECONNECT_EVERY_S = 1.0


class Reconnector:
    """The reconnections a receive thread owes (peer -> when) and made (peer -> when)."""

    def __init__(self, peers: Mapping[str, str], log: EventLog) -> None:
        self.peers = peers
        self.sockets: dict[str, zmq.Socket[Any]] = {}
        self._log = log
        self._due: dict[str, float] = {}
        self._at: dict[str, float] = {}
        self._unannounced: set[str] = set()  # connected when they announce themselves
        self.reconnects = 0

    def connect(self, peer: str, announced: bool = True) -> None:
        """Connect ``peer``'s socket now, or (``announced`` False) when :meth:`announced`."""
        if announced:
            self.sockets[peer].connect(self.peers[peer])
        else:
            self._unannounced.add(peer)

    def announced(self, peer: str) -> None:
        """``peer`` listens (it subscribed to us): connect its socket if it waited for that.

        Later announcements (the peer reconnected) change nothing: libzmq
        reconnects a socket that was connected once.
        """
        if peer not in self._unannounced:
            return
        self._unannounced.discard(peer)
        endpoint = self.peers[peer]
        try:
            self.sockets[peer].connect(endpoint)
        except zmq.ZMQError as exc:  # the receive thread must survive a bad endpoint
            self._log.error("net.in.connect_failed", peer=peer, endpoint=endpoint, error=str(exc))
            return
        self._log.debug("net.in.announced", peer=peer, endpoint=endpoint)

    @property
    def unannounced(self) -> frozenset[str]:
        """Peers whose socket waits for them to announce themselves."""
        return frozenset(self._unannounced)

    def disconnected(self, peer: str) -> Callable[[], None]:
        """The monitor's callback for ``peer``'s disconnect."""

        def schedule() -> None:
            # After a normal disconnect libzmq reconnects by itself (it reports
            # CONNECT_RETRIED, which cancels this); after a protocol error (an
            # oversized frame) it never does.  So wait a little longer than
            # libzmq would before its retry, and reconnect only if it did not;
            # and not again within the maximum reconnect interval.  Cutting a
            # connection libzmq is still using races its receive path.
            now = time.monotonic()
            last = self._at.get(peer, float("-inf"))
            due = max(now + RECONNECT_GRACE_S, last + OWN_RECONNECT_EVERY_S)
            self._due.setdefault(peer, due)

        return schedule

    def retrying(self, peer: str) -> Callable[[], None]:
        """The monitor's callback for libzmq's own retry of ``peer``."""

        def cancel() -> None:
            self._due.pop(peer, None)  # libzmq is on it

        return cancel

    def next_due(self) -> float | None:
        """When the next reconnect is due (monotonic seconds; None: none is owed)."""
        return min(self._due.values()) if self._due else None

    def reconnect_due(self) -> list[str]:
        """Reconnect every peer whose time has come; those reconnected."""
        if not self._due:
            return []
        done: list[str] = []
        now = time.monotonic()
        for peer, due in list(self._due.items()):
            if due > now:
                continue
            del self._due[peer]
            self._reconnect(peer, now)
            done.append(peer)
            self.reconnects += 1
            if should_log(self.reconnects):
                self._log.info(
                    "net.in.reconnect",
                    peer=peer,
                    endpoint=self.peers[peer],
                    count=self.reconnects,
                )
        return done

    def _reconnect(self, peer: str, now: float) -> None:
        # disconnect + connect: a fresh session whatever libzmq did with the old
        # one (after a normal disconnect it would retry; after a protocol error it
        # would not).  Subscriptions are resent on the new connection.
        self._at[peer] = now
        endpoint, sub = self.peers[peer], self.sockets[peer]
        try:
            sub.disconnect(endpoint)
        except zmq.ZMQError:
            pass  # already gone
        sub.connect(endpoint)
