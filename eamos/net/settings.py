"""Timing of the network layer: :class:`LinkSettings` (the ``[net]`` keys) and ZeroMQ defaults.

Stdlib only: the pure protocol (:mod:`eamos.net.session`) and the config
loader read it without loading ZeroMQ.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Final

__all__ = ["DEFAULT_HEARTBEAT_MS", "LinkSettings"]

DEFAULT_HEARTBEAT_MS: Final = 1000
"""ZeroMQ (ZMTP) heartbeat interval; a connection silent for 5 of them is dropped."""


@dataclass(frozen=True)
class LinkSettings:
    """Timing of the reliability layer (every field is a ``[net]`` config key too)."""

    heartbeat_s: float = 1.0
    """Heartbeat period; also how often the latest telemetry sample is repeated.

    Each heartbeat wakes every peer watching it (a few hundred microseconds of
    CPU there), so the period is a trade between detection time and load."""
    peer_timeout_s: float = 3.0
    """A peer not heard from for this long is reported lost."""
    telemetry_stale_s: float = 2.5
    """A drone's telemetry not heard for this long is stale: conditions wait."""
    telemetry_max_hz: float = 20.0
    """At most this many telemetry samples per second leave (the latest always does)."""
    rto_min_s: float = 0.0
    """Lower bound of the retransmission timeout; 0: twice ``heartbeat_s``.  It
    must exceed ``heartbeat_s``: steady traffic is acknowledged by the
    receiver's heartbeats.  The timer is the safety net: losses that are known
    (a reconnect, a late subscriber, a gap the receiver saw) are resent at once,
    and TCP recovers lost packets while a connection lasts."""
    rto_max_s: float = 0.0
    """Upper bound of the retransmission timeout; 0: five times ``heartbeat_s``."""
    rto_initial_s: float = 0.0
    """Retransmission timeout before any round trip was measured; 0: three times
    ``heartbeat_s`` (within ``[rto_min_s, rto_max_s]``).  A link's first message is
    acknowledged by the receiver's next heartbeat, up to ``heartbeat_s`` later, and the
    receiver may be as busy as the sender: at a 200-drone fork on two cores the first
    round trips took up to 2.5 s (docs/performance.md)."""
    window: int = 256
    """At most this many messages of one link are retransmitted per timeout."""
    reorder_limit: int = 65536
    """Out-of-order messages buffered per link (beyond, they are resent later)."""
    zmq_heartbeat_ms: int = DEFAULT_HEARTBEAT_MS
    """ZeroMQ's own connection heartbeat (drops dead TCP connections)."""

    def __post_init__(self) -> None:
        # Derived defaults (0 = derive); object.__setattr__ because frozen.
        if self.rto_min_s == 0:
            object.__setattr__(self, "rto_min_s", 2 * self.heartbeat_s)
        if self.rto_max_s == 0:
            object.__setattr__(self, "rto_max_s", max(5 * self.heartbeat_s, self.rto_min_s))
        if self.rto_initial_s == 0:
            initial = min(max(3 * self.heartbeat_s, self.rto_min_s), self.rto_max_s)
            object.__setattr__(self, "rto_initial_s", initial)
        for name in (
            "heartbeat_s",
            "peer_timeout_s",
            "telemetry_stale_s",
            "telemetry_max_hz",
            "rto_min_s",
            "rto_max_s",
            "rto_initial_s",
        ):
            value = getattr(self, name)
            if not value > 0:
                raise ValueError(f"{name}: must be > 0, got {value!r}")
        if self.rto_max_s < self.rto_min_s:
            raise ValueError("rto_max_s: must be >= rto_min_s")
        if self.rto_min_s <= self.heartbeat_s:
            raise ValueError(
                "rto_min_s: must be longer than heartbeat_s (heartbeats carry the acks)"
            )
        if self.peer_timeout_s <= self.heartbeat_s:
            raise ValueError("peer_timeout_s: must be longer than heartbeat_s")
        if self.telemetry_stale_s <= self.heartbeat_s:
            raise ValueError(
                "telemetry_stale_s: must be longer than heartbeat_s (the telemetry refresh)"
            )
