"""What node logic asks its host to do: small frozen effects (dask-style transitions).

A node's logic (:mod:`.kinds`) never sends a message, reads a clock or
touches a thread: each input returns a list of these effects, in order, and
the host applies them.  Two hosts exist: the :class:`~eamos.actors.node.MissionNode`
actor (which turns them into messages to other actors) and the synchronous
virtual-time driver (:mod:`eamos.virtual`), which routes them in one thread.
"""

from __future__ import annotations

from typing import Any

import msgspec

from ..messages import ActionRecord, Interrupt, NodeEvent
from ..state import Iteration, Status


class Route(msgspec.Struct, frozen=True):
    """One outgoing arc of a node."""

    dst: str
    drone: str
    kind: str
    external: bool


class Emit(msgspec.Struct, frozen=True):
    """Trigger the node at the end of ``route`` for ``iteration`` with ``status``."""

    route: Route
    iteration: Iteration
    status: Status


class StartAction(msgspec.Struct, frozen=True):
    """Run the node's uniform action for this activation (answer: ``action_finished``)."""

    iteration: Iteration
    action: str
    args: tuple[float, ...]


class CancelAction(msgspec.Struct, frozen=True):
    """Cancel the action the node runs for this activation (it answers ``cancelled``)."""

    iteration: Iteration


class WatchTelemetry(msgspec.Struct, frozen=True):
    """Push this node the property values of ``drones`` now and whenever they change."""

    drones: tuple[str, ...]


class UnwatchTelemetry(msgspec.Struct, frozen=True):
    """Stop pushing telemetry to this node."""


class Resolve(msgspec.Struct, frozen=True):
    """The node finished one activation; ``top_level``: for good (outside every loop)."""

    iteration: Iteration
    status: Status
    top_level: bool


class Broadcast(msgspec.Struct, frozen=True):
    """Interrupt a structure's body on these drones (through the executive)."""

    interrupt: Interrupt
    drones: tuple[str, ...]


class Progress(msgspec.Struct, frozen=True):
    """Something worth showing live (the executive coalesces it for the ground station)."""

    event: NodeEvent


class Record(msgspec.Struct, frozen=True):
    """An action ended: its record for the summary (doubles as the "finished" progress)."""

    record: ActionRecord


class ReleaseBegin(msgspec.Struct, frozen=True):
    """A Do's end node tells its begin node (if it runs on the same drone) to stop watching."""

    begin: str
    iteration: Iteration


class Note(msgspec.Struct, frozen=True):
    """A mission-log line (``level`` is a logger method name; see docs/logs.md)."""

    level: str
    event: str
    fields: dict[str, Any] = msgspec.field(default_factory=dict)


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
