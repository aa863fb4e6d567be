"""Messages between the actors of one drone runtime (typed, frozen), and who takes them.

Cross-drone messages have their own wire format in :mod:`eamos.net.wire`;
these never leave the process.  An actor holds each of the others as a
:class:`Mailbox` of the messages it sends it: a node sees the telemetry board
as a ``Mailbox[Watch | Unwatch]``, whether it is the board's actor ref or a
test's recorder.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Protocol, TypeVar

import msgspec

from .state import Iteration, Status

if TYPE_CHECKING:
    from .logic.telemetry import PropertyValues

M = TypeVar("M", contravariant=True)


class Mailbox(Protocol[M]):
    """Something that takes messages of type ``M`` one way, without waiting.

    A Pykka actor's ref (``ActorRef.tell``), the Out-Bridge's
    :class:`~.outbox.Outbox`, or a test's stand-in that records what it is told.
    """

    def tell(self, message: M) -> None:
        """Hand over ``message``; raises ``pykka.ActorDeadError`` if the receiver stopped."""
        ...


class Trigger(msgspec.Struct, frozen=True):
    """A precondition arc delivers: node ``src`` finished ``iteration`` with ``status``."""

    src: str
    dst: str
    iteration: Iteration
    status: Status


class RemoteTrigger(Trigger, frozen=True):
    """A :class:`Trigger` the In-Bridge delivered from drone ``src_drone``.

    The node writes the ``mission.inbridge.received`` line after its own work, so
    the line is off the trigger's path (the In-Bridge's thread writing it would hold
    the interpreter while the node's thread wakes)."""

    src_drone: str = ""


class Fire(msgspec.Struct, frozen=True):
    """Start the initial node (the ground station's start trigger)."""


class Interrupt(msgspec.Struct, frozen=True):
    """The structure ``scope`` (a Do or Repeat begin node) interrupts its body."""

    scope: int
    iteration: Iteration
    mode: str  # "all", "waits", or a Whenever's "suspend"/"resume"


class Release(msgspec.Struct, frozen=True):
    """A Do's end node tells its begin node that Body is over: stop watching."""

    iteration: Iteration


class PeerLost(msgspec.Struct, frozen=True):
    """The drone hosting the nodes ``sources`` (keys) is lost for good (its link is gone).

    Nodes inside a Try's Body then count its arcs as ``failed``: the Try catches it
    (:meth:`eamos.actors.logic.NodeLogic.peer_lost`); other nodes ignore it.
    """

    sources: frozenset[str]


class TelemetryChanged(msgspec.Struct, frozen=True):
    """New property values of one drone, for the nodes watching it."""

    drone: str
    values: PropertyValues


class Watch(msgspec.Struct, frozen=True):
    """Ask the telemetry board for updates of these drones."""

    watcher: Mailbox[TelemetryChanged]
    drones: tuple[str, ...]


class Unwatch(msgspec.Struct, frozen=True):
    """Stop the telemetry board's updates to this watcher."""

    watcher: Mailbox[TelemetryChanged]


class RemoteTelemetry(msgspec.Struct, frozen=True):
    """A telemetry sample received from another drone."""

    drone: str
    values: PropertyValues


class AbortMission(msgspec.Struct, frozen=True):
    """Stop executing: no more actions, no more triggers."""

    reason: str = ""


class SendTrigger(msgspec.Struct, frozen=True):
    """Ask the out-bridge to deliver a trigger to another drone."""

    dest: str
    trigger: Trigger


class SendInterrupt(msgspec.Struct, frozen=True):
    """Ask the out-bridge to deliver an interrupt to another drone."""

    dest: str
    interrupt: Interrupt


class ActionRecord(msgspec.Struct, frozen=True):
    """One action a node ran, for the summary (times in epoch seconds)."""

    node: str
    action: str
    args: tuple[float, ...]
    iteration: Iteration
    start: float
    end: float
    result: str  # "ok" | "failed" | "cancelled"
    reason: str = ""


class NodeEvent(msgspec.Struct, frozen=True):
    """A node started or finished something worth showing live."""

    node: str
    state: str  # "running", "ok", "failed", "cancelled", "waiting", "skipped", "blocked"
    action: str
    iteration: Iteration = ()
    detail: str = ""


class NodeResolved(msgspec.Struct, frozen=True):
    """A top-level node (outside any loop) has finished for good."""

    node: str
    status: Status
