"""EAMOS network layer: the wire format and the Out-/In-Bridges between participants.

* :mod:`eamos.net.wire` -- the one versioned wire format (``encode``/``decode``).
* :mod:`eamos.net.bridges` -- :class:`OutBridge` (XPUB) and :class:`InBridge` (SUB),
  plain or CURVE.
* :mod:`eamos.net.link` -- :class:`Link`: sequence numbers, acks, retransmission,
  heartbeats, peer liveness, latest-value telemetry.
* :mod:`eamos.net.keys` -- fleet key pairs (``eamos keys``), the ZAP
  authenticator, the plain-on-loopback rule.

See ``docs/wire-format.md`` for the message table and ``docs/network.md`` for
delivery, security and the fault tests.
"""

from eamos.net.bridges import InBridge, OutBridge
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
    "Message",
    "OutBridge",
    "Progress",
    "Ready",
    "Report",
    "Resolved",
    "Start",
    "TelemetrySample",
    "Trigger",
    "WireError",
    "decode",
    "encode",
    "topic_heartbeat",
    "topic_telemetry",
    "topic_to",
]
