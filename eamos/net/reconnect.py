"""Reconnecting an In-Bridge's peer sockets where libzmq would not, or not soon enough.

Owned by the In-Bridge's receive thread (every method runs there, as the
sockets do).  Two cases:

* after a protocol error (an oversized frame, a failed handshake) libzmq never
  reconnects: :meth:`Reconnector.disconnected` schedules our own reconnect for
  when libzmq has not started its own retry within :data:`RECONNECT_GRACE_S`,
  and then at most every :data:`~eamos.net.sockets.RECONNECT_IVL_MAX_MS`;
* a peer that subscribed to our Out-Bridge is up, but libzmq's backed-off
  retry (0.1, 0.3, 0.7 s...) may be far off: :meth:`Reconnector.hurry`
  connects now if the socket never connected.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from typing import Any

import zmq

from eamos.net.sockets import RECONNECT_IVL_MAX_MS, Monitor, should_log

__all__ = ["RECONNECT_GRACE_S", "Reconnector"]

#: After a disconnect, how long the bridge leaves libzmq to start its own
#: reconnect (it retries within RECONNECT_IVL_MS after a normal disconnect)
#: before it reconnects the socket itself.
RECONNECT_GRACE_S = 0.5


class Reconnector:
    """The reconnections a receive thread owes (peer -> when) and made (peer -> when)."""

    def __init__(self, peers: Mapping[str, str], log: Any) -> None:
        self.peers = peers
        self.sockets: dict[str, zmq.Socket[Any]] = {}
        self.monitors: dict[str, Monitor] = {}
        self._log = log
        self._due: dict[str, float] = {}
        self._at: dict[str, float] = {}
        self.reconnects = 0

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
            due = max(now + RECONNECT_GRACE_S, last + RECONNECT_IVL_MAX_MS / 1e3)
            self._due.setdefault(peer, due)

        return schedule

    def retrying(self, peer: str) -> Callable[[], None]:
        """The monitor's callback for libzmq's own retry of ``peer``."""

        def cancel() -> None:
            self._due.pop(peer, None)  # libzmq is on it

        return cancel

    def poll_timeout_ms(self) -> int | None:
        """How long the receive thread may wait for messages before a reconnect is due."""
        if not self._due:
            return None  # nothing owed: wait for messages only
        wait = min(self._due.values()) - time.monotonic()
        return max(0, int(wait * 1e3) + 1)

    def reconnect_due(self) -> None:
        """Reconnect every peer whose time has come."""
        if not self._due:
            return
        now = time.monotonic()
        for peer, due in list(self._due.items()):
            if due > now:
                continue
            del self._due[peer]
            self._reconnect(peer, now)
            self.reconnects += 1
            if should_log(self.reconnects):
                self._log.info(
                    "net.in.reconnect",
                    peer=peer,
                    endpoint=self.peers[peer],
                    count=self.reconnects,
                )

    def hurry(self, peer: str) -> None:
        """``peer`` is up (it subscribed to us): connect now if the socket never connected."""
        sub, monitor = self.sockets.get(peer), self.monitors.get(peer)
        if sub is None or monitor is None:
            return
        monitor.drain()
        if monitor.connections:
            return  # connected once: libzmq's own reconnection (or ours) handles it
        if self.peers[peer].startswith("inproc://"):
            # inproc connects at once (no retry to hurry) and its monitor reports no
            # connection: cutting a live inproc session trips libzmq (fq.cpp !_more).
            return
        self._reconnect(peer, time.monotonic())

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
