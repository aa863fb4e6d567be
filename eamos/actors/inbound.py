"""The In-Bridge's routing (paper Figures 10, 11): each wire message to the actor it is for."""

from __future__ import annotations

import threading
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING

import pykka

from ..net import wire
from ..net.effects import PeerStatus, TelemetryStale, TriggersAcknowledged
from ..net.link import Delivered
from ..program.format import DroneProgram
from .dispatch import tell_here
from .executive import DeliverInterrupt, TriggerReceived
from .failure import FailureSink
from .logic.telemetry import stale_values, telemetry_values
from .messages import Interrupt, Mailbox, RemoteTelemetry, RemoteTrigger

if TYPE_CHECKING:
    from ..logs import EventLog

__all__ = ["InRouter", "StartGate", "incoming_arcs"]

#: At most this many triggers and interrupts wait for the Start (a flood is dropped).
MAX_HELD = 4096


def incoming_arcs(program: DroneProgram) -> dict[tuple[str, str], str]:
    """``(src node, dst node)`` of every external arc into ``program``'s own nodes ->
    the participant hosting the source node: who alone may send that trigger."""
    native = {n.key for n in program.native_nodes()}
    host = {n.key: n.drone for n in program.nodes}
    return {
        (a.src, a.dst): host.get(a.src, "") for a in program.arcs if a.external and a.dst in native
    }


_CONTROL = (wire.Start, wire.Abort, wire.Complete, wire.Operator)
_ORDERS = ("prepare", "commit", "cancel")  # an amendment's phases, from the ground station


class StartGate:
    """What a drone's node takes before the ground station's Start, and which Start it takes.

    A node started by a roll-out (or ``eamos run``) belongs to one deployment
    (its config's ``deployment``).  It acts on nothing until the Start naming it
    arrives: triggers and interrupts are held, in order (at most
    :data:`MAX_HELD`), and handed on when it comes (a peer's trigger may overtake
    the ground station's Start: they travel on different links).  What the
    ground station sends counts only from a session (incarnation) whose Start of
    this deployment was taken: a Start of another deployment -- the ground
    station of an earlier roll-out, still running -- is refused (said once per
    session in ``node.out``), its triggers stay held and its Complete is
    refused; a restarted ground station of this deployment is taken with its
    new Start.  An Abort is always obeyed.  ``deployment`` "": any Start.

    ``on_running`` is called once, before the first trigger reaches a node: from
    then on something may have run on this drone (:mod:`.rejoin` records it).
    Used on the In-Bridge's receive thread; the lock guards the reads from others.
    """

    def __init__(
        self,
        drone: str,
        deployment: str,
        log: EventLog,
        on_running: Callable[[], None] | None = None,
        tell: Callable[[str, str], None] | None = None,
        ground: str = wire.GROUND_STATION,
    ) -> None:
        self.drone = drone
        self.deployment = deployment
        self.log = log
        self.on_running = on_running
        self.tell = tell
        self.ground = ground
        self._lock = threading.Lock()
        # The ground station sessions (incarnations) whose Start of this deployment
        # was taken; 0 stands for messages sent outside a session.
        self._accepted: set[int] = set()
        self._refused: set[tuple[str, int]] = set()
        self._held: list[wire.Trigger | wire.Interrupt] = []
        self._running = False
        self.dropped = 0  # held messages dropped over MAX_HELD

    @property
    def started(self) -> bool:
        """A Start of this node's deployment arrived."""
        with self._lock:
            return bool(self._accepted)

    def _counts(self, msg: wire.Message) -> bool:
        """Whether ``msg`` may act now (lock held): after a Start, and from the ground
        station only in a session whose Start was taken."""
        if not self._accepted:
            return False
        if msg.sender != self.ground or not msg.incarnation or 0 in self._accepted:
            return True
        return msg.incarnation in self._accepted

    def start(self, msg: wire.Start) -> list[wire.Trigger | wire.Interrupt] | None:
        """Take or refuse ``msg``: the held messages to hand on now (None: refused)."""
        if self.deployment and msg.deployment != self.deployment:
            key = (msg.deployment, msg.incarnation)
            with self._lock:
                first = key not in self._refused
                self._refused.add(key)
            self.log.warning(
                "mission.start.refused",
                sender=msg.sender,
                deployment=msg.deployment,
                own=self.deployment,
            )
            if first and self.tell is not None:
                self.tell(
                    self.drone,
                    f"refused a Start of deployment {msg.deployment or '(none)'}: this node was "
                    f"rolled out as deployment {self.deployment} (a ground station of another "
                    "roll-out?); it waits for its own",
                )
            return None
        with self._lock:
            if msg.incarnation in self._accepted:
                return []  # again (resent to a restarted node, or retransmitted)
            first = not self._accepted
            self._accepted.add(msg.incarnation)
            ready = [m for m in self._held if self._counts(m)]
            self._held = [m for m in self._held if not self._counts(m)]
        self.log.info(
            "mission.start",
            sender=msg.sender,
            deployment=msg.deployment,
            released=len(ready),
            **({} if first else {"session": "restarted"}),
        )
        return ready

    def hold(self, msg: wire.Trigger | wire.Interrupt) -> bool:
        """Keep ``msg`` until it may act (True), or False: hand it on now."""
        with self._lock:
            if self._counts(msg):
                return False
            if len(self._held) < MAX_HELD:
                self._held.append(msg)
                return True
            self.dropped += 1
            dropped = self.dropped
        self.log.warning("mission.start.held_dropped", sender=msg.sender, dropped=dropped)
        return True

    def takes_complete(self, msg: wire.Complete) -> bool:
        """Whether ``msg`` may end this node's mission: from a session whose Start was taken."""
        with self._lock:
            return self._counts(msg)

    def running(self) -> None:
        """A trigger is about to reach a node (the first time: ``on_running``)."""
        with self._lock:
            if self._running:
                return
            self._running = True
        if self.on_running is not None:
            self.on_running()


