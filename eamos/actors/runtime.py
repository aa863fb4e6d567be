"""One drone's execution environment (paper Section VI, Figure 3 F-K).

:class:`DroneRuntime` loads a drone program and builds, for that drone only:
one :class:`~.node.MissionNode` actor per native MDG node, the uniform-API
actor over its adapter, a :class:`TelemetryBoard` (latest property values,
pushed to the conditions that read them), an :class:`Outbox` (the Out-Bridge) and an
In-Bridge to the other participants, and a :class:`DroneExecutive` that keeps
the records.  It holds no global state: two runtimes live happily in one
process (as the tests do).
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pykka
import zmq

from ..hal.api import Adapter, AdapterError, Telemetry
from ..logs import DroneLogs
from ..net import wire
from ..net.bridges import InBridge, OutBridge
from ..net.keys import FleetKeys, KeysError, plain_refusal
from ..net.link import Link, LinkSettings, PeerStatus, TelemetryStale
from ..program.format import DroneProgram
from ..program.uniform import GROUND_STATION, PROPERTY_FIELDS
from .dispatch import Dispatcher
from .messages import (
    AbortMission,
    ActionRecord,
    Fire,
    Interrupt,
    LocalTelemetry,
    NodeEvent,
    NodeResolved,
    RemoteTelemetry,
    SendInterrupt,
    SendTrigger,
    TelemetryChanged,
    Trigger,
    Unwatch,
    Watch,
)
from .node import BroadcastInterrupt, Links, MissionNode, Route, Wire
from .uniform_api import Abort as HalAbort
from .uniform_api import UniformAPI


class DroneRuntimeError(Exception):
    """A drone runtime cannot start or run (bad program, adapter unusable, network)."""


def telemetry_values(sample: Telemetry | wire.TelemetrySample) -> dict[str, Any]:
    """Uniform property values (``X``, ``Battery`` ...) of a telemetry sample."""
    values = {prop: getattr(sample, fld) for prop, fld in PROPERTY_FIELDS.items()}
    values["_time_s"] = sample.time_s
    values["_landed"] = sample.landed
    return values


def stale_values(age_s: float) -> dict[str, Any]:
    """Property values of a drone whose telemetry went stale: none (conditions wait)."""
    values: dict[str, Any] = dict.fromkeys(PROPERTY_FIELDS)
    values["_stale_s"] = age_s
    return values


# -- actors -------------------------------------------------------------------


class TelemetryBoard(pykka.ThreadingActor):
    """Latest property values per drone; pushes changes to the nodes watching them."""

    def __init__(self, drone: str, out_bridge: Any, mission_id: str) -> None:
        super().__init__()
        self.drone = drone
        self.out_bridge = out_bridge
        self.mission_id = mission_id
        self.latest: dict[str, dict[str, Any]] = {}
        self.local: Telemetry | None = None
        self.watchers: dict[Any, tuple[str, ...]] = {}
        self.landed_waiters: list[threading.Event] = []

    def on_receive(self, message: Any) -> Any:
        if isinstance(message, LocalTelemetry):
            sample: Telemetry = message.sample
            self.local = sample
            self._update(self.drone, telemetry_values(sample))
            if self.out_bridge is not None:
                self.out_bridge.tell(
                    wire.TelemetrySample(
                        mission=self.mission_id,
                        sender=self.drone,
                        time_s=sample.time_s,
                        x_m=sample.x_m,
                        y_m=sample.y_m,
                        z_m=sample.z_m,
                        lat_deg=sample.lat_deg,
                        lon_deg=sample.lon_deg,
                        alt_m=sample.alt_m,
                        battery_pct=sample.battery_pct,
                        armed=sample.armed,
                        landed=sample.landed,
                    )
                )
            if sample.landed:
                for event in self.landed_waiters:
                    event.set()
                self.landed_waiters.clear()
        elif isinstance(message, RemoteTelemetry):
            self._update(message.drone, message.values)
        elif isinstance(message, Watch):
            self.watchers[message.watcher] = message.drones
            for drone in message.drones:
                if drone in self.latest:
                    message.watcher.tell(TelemetryChanged(drone, self.latest[drone]))
        elif isinstance(message, Unwatch):
            self.watchers.pop(message.watcher, None)
        elif isinstance(message, _LatestLocal):
            return self.local
        elif isinstance(message, _WhenLanded):
            if self.local is None or self.local.landed:
                message.event.set()
            else:
                self.landed_waiters.append(message.event)
        return None

    def _update(self, drone: str, values: dict[str, Any]) -> None:
        old = self.latest.get(drone)
        self.latest[drone] = values
        if old is not None and all(
            old.get(k) == v for k, v in values.items() if not k.startswith("_")
        ):
            return  # nothing a condition reads changed
        for watcher, drones in list(self.watchers.items()):
            if drone in drones:
                watcher.tell(TelemetryChanged(drone, values))


@dataclass(frozen=True)
class _LatestLocal:
    pass


@dataclass(frozen=True)
class _WhenLanded:
    event: threading.Event


class Outbox:
    """The Out-Bridge (paper Figures 10, 11): packs messages for remote drones onto the wire.

    It takes messages with ``tell`` like an actor, but handles them in the
    caller's thread: the link's ``send`` (:class:`~eamos.net.link.Link`, which
    numbers reliable messages and retransmits them until acknowledged) is
    already a thread-safe hand-over to the bridge's socket thread, and a second
    queue would only add a context switch to every cross-drone trigger.
    ``triggers_sent`` counts each trigger once, however often the link had to
    retransmit it (the Table 7 check).
    """

    def __init__(self, bridge: Link, drone: str, mission_id: str, log: Any) -> None:
        self.bridge = bridge
        self.drone = drone
        self.mission_id = mission_id
        self.log = log
        self._lock = threading.Lock()
        self.triggers_sent = 0
        self.sent_by_dest: dict[str, int] = {}

    def tell(self, message: Any) -> None:
        if isinstance(message, SendTrigger):
            t = message.trigger
            self.bridge.send(
                wire.Trigger(
                    mission=self.mission_id,
                    sender=self.drone,
                    dest=message.dest,
                    src_node=t.src,
                    dst_node=t.dst,
                    iteration=t.iteration,
                    status=t.status,
                )
            )
            with self._lock:
                self.triggers_sent += 1
                self.sent_by_dest[message.dest] = self.sent_by_dest.get(message.dest, 0) + 1
            self.log.info(
                "mission.outbridge.sent",
                dest=message.dest,
                src=t.src,
                dst=t.dst,
                iteration=list(t.iteration),
                status=t.status,
            )
        elif isinstance(message, SendInterrupt):
            i = message.interrupt
            self.bridge.send(
                wire.Interrupt(
                    mission=self.mission_id,
                    sender=self.drone,
                    dest=message.dest,
                    scope=str(i.scope),
                    iteration=i.iteration,
                    mode=i.mode,
                )
            )
            self.log.info(
                "mission.outbridge.interrupt",
                dest=message.dest,
                scope=i.scope,
                iteration=list(i.iteration),
                mode=i.mode,
            )
        else:
            self.bridge.send(message)

    def counts(self) -> dict[str, Any]:
        with self._lock:
            return {"triggers_sent": self.triggers_sent, "by_dest": dict(self.sent_by_dest)}


PROGRESS_INTERVAL_S = 0.1


@dataclass(frozen=True)
class _FlushProgress:
    pass


@dataclass(frozen=True)
class _TriggerReceived:
    src_drone: str


@dataclass(frozen=True)
class _DeliverInterrupt:
    interrupt: Interrupt


@dataclass(frozen=True)
class _Snapshot:
    pass


class DroneExecutive(pykka.ThreadingActor):
    """Keeps the drone's records and tells the ground station how it is doing."""

    def __init__(
        self,
        program: DroneProgram,
        nodes: Mapping[str, Any],
        out_bridge: Any,
        to_ground: Callable[[Any], None],
        log: Any,
    ) -> None:
        super().__init__()
        self.program = program
        self.drone = program.drone
        self.nodes = nodes
        self.out_bridge = out_bridge
        self.to_ground = to_ground
        self.log = log
        self.top_level = {n.key for n in program.native_nodes() if not n.loops}
        self.labels = {n.key: n.label for n in program.native_nodes()}
        self.resolved: dict[str, str] = {}
        self.records: list[ActionRecord] = []
        self.triggers_received = 0
        self.current: dict[str, str] = {}
        self.scope_index: dict[int, list[Any]] = {}
        for node in program.native_nodes():
            for scope in node.scopes:
                self.scope_index.setdefault(scope, []).append(nodes[node.key])
        self.finished_actions = 0
        self._pending_progress: wire.Progress | None = None
        self._last_progress = float("-inf")
        self._flush_timer: threading.Timer | None = None
        self.resolved_event = threading.Event()
        if not self.top_level:
            self.resolved_event.set()

    def on_start(self) -> None:
        if not self.top_level:
            self.to_ground(wire.Resolved(mission=self.program.mission_id, sender=self.drone))

    def on_receive(self, message: Any) -> Any:
        if isinstance(message, NodeResolved):
            self.resolved[message.node] = message.status
            if self.top_level <= self.resolved.keys() and not self.resolved_event.is_set():
                self._flush_progress()
                self.resolved_event.set()
                self.log.info("mission.resolved", nodes=len(self.resolved))
                self.to_ground(wire.Resolved(mission=self.program.mission_id, sender=self.drone))
        elif isinstance(message, ActionRecord):
            self.records.append(message)
            self._progress(
                message.result,
                message.node,
                self.labels.get(message.node, message.action),
                message.iteration,
                message.reason,
                urgent=message.result != "ok",
            )
        elif isinstance(message, NodeEvent):
            self._progress(
                message.state,
                message.node,
                message.action,
                message.iteration,
                message.detail,
                urgent=message.state in ("failed", "blocked"),
            )
        elif isinstance(message, _FlushProgress):
            self._flush_timer = None
            self._flush_progress()
        elif isinstance(message, BroadcastInterrupt):
            for drone in message.drones:
                if drone == self.drone:
                    self._deliver(message.interrupt)
                else:
                    self.out_bridge.tell(SendInterrupt(drone, message.interrupt))
        elif isinstance(message, _DeliverInterrupt):
            self._deliver(message.interrupt)
        elif isinstance(message, _TriggerReceived):
            self.triggers_received += 1
        elif isinstance(message, _Snapshot):
            return {
                "records": list(self.records),
                "triggers_received": self.triggers_received,
                "resolved": dict(self.resolved),
                "all_resolved": self.resolved_event.is_set(),
            }
        return None

    def _progress(
        self,
        state: str,
        node: str,
        action: str,
        iteration: tuple[int, ...],
        detail: str,
        urgent: bool,
    ) -> None:
        """Tell the ground station, at most every PROGRESS_INTERVAL_S unless it matters.

        Progress is for people watching; bursts of instant actions would otherwise
        flood the link and slow the mission itself.  The latest state always
        arrives: a pending update is flushed by a timer, or before Resolved.
        """
        if state in ("ok", "failed", "cancelled"):
            self.finished_actions += 1
        self._pending_progress = wire.Progress(
            mission=self.program.mission_id,
            sender=self.drone,
            state=state,
            node=node,
            action=action,
            detail={
                "iteration": list(iteration),
                "detail": detail,
                "finished": self.finished_actions,
            },
        )
        now = time.monotonic()
        if urgent or now - self._last_progress >= PROGRESS_INTERVAL_S:
            self._flush_progress()
        elif self._flush_timer is None:
            delay = PROGRESS_INTERVAL_S - (now - self._last_progress)
            self._flush_timer = threading.Timer(delay, self.actor_ref.tell, (_FlushProgress(),))
            self._flush_timer.daemon = True
            self._flush_timer.start()

    def _flush_progress(self) -> None:
        if self._pending_progress is not None:
            self.to_ground(self._pending_progress)
            self._pending_progress = None
            self._last_progress = time.monotonic()

    def on_stop(self) -> None:
        if self._flush_timer is not None:
            self._flush_timer.cancel()

    def _deliver(self, interrupt: Interrupt) -> None:
        for ref in self.scope_index.get(interrupt.scope, ()):
            ref.tell(interrupt)


