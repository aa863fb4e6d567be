"""What node logic asks its host to do: small frozen effects (dask-style transitions).

A node's logic (:mod:`.kinds`) never sends a message, reads a clock or
touches a thread: each input returns a list of these effects, in order, and
the host applies them.  Two hosts exist: the :class:`~eamos.actors.node.MissionNode`
actor (which turns them into messages to other actors) and the synchronous
virtual-time driver (:mod:`eamos.virtual`), which routes them in one thread.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from ..messages import ActionRecord, Interrupt, NodeEvent
from ..state import Iteration, Status


@dataclass(frozen=True)
class Route:
    """One outgoing arc of a node."""

    dst: str
    drone: str
    kind: str
    external: bool


@dataclass(frozen=True)
class Emit:
    """Trigger the node at the end of ``route`` for ``iteration`` with ``status``."""

    route: Route
    iteration: Iteration
    status: Status


@dataclass(frozen=True)
class StartAction:
    """Run the node's uniform action for this activation (answer: ``action_finished``)."""

    iteration: Iteration
    action: str
    args: tuple[float, ...]


@dataclass(frozen=True)
class CancelAction:
    """Cancel the action the node runs for this activation (it answers ``cancelled``)."""

    iteration: Iteration


@dataclass(frozen=True)
class WatchTelemetry:
    """Push this node the property values of ``drones`` now and whenever they change."""

    drones: tuple[str, ...]


@dataclass(frozen=True)
class UnwatchTelemetry:
    """Stop pushing telemetry to this node."""


@dataclass(frozen=True)
class Resolve:
    """The node finished one activation; ``top_level``: for good (outside every loop)."""

    iteration: Iteration
    status: Status
    top_level: bool


@dataclass(frozen=True)
class Broadcast:
    """Interrupt a structure's body on these drones (through the executive)."""

    interrupt: Interrupt
    drones: tuple[str, ...]


@dataclass(frozen=True)
class Progress:
    """Something worth showing live (the executive coalesces it for the ground station)."""

    event: NodeEvent


@dataclass(frozen=True)
class Record:
    """An action ended: its record for the summary (doubles as the "finished" progress)."""

    record: ActionRecord


@dataclass(frozen=True)
class ReleaseBegin:
    """A Do's end node tells its begin node (if it runs on the same drone) to stop watching."""

    begin: str
    iteration: Iteration


@dataclass(frozen=True)
class Note:
    """A mission-log line (``level`` is a logger method name; see docs/logs.md)."""

    level: str
    event: str
    fields: dict[str, Any] = field(default_factory=dict, hash=False)


Effect = (
    Emit
    | StartAction
    | CancelAction
    | WatchTelemetry
    | UnwatchTelemetry
    | Resolve
    | Broadcast
    | Progress
    | Record
    | ReleaseBegin
    | Note
)
