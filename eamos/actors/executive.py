"""The drone executive: records, trigger counts, resolution, progress to the ground station."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import pykka

from ..net import wire
from ..net.progress import ProgressEvent, progress_batch
from ..program.format import DroneProgram
from ..program.uniform import MOTION_ACTIONS
from .alarm import Alarm
from .dispatch import Dispatcher, RidesAlong
from .failure import FailureSink, RuntimePart
from .messages import ActionRecord, Interrupt, Mailbox, NodeEvent, NodeResolved, SendInterrupt
from .node import BroadcastInterrupt, ExecutiveNews
from .state import Iteration
from .stranded import Activity

if TYPE_CHECKING:
    from ..logs import EventLog

__all__ = [
    "PROGRESS_INTERVAL_S",
    "STATE_ACTIONS",
    "AskActivity",
    "DeliverInterrupt",
    "DroneExecutive",
    "ExecutiveSnapshot",
    "NewProgram",
    "Snapshot",
    "TriggerReceived",
    "ask_activity",
    "ask_snapshot",
]

PROGRESS_INTERVAL_S = 0.1
#: A batch of progress events is sent at once when it holds this many.
PROGRESS_BATCH_MAX = 256

#: Actions after which the vehicle's reported state (position, armed) may differ.
STATE_ACTIONS = MOTION_ACTIONS | {"Arm", "Disarm"}


@dataclass(frozen=True)
class TriggerReceived(RidesAlong):
    """The in-bridge delivered a trigger from ``src_drone`` (counted for Table 7; the
    count rides along with the executive's next mail: it wakes no thread)."""

    src_drone: str


@dataclass(frozen=True)
class DeliverInterrupt:
    """An interrupt from another drone, for this drone's nodes in its scope."""

    interrupt: Interrupt


@dataclass(frozen=True)
class AskActivity:
    """Ask: the executive's :class:`~.stranded.Activity` (resolved? idle since when?)."""


@dataclass(frozen=True)
class NewProgram:
    """Ask: run an amended ``program`` with these node actors (:mod:`.reprogram`)."""

    program: DroneProgram
    nodes: Mapping[str, Mailbox[Interrupt]]


@dataclass(frozen=True)
class Snapshot:
    """Ask: the executive's :class:`ExecutiveSnapshot`."""


@dataclass(frozen=True)
class ExecutiveSnapshot:
    """What the executive knows at one moment (for the drone's report)."""

    records: tuple[ActionRecord, ...] = ()
    triggers_received: int = 0
    resolved: Mapping[str, str] = field(default_factory=dict)
    all_resolved: bool = False
    state_changed_s: float | None = None  # monotonic: last STATE_ACTIONS record arrived
    state_action: str | None = None  # and its action


def ask_snapshot(
    executive: pykka.ActorRef[DroneExecutive] | None, timeout_s: float
) -> ExecutiveSnapshot:
    """The executive's snapshot (an empty one if there is no executive, or it stopped)."""
    if executive is None:
        return ExecutiveSnapshot()
    try:
        snap: ExecutiveSnapshot = executive.ask(Snapshot(), block=True, timeout=timeout_s)
    except pykka.ActorDeadError:
        return ExecutiveSnapshot()
    return snap


def ask_activity(executive: pykka.ActorRef[DroneExecutive] | None, timeout_s: float) -> Activity:
    """The executive's :class:`~.stranded.Activity` (not resolved, busy, if there is none)."""
    if executive is None:
        return Activity(False, None)
    try:
        answer: Activity = executive.ask(AskActivity(), block=True, timeout=timeout_s)
    except pykka.ActorDeadError:
        return Activity(False, None)
    return answer


@dataclass(frozen=True)
class _FlushProgress:
    """Send the progress events held since the last flush (the executive to itself)."""


def journal_entry(
    state: str,
    node: str,
    action: str,
    iteration: Iteration,
    detail: str,
    finished: int,
    at: float,
    where: tuple[float, float, float] | None,
) -> dict[str, Any]:
    """One reported progress event as the node's journal keeps it (as the ground station
    does: :func:`~.continuation.activations` reads both)."""
    entry: dict[str, Any] = {
        "t": at,
        "state": state,
        "node": node,
        "action": action,
        "iteration": list(iteration),
        "detail": detail,
    }
    if where is not None:
        entry["position"] = list(where)
    return entry


class DroneExecutive(RuntimePart):
    """Keeps the drone's records and tells the ground station how it is doing."""

    part = "executive"

    def __init__(
        self,
        dispatcher: Dispatcher,
        program: DroneProgram,
        nodes: Mapping[str, Mailbox[Interrupt]],
        out_bridge: Mailbox[SendInterrupt],
        to_ground: Callable[[wire.Message], None],
        log: EventLog,
        failure: FailureSink | None = None,
        journal: Callable[[list[dict[str, Any]]], None] | None = None,
        position: Callable[[], tuple[float, float, float] | None] | None = None,
        resolved: threading.Event | None = None,
    ) -> None:
        """``journal``: also hand each progress event to it as it happens, before the
        batch that carries it to the ground station (the node's own record,
        :class:`~.rejoin.NodeJournal`: an action that ended is on disk before a kill
        can lose it), a running action with where its vehicle was when it began
        (``position()``, its latest sample).  ``resolved``: set once every top-level
        node finished (the runtime's thread waits on it instead of asking)."""
        super().__init__(dispatcher)
        self.program = program
        self.journal = journal
        self.position = position if journal is not None else None
        self.drone = program.drone
        self.nodes = nodes
        self.out_bridge = out_bridge
        self.to_ground = to_ground
        self.log = log
        self.failure = failure
        self.top_level: set[str] = set()
        self.labels: dict[str, str] = {}
        self.scope_index: dict[int, list[Mailbox[Interrupt]]] = {}
        self._take_program(program, nodes)
        self.resolved: dict[str, str] = {}
        self.records: list[ActionRecord] = []
        self.triggers_received = 0
        self.state_changed_s: float | None = None
        self.state_action: str | None = None
        self.finished_actions = 0
        self.running: set[tuple[str, tuple[int, ...]]] = set()  # (node, iteration) running now
        self.idle_since: float | None = time.monotonic()
        # (state, node, action, iteration, detail, finished, at, position), oldest first
        self._pending_progress: list[
            tuple[str, str, str, Iteration, str, int, float, tuple[float, float, float] | None]
        ] = []
        self._last_progress = float("-inf")
        # One thread for the executive's life, started in on_start (not a Timer, a
        # new thread, per interval); it tells the executive to flush.
        self._flush_alarm = Alarm(self._tell_flush, name=f"eamos-progress-{self.drone}")
        self._flush_due = False
        self.resolved_event = resolved if resolved is not None else threading.Event()
        if not self.top_level:
            self.resolved_event.set()

    def _take_program(self, program: DroneProgram, nodes: Mapping[str, Mailbox[Interrupt]]) -> None:
        """Run ``program`` with these node actors (at the start, and when amended)."""
        self.program, self.nodes = program, nodes
        self.top_level = {n.key for n in program.native_nodes() if not n.loops}
        self.labels = {n.key: n.label for n in program.native_nodes()}
        self.scope_index = {}
        for node in program.native_nodes():
            for scope in node.scopes:
                self.scope_index.setdefault(scope, []).append(nodes[node.key])

    def on_start(self) -> None:
        self._flush_alarm.start()  # here, not in the first event's turn (on a trigger's path)
        if not self.top_level:
            self.to_ground(wire.Resolved(mission=self.program.mission_id, sender=self.drone))

    def on_receive(self, message: object) -> ExecutiveSnapshot | Activity | None:
        if isinstance(message, ExecutiveNews):
            for item in message.items:
                self._news(item)
            return None
        return self._news(message)

    def _news(self, message: object) -> ExecutiveSnapshot | Activity | None:
        if isinstance(message, NodeResolved):
            self._node_resolved(message)
        elif isinstance(message, ActionRecord):
            self._record(message)
        elif isinstance(message, NodeEvent):
            self._track(message)
            self._progress(
                message.state,
                message.node,
                message.action,
                message.iteration,
                message.detail,
                urgent=message.state in ("failed", "blocked"),
            )
        elif isinstance(message, _FlushProgress):
            self._flush_due = False
            self._flush_progress()
        elif isinstance(message, BroadcastInterrupt):
            for drone in message.drones:
                if drone == self.drone:
                    self._deliver(message.interrupt)
                else:
                    self.out_bridge.tell(SendInterrupt(drone, message.interrupt))
        elif isinstance(message, DeliverInterrupt):
            self._deliver(message.interrupt)
        elif isinstance(message, TriggerReceived):
            self.triggers_received += 1
        elif isinstance(message, Snapshot):
            return self.snapshot()
        elif isinstance(message, NewProgram):
            self._take_program(message.program, message.nodes)
            return Activity(self.resolved_event.is_set(), self.idle_since)
        elif isinstance(message, AskActivity):
            return Activity(self.resolved_event.is_set(), self.idle_since)
        return None

    def on_stop(self) -> None:
        self._flush_alarm.stop()
        # What a pending flush would have sent still goes (the send side closes
        # after the actors stop).
        self._flush_progress()

    def _tell_flush(self) -> None:
        try:
            self.actor_ref.tell(_FlushProgress())
        except pykka.ActorDeadError:
            pass  # stopped meanwhile: on_stop sent what was pending

    def snapshot(self) -> ExecutiveSnapshot:
        """The records and counts so far."""
        return ExecutiveSnapshot(
            records=tuple(self.records),
            triggers_received=self.triggers_received,
            resolved=dict(self.resolved),
            all_resolved=self.resolved_event.is_set(),
            state_changed_s=self.state_changed_s,
            state_action=self.state_action,
        )

    def _node_resolved(self, message: NodeResolved) -> None:
        self.resolved[message.node] = message.status
        if self.top_level <= self.resolved.keys() and not self.resolved_event.is_set():
            self._flush_progress()
            self.resolved_event.set()
            self.log.info("mission.resolved", nodes=len(self.resolved))
            self.to_ground(wire.Resolved(mission=self.program.mission_id, sender=self.drone))

    def _track(self, event: NodeEvent) -> None:
        """Actions running now (a stranded drone is one that waits, idle)."""
        if event.state == "running":
            self.running.add((event.node, tuple(event.iteration)))
            self.idle_since = None
        elif event.state in ("failed", "cancelled", "ok"):
            self._finished(event.node, tuple(event.iteration))

    def _finished(self, node: str, iteration: tuple[int, ...]) -> None:
        self.running.discard((node, iteration))
        if not self.running and self.idle_since is None:
            self.idle_since = time.monotonic()

    def _record(self, record: ActionRecord) -> None:
        self.records.append(record)
        self._finished(record.node, tuple(record.iteration))
        if record.action in STATE_ACTIONS:
            self.state_changed_s = time.monotonic()
            self.state_action = record.action
        self._progress(
            record.result,
            record.node,
            self.labels.get(record.node, record.action),
            record.iteration,
            record.reason,
            urgent=record.result != "ok",
        )

    def _progress(
        self,
        state: str,
        node: str,
        action: str,
        iteration: tuple[int, ...],
        detail: str,
        urgent: bool,
    ) -> None:
        """Tell the ground station every state change, batched: at most one message
        every PROGRESS_INTERVAL_S unless it matters (or the batch is full).

        Progress is for people watching; a message per change in bursts of
        instant actions would flood the link and slow the mission itself, and
        keeping only the latest would hide changes.  So every change is kept, in
        order, and a batch goes out by a timer, when full, or before Resolved
        (:mod:`eamos.net.progress`).
        """
        if state in ("ok", "failed", "cancelled"):
            self.finished_actions += 1
        # Kept raw: the wire form is built once per batch, at flush time.
        where = self.position() if self.position is not None and state == "running" else None
        pending = (
            state,
            node,
            action,
            iteration,
            detail,
            self.finished_actions,
            time.time(),
            where,
        )
        self._pending_progress.append(pending)
        if self.journal is not None:
            self.journal([journal_entry(*pending)])
        now = time.monotonic()
        if (
            urgent
            or now - self._last_progress >= PROGRESS_INTERVAL_S
            or len(self._pending_progress) >= PROGRESS_BATCH_MAX
        ):
            self._flush_progress()
        elif not self._flush_due:
            self._flush_due = True
            self._flush_alarm.arm(PROGRESS_INTERVAL_S - (now - self._last_progress))

    def _flush_progress(self) -> None:
        if self._pending_progress:
            events: list[ProgressEvent] = [
                (
                    state,
                    node,
                    action,
                    # "at": when it changed, to show events of all drones in order
                    {"iteration": list(it), "detail": detail, "finished": done, "at": at},
                )
                for state, node, action, it, detail, done, at, _ in self._pending_progress
            ]
            batch = progress_batch(self.program.mission_id, self.drone, events)
            self.to_ground(batch)
            self._pending_progress = []
            self._last_progress = time.monotonic()
        if self._flush_due:  # sent before the alarm: it need not fire
            self._flush_due = False
            self._flush_alarm.cancel()

    def _deliver(self, interrupt: Interrupt) -> None:
        for ref in self.scope_index.get(interrupt.scope, ()):
            ref.tell(interrupt)