@dataclass(frozen=True)
class InRouter:
    """Called by the link (on its receive thread) with every message for this participant.

    A trigger's node, an interrupt's executive and a telemetry sample's board run
    their turn on that thread when they are idle (:func:`~.dispatch.tell_here`: no
    worker woken on the trigger's path, nor for each sample).  ``ground_handler``
    is set on the ground station: it also sees reports, progress, peer status and
    the fleet's telemetry.  An
    exception while routing to the runtime's actors goes to the runtime's
    failure policy (``failure``); one in the ground station's handler goes back
    to the link, which logs it.
    """

    drone: str
    nodes: Mapping[str, Mailbox[RemoteTrigger]]
    executive: Mailbox[TriggerReceived | DeliverInterrupt]
    board: Mailbox[RemoteTelemetry]
    log: EventLog
    abort: Callable[[str], None]
    completed: threading.Event
    failure: FailureSink
    ground_handler: Callable[[Delivered], None] | None = None
    control_from: frozenset[str] = frozenset({wire.GROUND_STATION})
    """Who may start, abort and complete the mission: the ground station (``eamos abort``
    speaks as it, with its key).  ``sender`` is authenticated: the In-Bridge
    accepts on each peer's socket only messages naming that peer, and with CURVE
    the socket proved the peer's key."""
    arc_hosts: dict[tuple[str, str], str] | None = None
    """:func:`incoming_arcs` of the program: a trigger counts only on one of these arcs,
    and only from the participant hosting its source node (an authenticated sender
    may still lie about the node it speaks for).  None: not checked."""
    gate: StartGate | None = None
    """A drone's node: nothing acts before the Start of its own deployment
    (:class:`StartGate`).  None (the ground station, tests): no gate."""
    operator: Callable[[wire.Operator], None] | None = None
    """The runtime's handler of the operator's commands (:mod:`.operator`), obeyed like
    an Abort: from the ground station only, before or after the Start."""
    acknowledged: Callable[[TriggersAcknowledged], None] | None = None
    """Where the triggers a peer acknowledged go: the node's journal, so that a
    restarted node never sends them again (:mod:`.rejoin`).  None: nowhere."""
    amend: Callable[[wire.Amend], None] | None = None
    """The runtime's handler of an amendment's phases (:mod:`.reprogram`), from the
    ground station only.  None: amendments are not taken (the ground station)."""

    def accept_arcs(self, arcs: Mapping[tuple[str, str], str]) -> None:
        """Take triggers on ``arcs`` too (an amendment's new arcs, before any flies)."""
        if self.arc_hosts is not None:
            self.arc_hosts.update(arcs)

    def keep_arcs(self, arcs: Mapping[tuple[str, str], str]) -> None:
        """Take triggers on ``arcs`` only (an amendment applied or cancelled)."""
        if self.arc_hosts is not None:
            for arc in [a for a in self.arc_hosts if a not in arcs]:
                del self.arc_hosts[arc]
            self.arc_hosts.update(arcs)

    def __call__(self, msg: Delivered) -> None:
        try:
            for_station = self.route(msg)
        except pykka.ActorDeadError:
            # Only while the runtime stops: its actors go before the link's last callback.
            self.log.debug("mission.inbridge.receiver_gone", message=type(msg).__name__)
            return
        except Exception as exc:
            self.failure("in-bridge", exc)
            return
        if for_station and self.ground_handler is not None:
            self.ground_handler(msg)

    def route(self, msg: Delivered) -> bool:
        """Hand ``msg`` to the node, board, executive or runtime it is for.

        True if the ground station (if this is it) should see it too.
        """
        if isinstance(msg, wire.Trigger):
            if self.gate is None or not self.gate.hold(msg):
                self._trigger(msg)
        elif isinstance(msg, wire.TelemetrySample):
            # On this thread (caller runs): at the ground station the fleet's samples
            # would otherwise wake the board's worker for each one.
            tell_here(self.board, RemoteTelemetry(msg.sender, telemetry_values(msg)))
            return True
        elif isinstance(msg, TelemetryStale):
            # Withdraw the drone's values: a condition reading them now waits
            # (Unknown) for a fresh sample instead of deciding on old data.
            # The link logged mission.telemetry.stale.
            tell_here(self.board, RemoteTelemetry(msg.sender, stale_values(msg.age_s)))
        elif isinstance(msg, PeerStatus):
            # The link logged mission.peer.<state>; the ground station shows it.
            return True
        elif isinstance(msg, TriggersAcknowledged):
            if self.acknowledged is not None:
                self.acknowledged(msg)
        elif isinstance(msg, wire.Interrupt):
            if self.gate is None or not self.gate.hold(msg):
                self._interrupt(msg)
        elif (
            isinstance(msg, _CONTROL) or (isinstance(msg, wire.Amend) and msg.phase in _ORDERS)
        ) and msg.sender not in self.control_from:
            # A fleet member's key does not make it the ground station: a drone
            # must not end, abort or start another's mission.
            self.log.warning(
                "mission.control.refused",
                message=type(msg).__name__,
                sender=msg.sender,
                allowed=sorted(self.control_from),
            )
        elif isinstance(msg, wire.Abort):
            self.abort(msg.reason or f"abort from {msg.sender}")
        elif isinstance(msg, wire.Amend) and msg.phase not in _ORDERS:
            return True  # a drone's answer: for the ground station
        elif isinstance(msg, wire.Amend):
            if self.amend is not None:
                self.amend(msg)
        elif isinstance(msg, wire.Operator):
            if self.operator is not None and msg.target in ("", self.drone):
                self.operator(msg)
        elif isinstance(msg, wire.Complete):
            if self.gate is not None and not self.gate.takes_complete(msg):
                # Before this node's Start, or from another ground station's session.
                self.log.warning("mission.complete.refused", sender=msg.sender)
            else:
                self.log.info("mission.complete", sender=msg.sender)
                self.completed.set()
        elif isinstance(msg, wire.Start):
            self._start(msg)
        else:
            return True  # Ready, Progress, Resolved, Report ...: for the ground station
        return False

    def _start(self, msg: wire.Start) -> None:
        if self.gate is None:
            self.log.info("mission.start", sender=msg.sender)
            return
        for held in self.gate.start(msg) or ():
            if isinstance(held, wire.Trigger):
                self._trigger(held)
            else:
                self._interrupt(held)

    def _trigger(self, msg: wire.Trigger) -> None:
        ref = self.nodes.get(msg.dst_node)
        if ref is None or msg.dest != self.drone:
            self.log.warning("mission.inbridge.unknown_node", src=msg.sender, dst=msg.dst_node)
            return
        if self.arc_hosts is not None:
            host = self.arc_hosts.get((msg.src_node, msg.dst_node))
            if host != msg.sender:
                # A fleet member's key proves who sends, not which node it speaks for.
                self.log.warning(
                    "mission.inbridge.forged_trigger",
                    sender=msg.sender,
                    src=msg.src_node,
                    dst=msg.dst_node,
                    host=host or "(no such arc)",
                )
                return
        # The count first: it rides along with the executive's next mail (no thread
        # woken), and is counted before anything the node's turn makes happen (the
        # drone resolved, a report asked for).  Then the node's turn, on this thread
        # if the node is idle (no worker woken); it writes the "received" line after
        # its own work.
        if self.gate is not None:
            self.gate.running()
        self.executive.tell(TriggerReceived(msg.sender))
        tell_here(
            ref,
            RemoteTrigger(
                msg.src_node,
                msg.dst_node,
                tuple(msg.iteration),
                msg.status,  # type: ignore[arg-type]
                msg.sender,
            ),
        )

    def _interrupt(self, msg: wire.Interrupt) -> None:
        try:
            scope = int(msg.scope)
        except ValueError:
            self.log.warning("mission.inbridge.bad_interrupt", scope=msg.scope)
            return
        # On this thread too if the executive is idle: it tells the nodes in the scope.
        tell_here(
            self.executive, DeliverInterrupt(Interrupt(scope, tuple(msg.iteration), msg.mode))
        )
