"""Waiting on many ZeroMQ sockets at a cost that grows with the sockets ready, not watched.

``zmq_poll`` looks at every socket it is given on every call: an In-Bridge of a
fan-in endpoint (the ground station, a drone every other waits for) watches a SUB
socket and a monitor per peer, so each wake-up, one message or a hundred, cost a
walk over 2N + 1 sockets.  :class:`SocketWatch` waits instead on each socket's
``ZMQ_FD`` with the operating system's selector (epoll on Linux) and asks
``ZMQ_EVENTS`` only of the sockets whose descriptor fired, as libzmq documents
for integrating its sockets into another event loop (``zmq_getsockopt``,
``ZMQ_FD``; the way pyzmq's own asyncio sockets wait):

* the descriptor only *signals* that the socket's state may have changed; the
  socket is readable when ``ZMQ_EVENTS`` has ``POLLIN``;
* the signal is edge-like: reading the socket (or asking ``ZMQ_EVENTS``)
  consumes it, so messages already queued when the watch starts, or left
  behind by a bounded drain, raise no new signal.  Every socket is therefore
  checked once when added, and a caller that stops draining a readable socket
  says so (:meth:`SocketWatch.again`) so it is checked without waiting.

Owned by one thread (ZeroMQ sockets are): the bridge thread that reads them.
"""

from __future__ import annotations

import selectors
from typing import Any

import zmq

__all__ = ["SocketWatch"]

_EVENTS = zmq.EVENTS
_POLLIN = int(zmq.POLLIN)


class SocketWatch:
    """The readable ones of a set of ZeroMQ sockets, found through their descriptors."""

    def __init__(self) -> None:
        self._selector = selectors.DefaultSelector()
        self._unchecked: set[zmq.Socket[Any]] = set()

    def add(self, sock: zmq.Socket[Any]) -> None:
        """Watch ``sock`` (checked at the next :meth:`wait`, for what is queued already)."""
        fd = sock.getsockopt(zmq.FD)
        assert isinstance(fd, int)  # pyzmq types every option as int | bytes
        self._selector.register(fd, selectors.EVENT_READ, sock)
        self._unchecked.add(sock)

    def discard(self, sock: zmq.Socket[Any]) -> None:
        """Stop watching ``sock`` (before it closes: its descriptor number may be reused)."""
        self._unchecked.discard(sock)
        fd = sock.getsockopt(zmq.FD)
        assert isinstance(fd, int)
        try:
            self._selector.unregister(fd)
        except KeyError:
            pass  # never added (a member whose addition failed part way)

    def again(self, sock: zmq.Socket[Any]) -> None:
        """``sock`` may still be readable (its drain stopped early): check it without waiting."""
        self._unchecked.add(sock)

    def wait(self, timeout_s: float | None) -> set[zmq.Socket[Any]]:
        """The sockets readable now, waiting at most ``timeout_s`` (None: until one is)
        when none is known to need a look; an empty set on timeout."""
        wait = 0.0 if self._unchecked else timeout_s
        for key, _ in self._selector.select(wait):
            self._unchecked.add(key.data)
        looked, self._unchecked = self._unchecked, set()
        return {s for s in looked if s.getsockopt(_EVENTS) & _POLLIN}  # type: ignore[operator]

    def close(self) -> None:
        """Stop watching (before the sockets close); idempotent."""
        self._selector.close()
