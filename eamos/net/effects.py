"""The session's effects: what the reliable-delivery session tells its driver to do.

The pure :class:`~eamos.net.session.ReliableSession` takes events and returns
effects (:data:`SessionEffect`), small frozen values the driver
(:class:`~eamos.net.link.Link`) carries out in order: :class:`Send` a wire
message, :class:`Deliver` an item to the application, report a
:class:`PeerChanged`, :class:`Wake` the timer earlier.  (A drone's actions are
something else: :mod:`eamos.program.uniform`.)  :class:`PeerStatus` and
:class:`TelemetryStale` and :class:`TriggersAcknowledged` are local events: handed to the
application with the messages, never on the wire.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TypeAlias

import eamos.net.wire as wire

__all__ = [
    "Deliver",
    "PeerChanged",
    "PeerStatus",
    "Send",
    "SessionEffect",
    "TelemetryStale",
    "TriggersAcknowledged",
    "Wake",
]


# -- local events (handed to the application, never on the wire) ------------------


@dataclass(frozen=True)
class PeerStatus:
    """Local event: peer ``sender`` went silent (``lost``), came ``back``, or ``left``.

    ``serial`` increases per session: a handler that sees events of one peer
    out of order (they come from two threads) keeps the highest.
    """

    sender: str
    state: str
    silent_s: float
    serial: int


@dataclass(frozen=True)
class TelemetryStale:
    """Local event: no telemetry from drone ``sender`` for ``age_s`` seconds."""

    sender: str
    age_s: float


@dataclass(frozen=True)
class TriggersAcknowledged:
    """Local event: peer ``sender`` acknowledged these triggers of ours, each
    ``(source node, destination node, iteration)``: they need never be sent again,
    even by a restarted node (which journals them, :mod:`eamos.actors.rejoin`)."""

    sender: str
    triggers: tuple[tuple[str, str, tuple[int, ...]], ...]


# -- effects (what the driver must do) -----------------------------------------------


@dataclass(frozen=True)
class Send:
    """Put ``message`` on the network, in the order the effects are given."""

    message: wire.Message


@dataclass(frozen=True)
class Deliver:
    """Hand ``item`` to the application (exactly once, in order per link)."""

    item: wire.Message | TelemetryStale | TriggersAcknowledged


@dataclass(frozen=True)
class PeerChanged:
    """A peer went lost, came back or left; the application gets ``status`` too."""

    status: PeerStatus


@dataclass(frozen=True)
class Wake:
    """Call ``on_tick`` at ``at`` at the latest: a new deadline, maybe earlier than any known."""

    at: float


#: Every effect the session returns.
SessionEffect: TypeAlias = Send | Deliver | PeerChanged | Wake
