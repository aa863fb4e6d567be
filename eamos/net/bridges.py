"""Out-Bridge and In-Bridge (the paper's names): the sockets between participants.

Code: :mod:`eamos.net.out_bridge` (:class:`OutBridge`), :mod:`eamos.net.in_bridge`
(:class:`InBridge`), :mod:`eamos.net.sockets` (socket options, CURVE set-up,
control pipes, handshake monitors); this module names what others use.

Each participant (drone or ground station) owns exactly one :class:`OutBridge`
(an XPUB socket it binds; everything it sends leaves through it) and one
:class:`InBridge` (one SUB socket connected to the Out-Bridges of its peers).

Threading model
---------------
ZeroMQ sockets must not be used by two threads at once; a socket may change
threads behind a full memory barrier (a lock).  So:

* ``OutBridge.send`` may be called from any thread.  It encodes the message in
  the caller's thread (so a bad message raises :class:`~eamos.net.wire.WireError`
  at the caller), then, under the bridge's lock, writes the frames to the XPUB
  socket itself: no hand-over to another thread, which cost every message a
  context switch.  The bridge thread polls the socket's descriptor
  (``ZMQ_FD``, safe to poll from any thread) and reads the subscription frames
  under the same lock; since ``ZMQ_FD`` is edge-triggered, a sender that finds
  a subscription frame waiting after its send wakes the thread through an
  in-process PAIR pipe.  Messages from one thread leave in the order they were
  sent, and ``send`` never blocks (XPUB drops at the high-water mark instead).
* ``InBridge``'s sockets (a SUB socket and a monitor per peer) are read by one
  receive thread (:class:`~eamos.net.receive_host.ReceiveHost`): a thread of its
  own for a participant alone in its process, or the one thread that reads every
  In-Bridge of the drones sharing a process.  ``add_subscription``, ``announce``
  and ``close`` are requests queued to that thread (a control PAIR pipe wakes
  it).  ``on_message`` is called on that thread, so it should hand work off
  quickly (e.g. to an actor's mailbox) rather than block; a bridge whose own
  sockets fail leaves the thread, the others read on.

Lifecycle
---------
Construct (binds/connects and subscribes), ``start()`` (starts the thread, or
hands the In-Bridge to its receive thread), use, ``close()`` (idempotent, never
blocks for long: sockets are closed with a small linger by the thread that owns
them, which the caller waits for with a timeout).
Both bridges are also context managers (``with OutBridge(...) as out:``).
Closing sockets never blocks in ZeroMQ; only ``Context.term()`` waits for up to
the linger time to flush messages still queued to peers, which is what lets a
final Abort or Complete get out before the process exits.

Security
--------
With ``curve=`` (a :class:`~eamos.net.keys.FleetKeys`) the Out-Bridge is a
CURVE server (ZAP domain :func:`~eamos.net.zap.participant_domain`, enforced: a
context without a ZAP handler admits nobody; the participants of one context
share its handler, :class:`~eamos.net.zap.ZapHandler`) and the In-Bridge opens one CURVE
client socket per peer, each knowing that peer's public key, so a message read
from a socket comes from that peer.  With ``check_sender=True`` the In-Bridge
also drops messages whose ``sender`` is not the peer of the socket they came
in on (a fleet member impersonating another).  Without ``curve`` the sockets
are plain; *whether* plain is allowed is decided above (config, runtime), see
:func:`eamos.net.keys.plain_refusal`.  Failed handshakes (wrong keys, a plain
peer meeting a CURVE one) are seen through ZeroMQ socket monitors and logged
as ``net.auth.failed``; unknown keys refused by ZAP as ``net.auth.denied``.

Reliability (sequence numbers, acks, retransmission, heartbeats) lives one
level up, in :mod:`eamos.net.session` (the protocol), driven by
:mod:`eamos.net.link` through :mod:`eamos.net.transport`; the driver uses
``on_subscription`` and ``on_batch_end`` to react to reconnections and to
acknowledge in batches.

Connections: ZeroMQ heartbeats (``heartbeat_ms``) drop a connection whose
peer went silent, and connection attempts time out after
``CONNECT_TIMEOUT_MS``, so a link that comes back is reconnected within about
a second instead of waiting for TCP's own back-off.
"""

from __future__ import annotations

from eamos.net.in_bridge import InBridge
from eamos.net.out_bridge import OutBridge
from eamos.net.sockets import (
    CONNECT_TIMEOUT_MS,
    DEFAULT_HEARTBEAT_MS,
    DEFAULT_HWM,
    DEFAULT_LINGER_MS,
    JOIN_TIMEOUT_S,
    RECONNECT_IVL_MAX_MS,
    RECONNECT_IVL_MS,
)

__all__ = [
    "CONNECT_TIMEOUT_MS",
    "DEFAULT_HEARTBEAT_MS",
    "DEFAULT_HWM",
    "DEFAULT_LINGER_MS",
    "JOIN_TIMEOUT_S",
    "RECONNECT_IVL_MAX_MS",
    "RECONNECT_IVL_MS",
    "InBridge",
    "OutBridge",
]
