"""EAMOS network layer: the wire format and the Out-/In-Bridges between participants.

* :mod:`eamos.net.wire` -- the one versioned wire format (``encode``/``decode``).
* :mod:`eamos.net.bridges` -- :class:`OutBridge` (XPUB) and :class:`InBridge` (SUB).

See ``docs/wire-format.md`` for the message table.
"""

from eamos.net.bridges import InBridge, OutBridge
from eamos.net.wire import (
    GROUND_STATION,
    TOPIC_ALL,
    WIRE_VERSION,
    Abort,
    Complete,
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
    topic_telemetry,
    topic_to,
)

__all__ = [
    "GROUND_STATION",
    "TOPIC_ALL",
    "WIRE_VERSION",
    "Abort",
    "Complete",
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
    "topic_telemetry",
    "topic_to",
]
