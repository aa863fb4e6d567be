"""How a drone runtime's parts are built, each from the program and the settings (start-up).

:class:`RuntimeStartup` builds them in the order they need each other: the
Out-Bridge first (the board and the executive send through it), the telemetry
board, the uniform-API actor over the adapter (an adapter that cannot start
stops the start), one node actor per native node, the executive; then every
node gets its links, and the In-Bridge connects last, once every actor a
message may be for exists.  :class:`~.runtime.DroneRuntime` keeps what it
builds (and stops what was built when a step fails).
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import pykka
import zmq

from ..hal.api import Adapter, AdapterError, Telemetry, read_at_most
from ..logs import DroneLogs
from ..net import wire
from ..net.bridges import InBridge
from ..net.effects import TriggersAcknowledged
from ..net.keys import FleetKeys, KeysError, plain_refusal
from ..net.link import Delivered, Link, LinkSettings
from ..net.receive_host import ReceiveHost
from ..net.timers import TimerHost
from ..net.zap import ZapHandler
from ..program.format import DroneProgram
from .board import LatestSample, LocalSample, TelemetryBoard
from .continuation import Replay
from .dispatch import Dispatcher, tell_here
from .errors import DroneRuntimeError
from .executive import DroneExecutive
from .failure import FailurePolicy, tell_operator
from .inbound import InRouter, StartGate, incoming_arcs
from .logic import program_wiring
from .node import Links, MissionNode, Wire
from .outbox import Outbox
from .rejoin import acknowledged_entry
from .uniform_api import UniformAPI, UniformSpace, answers_at_once, start_uniform_api
from .wiring import subscriptions, telemetry_read_hz, watched_peers

__all__ = ["NetSettings", "RuntimeStartup", "StartGateSettings"]


@dataclass(frozen=True)
class StartGateSettings:
    """A drone node's :class:`~.inbound.StartGate`: the deployment whose Start it takes
    ("": any) and what to call once, before the first trigger reaches a node."""

    deployment: str = ""
    on_running: Callable[[], None] | None = None


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


class RuntimeStartup:
    """Builds the parts of one drone's runtime (module docstring), one method per part.

    ``ground_handler`` is set on the ground station (it receives the fleet's reports
    and follows every drone's heartbeats); ``extra_topics`` are subscribed besides the
    program's; ``battery_reserve_pct`` is the floor below which a Try's Body fails.
    """

    def __init__(
        self,
        program: DroneProgram,
        adapter: Adapter,
        net: NetSettings,
        logs: DroneLogs,
        failures: FailurePolicy,
        context: zmq.Context[Any],
        *,
        ground_handler: Callable[[Delivered], None] | None = None,
        extra_topics: tuple[bytes, ...] = (),
        battery_reserve_pct: float | None = None,
        start_gate: StartGateSettings | None = None,
        replay: Replay | None = None,
        journal: Callable[[list[dict[str, Any]]], None] | None = None,
        zap: ZapHandler | None = None,
        timers: TimerHost | None = None,
        receivers: ReceiveHost | None = None,
    ) -> None:
        self.program = program
        self.zap = zap  # the shared context's ZAP handler (None: the link starts its own)
        self.timers = timers  # the process's link timer thread (None: the link's own)
        self.receivers = receivers  # the process's receive thread (None: the link's own)
        self.start_gate = start_gate
        self.replay = replay  # a restarted node's past (see DroneRuntime)
        self.journal = journal
        self.latest = LatestSample()
        self.drone = program.drone
        self.adapter = adapter
        self.net = net
        self.logs = logs
        self.failures = failures
        self.context = context
        self.ground_handler = ground_handler
        self.extra_topics = extra_topics
        self.battery_reserve_pct = battery_reserve_pct

    def check_settings(self) -> None:
        """Refuse network settings this drone may not use (plain sockets off-host, wrong keys)."""
        refusal = self.net.refusal(self.drone)
        if refusal is not None:
            raise DroneRuntimeError(f"{self.drone}: {refusal}")

    def open_link(self) -> Link:
        """Bind the Out-Bridge (the in-bridge connects last, once every actor exists)."""
        try:
            return Link(
                self.context,
                self.drone,
                self.program.mission_id,
                self.net.bind,
                self.logs.mission,
                keys=self.net.keys,
                settings=self.net.link,
                zap=self.zap,
                timers=self.timers,
                receivers=self.receivers,
            )
        except (zmq.ZMQError, KeysError) as exc:
            raise DroneRuntimeError(
                f"cannot bind the out-bridge at {self.net.bind}: {exc}"
            ) from exc

    def outbox(self, link: Link) -> Outbox:
        """The Out-Bridge as the actors see it."""
        return Outbox(
            link,
            self.drone,
            self.program.mission_id,
            self.logs.mission,
            acknowledged=self.replay.acknowledged if self.replay is not None else frozenset(),
        )

    def services(self) -> Dispatcher:
        """The telemetry board's dispatcher (one actor: one worker)."""
        return Dispatcher(workers=1, name=f"eamos-{self.drone}-services")

    def start_board(self, services: Dispatcher, outbox: Outbox) -> pykka.ActorRef[TelemetryBoard]:
        """The telemetry board, sending this drone's samples through ``outbox``."""
        return TelemetryBoard.start(
            services, self.drone, outbox, self.program.mission_id, self.failures
        )

    def uniform_space(self) -> UniformSpace:
        """The uniform API's bookkeeping over the adapter."""
        return UniformSpace(self.adapter, self.logs.uniform)

    def start_uniform_api(
        self, space: UniformSpace, board: pykka.ActorRef[TelemetryBoard]
    ) -> tuple[pykka.ActorRef[UniformAPI], AdapterError | None]:
        """Start the adapter behind the uniform-API actor (its samples go to ``board``);
        the actor, and the adapter's error when it could not start."""
        latest = self.latest

        def on_sample(sample: Telemetry) -> None:
            latest.put(sample)
            # The board's turn runs on the adapter's thread (caller runs): a worker
            # woken for every sample cost more than the turn; it never calls the adapter.
            tell_here(board, LocalSample(sample))

        self.pace_telemetry(self.program)
        return start_uniform_api(space, on_sample)

    def pace_telemetry(self, program: DroneProgram) -> None:
        """Tell the adapter how often ``program``'s drone reads its samples at most."""
        read_at_most(
            self.adapter, telemetry_read_hz(program, self.net.link, self.battery_reserve_pct)
        )

    def node_dispatcher(self) -> Dispatcher:
        """The node actors' dispatcher (the executive runs on it too)."""
        return Dispatcher(2, f"eamos-{self.drone}", self.failures.on_actor_exit)

    def start_nodes(
        self, dispatcher: Dispatcher, into: dict[str, pykka.ActorRef[MissionNode]]
    ) -> None:
        """One node actor per native node, into ``into`` (not wired yet: see :meth:`wire_nodes`)."""
        for key, w in program_wiring(self.program).items():
            into[key] = MissionNode.start(
                dispatcher,
                w.spec,
                w.routes,
                w.entry,
                w.loop,
                self.drone,
                self.logs.mission,
                w.begin_kind,
                battery_floor_pct=self.battery_reserve_pct,
                replay=self.replay,
            )

    def start_executive(
        self,
        dispatcher: Dispatcher,
        nodes: dict[str, pykka.ActorRef[MissionNode]],
        outbox: Outbox,
        to_ground: Callable[[wire.Message], None],
        resolved: threading.Event,
    ) -> pykka.ActorRef[DroneExecutive]:
        """The executive, on the nodes' dispatcher: their news (LazyMail) then wakes no
        other thread; it sets ``resolved`` once the drone's part resolved."""
        return DroneExecutive.start(
            dispatcher,
            self.program,
            dict(nodes),
            outbox,
            to_ground,
            self.logs.mission,
            self.failures,
            journal=self.journal,
            position=self.latest.position,
            resolved=resolved,
        )

    def wire_nodes(
        self,
        nodes: dict[str, pykka.ActorRef[MissionNode]],
        hal: pykka.ActorRef[UniformAPI],
        board: pykka.ActorRef[TelemetryBoard],
        outbox: Outbox,
        executive: pykka.ActorRef[DroneExecutive],
        space: UniformSpace,
    ) -> None:
        """Give every node its links: all the actors it talks to exist now."""
        # Nodes call an adapter that answers at once directly (no hop through the actor).
        direct = space if answers_at_once(self.adapter) else None
        links = Links(dict(nodes), hal, board, outbox, executive, direct)
        for ref in nodes.values():
            ref.tell(Wire(links))

    def router(
        self,
        nodes: dict[str, pykka.ActorRef[MissionNode]],
        executive: pykka.ActorRef[DroneExecutive],
        board: pykka.ActorRef[TelemetryBoard],
        abort: Callable[[str], None],
        completed: threading.Event,
        operator: Callable[[wire.Operator], None] | None = None,
        amend: Callable[[wire.Amend], None] | None = None,
    ) -> InRouter:
        """The In-Bridge's routing: each message to the actor it is for."""
        return InRouter(
            self.drone,
            nodes,
            executive,
            board,
            self.logs.mission,
            abort,
            completed,
            self.failures,
            self.ground_handler,
            arc_hosts=incoming_arcs(self.program),
            gate=self._gate(),
            operator=operator,
            amend=amend,
            acknowledged=self._journal_acknowledged if self.journal is not None else None,
        )

    def _journal_acknowledged(self, msg: TriggersAcknowledged) -> None:
        """Journal the triggers a peer acknowledged (on the link's thread: one write)."""
        assert self.journal is not None
        self.journal([acknowledged_entry(msg.triggers)])

    def _gate(self) -> StartGate | None:
        """A drone node's gate: nothing acts before its own deployment's Start."""
        settings = self.start_gate
        if settings is None or self.ground_handler is not None:
            return None
        return StartGate(
            self.drone, settings.deployment, self.logs.mission, settings.on_running, tell_operator
        )

    def connect(self, link: Link, router: InRouter) -> InBridge:
        """Connect the In-Bridge to the peers; from now on messages arrive."""
        topics = subscriptions(self.program, self.extra_topics)
        peers = {name: ep for name, ep in self.net.peers.items() if name != self.drone}
        try:
            # The ground station, up first, connects to a drone when it subscribes (listens).
            waits = peers if self.ground_handler is not None else ()
            link.connect(peers, topics, router, watch=self.watched_peers(), announced=waits)
        except (zmq.ZMQError, ValueError) as exc:
            named = ", ".join(f"{n} at {ep}" for n, ep in list(peers.items())[:3])
            more = f" and {len(peers) - 3} more" if len(peers) > 3 else ""
            raise DroneRuntimeError(
                f"cannot connect the in-bridge to {named}{more}: {exc}"
            ) from exc
        assert link.inb is not None
        return link.inb

    def watched_peers(self) -> list[str] | None:
        """Peers whose heartbeats this participant follows (None: every peer)."""
        return watched_peers(self.program, whole_fleet=self.ground_handler is not None)
