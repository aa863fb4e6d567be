"""Incarnations: telling a restarted participant from its predecessor, and resynchronising.

Each :class:`~eamos.net.session.ReliableSession` has an *incarnation*, a number
drawn once per process (its start time in microseconds, then random bits), and
stamps it on every message it sends (wire key ``n``).  A node killed and
started again with the same config has the same name and keys but a new, larger
incarnation, and it remembers nothing: its sequence numbers start again at 1
and it has received nothing.  Without incarnations its peers would take its
new messages for duplicates of the old ones, and would never resend what its
predecessor had acknowledged (the triggers it waits for, the ground station's
Start), so it could neither rejoin nor obey an Abort.

When a message shows a peer with a larger incarnation than known,
:func:`resynchronise` makes the session treat it as the new participant it is:

* its sequence spaces start afresh (link and broadcasts: nothing it sends is
  a duplicate);
* everything ever sent to it -- the link's history and this participant's
  broadcasts -- is unacknowledged again and resent at once, in order, so it
  receives the Start, every trigger and any Abort it missed;
* its telemetry clock starts again; a peer that had said goodbye is up again;
* ``mission.peer.restarted`` is logged and reported (a ``PeerStatus`` with
  state ``restarted``, which the ground station shows).

A message of a smaller incarnation (the predecessor's, still in flight) is
dropped.  Acknowledgements name the incarnation they are for (``di`` in an
Ack, ``ki`` in a heartbeat): a restarted participant ignores those meant for
its predecessor, which would otherwise acknowledge messages it never sent.
Pure: no clock (``now`` is passed in), no randomness but the draw at start.
"""

from __future__ import annotations

import os
import time

from eamos.net.effects import SessionEffect, Wake
from eamos.net.liveness import Liveness
from eamos.net.sequence import Peer, Receiving, Sending, SessionCounters

__all__ = ["admit", "mine", "new_incarnation", "resynchronise"]

_RANDOM_BITS = 8


def new_incarnation() -> int:
    """This process's incarnation: larger than any earlier process's (wall clock, µs).

    Random low bits tell apart two processes started in the same microsecond.
    About 2**59 today: within the wire format's 63-bit sequence numbers.
    """
    micros = time.time_ns() // 1000
    # The source ``secrets`` draws from, without importing it (and hmac, hashlib) at start.
    drawn = int.from_bytes(os.urandom(_RANDOM_BITS // 8), "big")
    return (micros << _RANDOM_BITS) | drawn | 1


def admit(
    peer: Peer,
    incarnation: int,
    broadcasts: Sending,
    live: Liveness,
    counters: SessionCounters,
    now: float,
    effects: list[SessionEffect],
) -> bool:
    """A message of ``incarnation`` (not the known one) came from ``peer``: take it?

    0 (a message sent outside a session) and the first incarnation heard are
    taken as they are; a larger one is a restart (:func:`resynchronise`, its
    effects appended to ``effects``); a smaller one is its predecessor's: False.
    """
    if not incarnation:
        return True
    if incarnation < peer.incarnation:
        counters.old_incarnation += 1
        return False
    if peer.incarnation:
        counters.restarts += 1
        effects += resynchronise(peer, incarnation, broadcasts, live, now)
    peer.incarnation = incarnation
    return True


def mine(own: int, acknowledged: int | None) -> bool:
    """Whether acknowledgements for incarnation ``acknowledged`` are for ``own`` (0: unknown)."""
    return not acknowledged or acknowledged == own


def resynchronise(
    peer: Peer, incarnation: int, broadcasts: Sending, live: Liveness, now: float
) -> list[SessionEffect]:
    """``peer`` restarted as ``incarnation``: start its sequences afresh, resend it everything.

    Returns the effects: the ``restarted`` peer event and a wake-up now for the
    retransmissions.
    """
    previous = peer.incarnation
    peer.incarnation = incarnation
    peer.rx = Receiving()
    peer.brx = Receiving()
    peer.acked_b = 0
    peer.ack_now = peer.nack = False
    peer.tel_time = None  # its clock (and the simulator's) started again
    if peer.state == "left":
        peer.state = "up"  # its predecessor said goodbye; this one is here
    peer.tx.replay(now)
    peer.tx.backoff = peer.rto
    broadcasts.replay(now)
    live.log.warning(
        "net.peer.restarted",
        peer=peer.name,
        incarnation=incarnation,
        previous=previous,
        resent=len(peer.tx.pending),
        broadcasts=len(broadcasts.pending),
    )
    silent = 0.0 if peer.heard is None else now - peer.heard
    return [live.event(peer, "restarted", silent), Wake(now)]