# -- the runtime ----------------------------------------------------------------


@dataclass(frozen=True)
class NetSettings:
    """Where this participant binds its Out-Bridge, where its peers' are, and how to secure it.

    ``keys`` (from ``eamos keys``) makes every link CURVE-encrypted and lets in
    only the fleet.  Leaving them out asks for plain sockets, which are refused
    unless every endpoint is local (loopback, ipc, inproc): development only.
    (A drone config must also say ``plain = true``; see :mod:`eamos.config`.)
    """

    bind: str
    peers: Mapping[str, str]
    keys: FleetKeys | None = None
    link: LinkSettings = field(default_factory=LinkSettings)

    def refusal(self, me: str) -> str | None:
        """Why these settings may not be used by participant ``me`` (None: fine)."""
        if self.keys is None:
            return plain_refusal([self.bind, *(e for n, e in self.peers.items() if n != me)])
        if self.keys.me != me:
            return f"the keys are {self.keys.me}'s, not {me}'s"
        missing = self.keys.missing(n for n in self.peers if n != me)
        if missing:
            return f"the fleet keys have no public key for {', '.join(missing)}"
        return None


class DroneRuntime:
    """Everything one drone runs for one mission; build, :meth:`start`, then :meth:`stop`."""

    def __init__(
        self,
        program: DroneProgram,
        adapter: Adapter,
        net: NetSettings,
        log_dir: Path | None = None,
        *,
        context: zmq.Context[Any] | None = None,
        ground_handler: Callable[[Any], None] | None = None,
        extra_topics: tuple[bytes, ...] = (),
    ) -> None:
        self.program = program
        self.drone = program.drone
        self.adapter = adapter
        self.net = net
        self.log_dir = log_dir
        self._own_context = context is None
        self.context = context if context is not None else zmq.Context()
        self.ground_handler = ground_handler  # set on the ground station: receives drone reports
        self.extra_topics = extra_topics
        self.logs = DroneLogs.open(log_dir, self.drone)
        self.log = self.logs.mission
        self.link: Link | None = None
        self.out: OutBridge | None = None
        self.inb: InBridge | None = None
        self.out_actor: Any = None
        self.board: Any = None
        self.hal: Any = None
        self.executive: Any = None
        self.nodes: dict[str, Any] = {}
        self.dispatcher: Dispatcher | None = None
        self.completed = threading.Event()
        self.aborted = threading.Event()
        self.abort_reason = ""
        self.adapter_error: AdapterError | None = None
        self._stopped = False
        self.started_at = 0.0

    # -- building -------------------------------------------------------------------

    def start(self) -> None:
        """Build every actor and bridge; raise :class:`DroneRuntimeError` if the drone can't run."""
        program = self.program
        self.started_at = time.monotonic()
        refusal = self.net.refusal(self.drone)
        if refusal is not None:
            self.stop()
            raise DroneRuntimeError(f"{self.drone}: {refusal}")
        try:
            self.link = Link(
                self.context,
                self.drone,
                program.mission_id,
                self.net.bind,
                self.logs.mission,
                keys=self.net.keys,
                settings=self.net.link,
            )
        except (zmq.ZMQError, KeysError) as exc:
            self.stop()
            raise DroneRuntimeError(
                f"cannot bind the out-bridge at {self.net.bind}: {exc}"
            ) from exc
        self.out = self.link.out
        self.out_actor = Outbox(self.link, self.drone, program.mission_id, self.logs.mission)
        self.dispatcher = Dispatcher(workers=2, name=f"eamos-{self.drone}")
        self.board = TelemetryBoard.start(self.drone, self.out_actor, program.mission_id)
        start_error: list[AdapterError] = []
        board = self.board
        self.hal = UniformAPI.start(
            self.adapter,
            self.logs.uniform,
            lambda sample: board.tell(LocalTelemetry(sample)),
            start_error.append,
        )
        # on_start has run once a first message is answered; an adapter that could
        # not start stops the actor, which the ask below reveals.
        try:
            # Answered only after on_start ran: the adapter is up, or the actor died.
            self.hal.proxy().drone.get(timeout=60)
        except pykka.ActorDeadError:
            pass
        if start_error or not self.hal.is_alive():
            reason = str(start_error[0]) if start_error else "the adapter did not start"
            self.adapter_error = start_error[0] if start_error else AdapterError(reason)
            self.stop()
            raise DroneRuntimeError(f"{self.drone}: {reason}")

        routes: dict[str, list[Route]] = {}
        entry: dict[str, set[str]] = {}
        loop: dict[str, set[str]] = {}
        drone_of = {n.key: n.drone for n in program.nodes}
        kind_of = {n.key: n.kind for n in program.nodes}
        for arc in program.arcs:
            routes.setdefault(arc.src, []).append(
                Route(arc.dst, drone_of[arc.dst], arc.kind, arc.external)
            )
            (loop if arc.kind == "loop" else entry).setdefault(arc.dst, set()).add(arc.src)
        for node in program.native_nodes():
            self.nodes[node.key] = MissionNode.start(
                self.dispatcher,
                node,
                tuple(routes.get(node.key, ())),
                frozenset(entry.get(node.key, ())),
                frozenset(loop.get(node.key, ())),
                self.drone,
                self.logs.mission,
                kind_of.get(f"n{node.begin}", "") if node.begin is not None else "",
            )
        to_ground = self._to_ground
        self.executive = DroneExecutive.start(
            program, dict(self.nodes), self.out_actor, to_ground, self.logs.mission
        )
        links = Links(dict(self.nodes), self.hal, self.board, self.out_actor, self.executive)
        for ref in self.nodes.values():
            ref.tell(Wire(links))
        topics = [wire.TOPIC_ALL, wire.topic_to(self.drone)]
        topics += [wire.topic_telemetry(d) for d in program.telemetry_from]
        topics += [t for t in self.extra_topics if t not in topics]
        peers = {name: ep for name, ep in self.net.peers.items() if name != self.drone}
        try:
            self.link.connect(peers, topics, self._on_message, watch=self.watched_peers())
        except (zmq.ZMQError, ValueError) as exc:
            self.stop()
            raise DroneRuntimeError(f"cannot connect the in-bridge to {peers}: {exc}") from exc
        self.inb = self.link.inb
        self.log.info(
            "mission.runtime.started",
            nodes=len(self.nodes),
            program=program.checksum,
            seconds=round(time.monotonic() - self.started_at, 4),
            secure=self.link.secure,
        )

    def watched_peers(self) -> list[str] | None:
        """Peers whose heartbeats this participant follows (None: every peer).

        The ground station watches the whole fleet; a drone, the participants
        it exchanges triggers, interrupts or telemetry with, and the ground
        station.  (Each heartbeat wakes its receiver: all-to-all would grow
        with the square of the fleet.)
        """
        if self.ground_handler is not None or self.drone == GROUND_STATION:
            return None
        native = {n.key for n in self.program.native_nodes()}
        drone_of = {n.key: n.drone for n in self.program.nodes}
        sources = {drone_of[a.src] for a in self.program.arcs if a.external and a.dst in native}
        watch = {*self.destinations(), *sources, *self.program.telemetry_from, GROUND_STATION}
        watch.discard(self.drone)
        return sorted(watch)

    # -- readiness ---------------------------------------------------------------------

    def destinations(self) -> list[str]:
        """Every participant this drone sends to (the ground station always)."""
        native = {n.key for n in self.program.native_nodes()}
        drone_of = {n.key: n.drone for n in self.program.nodes}
        dests = {drone_of[a.dst] for a in self.program.arcs if a.external and a.src in native}
        for node in self.program.native_nodes():
            dests.update(node.interrupt_drones)
        dests.add(GROUND_STATION)
        dests.discard(self.drone)
        return sorted(dests)

    def wait_subscribed(self, timeout_s: float) -> bool:
        """Block until every participant this drone sends to listens to it."""
        assert self.out is not None
        return self.out.wait_subscribed([wire.topic_to(d) for d in self.destinations()], timeout_s)

    def announce_ready(self, timeout_s: float, stop: threading.Event | None = None) -> bool:
        """Wait for the subscriptions, then tell the ground station this drone is ready.

        ``stop`` (set by a signal handler) ends the wait early: a node asked to stop
        while its peers are missing must not linger for the whole timeout.
        """
        deadline = time.monotonic() + timeout_s
        while not self.wait_subscribed(min(0.5, max(0.0, deadline - time.monotonic()))):
            if (stop is not None and stop.is_set()) or time.monotonic() >= deadline:
                self.log.error("mission.not_ready", waiting_for=self.destinations())
                return False
        self._to_ground(
            wire.Ready(
                mission=self.program.mission_id,
                sender=self.drone,
                program_checksum=self.program.checksum,
            )
        )
        self.log.info("mission.ready")
        return True

    # -- running -------------------------------------------------------------------------

    def fire(self) -> None:
        """Trigger the initial node (only the ground station's program has one)."""
        for node in self.program.native_nodes():
            if node.kind == "init":
                self.nodes[node.key].tell(Fire())

    def abort(self, reason: str) -> None:
        """Stop the mission on this drone: no more actions; the vehicle lands."""
        if self.aborted.is_set():
            return
        self.abort_reason = reason
        self.aborted.set()
        self.log.warning("mission.abort", reason=reason)
        for ref in self.nodes.values():
            ref.tell(AbortMission(reason))
        if self.hal is not None:
            self.hal.tell(HalAbort())

    def wait_landed(self, timeout_s: float) -> bool:
        """Wait (on telemetry, not polling) until the vehicle reports it is on the ground."""
        if self.board is None:
            return True
        event = threading.Event()
        self.board.tell(_WhenLanded(event))
        return event.wait(timeout_s)

    def _to_ground(self, msg: Any) -> None:
        if self.ground_handler is not None:
            self.ground_handler(msg)
        elif self.out_actor is not None:
            self.out_actor.tell(msg)

    def send(self, msg: Any) -> None:
        """Publish a wire message through this participant's out-bridge."""
        if self.out_actor is not None:
            self.out_actor.tell(msg)

    def _on_message(self, msg: wire.Message) -> None:
        """In-Bridge callback (its own thread): route each message to its actor."""
        if isinstance(msg, wire.Trigger):
            ref = self.nodes.get(msg.dst_node)
            if ref is None or msg.dest != self.drone:
                self.log.warning("mission.inbridge.unknown_node", src=msg.sender, dst=msg.dst_node)
                return
            self.log.info(
                "mission.inbridge.received",
                src_drone=msg.sender,
                src=msg.src_node,
                dst=msg.dst_node,
                iteration=list(msg.iteration),
                status=msg.status,
            )
            self.executive.tell(_TriggerReceived(msg.sender))
            ref.tell(Trigger(msg.src_node, msg.dst_node, tuple(msg.iteration), msg.status))  # type: ignore[arg-type]
        elif isinstance(msg, wire.TelemetrySample):
            self.board.tell(RemoteTelemetry(msg.sender, telemetry_values(msg)))
            if self.ground_handler is not None:
                self.ground_handler(msg)
        elif isinstance(msg, TelemetryStale):
            # Withdraw the drone's values: a condition reading them now waits
            # (Unknown) for a fresh sample instead of deciding on old data.
            # The link logged mission.telemetry.stale.
            self.board.tell(RemoteTelemetry(msg.sender, stale_values(msg.age_s)))
        elif isinstance(msg, PeerStatus):
            # The link logged mission.peer.<state>; the ground station shows it.
            if self.ground_handler is not None:
                self.ground_handler(msg)
        elif isinstance(msg, wire.Interrupt):
            try:
                scope = int(msg.scope)
            except ValueError:
                self.log.warning("mission.inbridge.bad_interrupt", scope=msg.scope)
                return
            self.executive.tell(_DeliverInterrupt(Interrupt(scope, tuple(msg.iteration), msg.mode)))
        elif isinstance(msg, wire.Abort):
            self.abort(msg.reason or f"abort from {msg.sender}")
        elif isinstance(msg, wire.Complete):
            self.log.info("mission.complete", sender=msg.sender)
            self.completed.set()
        elif isinstance(msg, wire.Start):
            self.log.info("mission.start", sender=msg.sender)
        elif self.ground_handler is not None:
            self.ground_handler(msg)

    # -- results ---------------------------------------------------------------------------

    def report(self) -> dict[str, Any]:
        """This drone's part of the run summary."""
        snap: dict[str, Any] = (
            self.executive.ask(_Snapshot(), timeout=30)
            if self.executive
            else {"records": [], "triggers_received": 0, "resolved": {}, "all_resolved": False}
        )
        counts = self.out_actor.counts() if self.out_actor else {"triggers_sent": 0}
        net = self.link.stats() if self.link is not None else {}
        local = self.board.ask(_LatestLocal(), timeout=30) if self.board else None
        stats = self.program.stats()
        actions = [
            {
                "node": r.node,
                "action": r.action,
                "args": list(r.args),
                "iteration": list(r.iteration),
                "start": r.start,
                "end": r.end,
                "result": r.result,
                **({"reason": r.reason} if r.reason else {}),
            }
            for r in sorted(snap["records"], key=lambda r: (r.start, r.node))
        ]
        failed = [a for a in actions if a["result"] == "failed"]
        blocked = sorted(k for k, s in snap["resolved"].items() if s == "failed")
        return {
            "ok": bool(snap["all_resolved"])
            and not failed
            and not blocked
            and not self.aborted.is_set(),
            "resolved": bool(snap["all_resolved"]),
            "aborted": self.aborted.is_set(),
            "abort_reason": self.abort_reason,
            "triggers_sent": counts["triggers_sent"],
            "triggers_received": snap["triggers_received"],
            "external_out": stats["external_out"],
            "external_in": stats["external_in"],
            "mdg": stats,
            "blocked_nodes": blocked,
            "actions": actions,
            "final": None
            if local is None
            else {
                "x": local.x_m,
                "y": local.y_m,
                "z": local.z_m,
                "armed": local.armed,
                "battery": local.battery_pct,
            },
            "adapter_error": str(self.adapter_error) if self.adapter_error else "",
            # Each trigger counts once above; what it took on the network is here.
            "retransmissions": net.get("retransmissions", 0),
            "duplicates_dropped": net.get("duplicates_dropped", 0),
            "net": net,
        }

    def stop(self) -> None:
        """Stop every actor and close the bridges; idempotent."""
        if self._stopped:
            return
        self._stopped = True
        if self.link is not None:
            # Goodbye heartbeat, then the receive side closes (no callbacks into
            # actors being stopped); the send side closes below, after the actors.
            self.link.close_receiving()
        for ref in [*self.nodes.values(), self.executive, self.board, self.hal]:
            if ref is not None:
                try:
                    ref.stop(block=True, timeout=30)
                except (pykka.ActorDeadError, pykka.Timeout):
                    pass
        if self.dispatcher is not None:
            self.dispatcher.shutdown()
        if self.link is not None:
            self.link.close()
        if self._own_context:
            self.context.term()
        self.logs.close()
