"""EAMOS network layer: the wire format, the reliable link, the Out-/In-Bridges.

* :mod:`eamos.net.wire` -- the one versioned wire format: messages are frozen
  ``msgspec.Struct`` s, built by their constructors; ``encode``/``decode``, which
  validates what peers send.
* :mod:`eamos.net.session` -- :class:`ReliableSession`, the reliable-delivery
  protocol, pure (sequence numbers, acks, retransmission, heartbeats, peer
  liveness, latest-value telemetry): events in, effects out (:mod:`eamos.net.effects`:
  send, deliver, peer changed, wake; the local events :class:`PeerStatus` and
  :class:`TelemetryStale`), time passed in;
  :mod:`eamos.net.incarnation` resynchronises peers with a restarted participant.
* :mod:`eamos.net.link` -- :class:`Link`, the driver that runs a session on
  threads, the bridges and a clock (what a participant's runtime uses);
  :class:`LinkSettings` (:mod:`eamos.net.settings`) its timing.
* :mod:`eamos.net.transport` -- the seam between driver and sockets
  (:class:`~eamos.net.transport.Transport`, the ZeroMQ one).
* :mod:`eamos.net.bridges` -- :class:`OutBridge` (XPUB) and :class:`InBridge` (SUB),
  plain or CURVE (code in ``out_bridge``, ``in_bridge``, ``sockets``).
* :mod:`eamos.net.keys` -- fleet key pairs (``eamos keys``), the ZAP
  authenticator, the plain-on-loopback rule; :mod:`eamos.net.zap` the ZAP handler a
  context's participants share (:class:`ZapHandler`).
* :mod:`eamos.net.readiness` -- :class:`~eamos.net.readiness.SocketWatch`, how an
  In-Bridge waits on a socket per peer at the cost of those ready.
* :mod:`eamos.net.descriptors` -- the file-descriptor limit a node raises.

See ``docs/wire-format.md`` for the message table and ``docs/network.md`` for
delivery, security and the fault tests.
"""

from eamos.net.bridges import InBridge, OutBridge
from eamos.net.effects import PeerStatus, TelemetryStale, TriggersAcknowledged
from eamos.net.link import Link
from eamos.net.session import ReliableSession
from eamos.net.settings import LinkSettings
from eamos.net.wire import (
    GROUND_STATION,
    TOPIC_ALL,
    WIRE_VERSION,
    Abort,
    Ack,
    Complete,
    Heartbeat,
    Interrupt,
    Message,
    Progress,
    Ready,
    Report,
    ReportPart,
    Resolved,
    Start,
    TelemetrySample,
    Trigger,
    WireError,
    decode,
    encode,
    topic_heartbeat,
    topic_telemetry,
    topic_to,
)
from eamos.net.zap import ZapHandler

__all__ = [
    "GROUND_STATION",
    "TOPIC_ALL",
    "WIRE_VERSION",
    "Abort",
    "Ack",
    "Complete",
    "Heartbeat",
    "InBridge",
    "Interrupt",
    "Link",
    "LinkSettings",
    "Message",
    "OutBridge",
    "PeerStatus",
    "Progress",
    "Ready",
    "ReliableSession",
    "Report",
    "ReportPart",
    "Resolved",
    "Start",
    "TelemetrySample",
    "TelemetryStale",
    "Trigger",
    "TriggersAcknowledged",
    "WireError",
    "ZapHandler",
    "decode",
    "encode",
    "topic_heartbeat",
    "topic_telemetry",
    "topic_to",
]
