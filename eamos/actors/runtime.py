"""One drone's execution environment (paper Section VI, Figure 3 F-K).

:class:`DroneRuntime` loads a drone program and builds, for that drone only:
one :class:`~.node.MissionNode` actor per native MDG node, the uniform-API
actor over its adapter, a :class:`~.board.TelemetryBoard` (latest property
values, pushed to the conditions that read them), an :class:`~.outbox.Outbox`
(the Out-Bridge) and an In-Bridge (:class:`~.inbound.InRouter` on the link) to
the other participants, and a :class:`~.executive.DroneExecutive` that keeps
the records.  It holds no global state: two runtimes live happily in one
process (as the tests do).

Failures of its own parts (not the nodes', which resolve ``failed``) go to a
:class:`~.failure.FailurePolicy`: logged once with the traceback, the drone
aborts (it lands), the drones waiting for it are released, and the ground
station hears ``Resolved`` at once (see :meth:`DroneRuntime._fail_safe`).  So
does a ``BaseException`` (``SystemExit``, ``KeyboardInterrupt``) raised inside
any of its actors, a node's included: it ends this drone's part, never another
runtime's in the same process (:meth:`.FailurePolicy.on_actor_exit`, the node
dispatcher's exit hook; the runtime parts report to the policy themselves).
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pykka
import zmq

from ..hal.api import Adapter, AdapterError
from ..logs import DroneLogs, LogWriter
from ..net import wire
from ..net.bridges import InBridge, OutBridge
from ..net.keys import FleetKeys, KeysError, plain_refusal
from ..net.link import Link, LinkSettings
from ..program.format import DroneProgram
from .board import LocalSample, TelemetryBoard, WhenLanded, ask_final_sample
from .dispatch import Dispatcher
from .executive import PROGRESS_INTERVAL_S as PROGRESS_INTERVAL_S
from .executive import DroneExecutive as DroneExecutive
from .executive import ask_snapshot
from .failure import FailurePolicy, RuntimeFailure, tell_operator
from .inbound import InRouter
from .logic import program_wiring
from .logic.telemetry import stale_values as stale_values
from .logic.telemetry import telemetry_values as telemetry_values
from .messages import AbortMission, Fire
from .node import Links, MissionNode, Wire
from .outbox import Outbox
from .readiness import wait_listening
from .uniform_api import Abort as HalAbort
from .uniform_api import UniformSpace, answers_at_once, start_uniform_api
from .wiring import destinations, released_arcs, subscriptions, watched_peers

if TYPE_CHECKING:
    from .report import DroneReport

# Outbox, TelemetryBoard, DroneExecutive, the telemetry-values functions and
# PROGRESS_INTERVAL_S stay importable from here (their home before the split).
__all__ = [
    "FINAL_SAMPLE_WAIT_S",
    "DroneExecutive",
    "DroneRuntime",
    "DroneRuntimeError",
    "NetSettings",
    "Outbox",
    "TelemetryBoard",
    "stale_values",
    "telemetry_values",
]

#: How long the report waits for the vehicle's first sample after its last
#: state-changing action (adapters send one when the state changes).
FINAL_SAMPLE_WAIT_S = 0.5
_ASK_TIMEOUT_S = 30.0


class DroneRuntimeError(Exception):
    """A drone runtime cannot start or run (bad program, adapter unusable, network)."""


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
        battery_reserve_pct: float | None = None,
        log_writer: LogWriter | None = None,
    ) -> None:
        """``log_writer``: the process's log writer when several runtimes share a process."""
        self.program = program
        self.battery_reserve_pct = battery_reserve_pct  # a Try's Body fails below it
        self.drone = program.drone
        self.adapter = adapter
        self.net = net
        self.log_dir = log_dir
        self._own_context = context is None
        self.context = context if context is not None else zmq.Context()
        self.ground_handler = ground_handler  # set on the ground station: receives drone reports
        self.extra_topics = extra_topics
        self.logs = DroneLogs.open(log_dir, self.drone, log_writer)
        self.log = self.logs.mission
        self.failures = FailurePolicy(self.log, self._fail_safe, self.drone)
        self.link: Link | None = None
        self.out: OutBridge | None = None
        self.inb: InBridge | None = None
        self.outbox: Outbox | None = None
        self.board: Any = None
        self.hal: Any = None
        self.uniform: UniformSpace | None = None
        self.executive: Any = None
        self.nodes: dict[str, Any] = {}
        self.router: InRouter | None = None  # the in-bridge's callback, once connected
        self.dispatcher: Dispatcher | None = None  # the node actors'
        self.services: Dispatcher | None = None  # the telemetry board's (one actor: one worker)
        self.completed = threading.Event()
        self.aborted = threading.Event()
        self.abort_reason = ""
        self.adapter_error: AdapterError | None = None
        self._lock = threading.Lock()
        self._resolved_told = self._stopped = False
        self.started_at = 0.0

    # -- building -------------------------------------------------------------------

    def start(self) -> None:
        """Build every actor and bridge; raise :class:`DroneRuntimeError` if the drone can't run."""
        self.started_at = time.monotonic()
        try:
            self._check_settings()
            self._open_link()
            self._start_board()
            self._start_uniform_api()
            self._start_nodes()
            self._start_executive()
            self._wire_nodes()
            self._connect()
        except DroneRuntimeError:
            self.stop()
            raise
        assert self.link is not None
        self.log.info(
            "mission.runtime.started",
            nodes=len(self.nodes),
            program=self.program.checksum,
            seconds=round(time.monotonic() - self.started_at, 4),
            secure=self.link.secure,
        )

    def _check_settings(self) -> None:
        refusal = self.net.refusal(self.drone)
        if refusal is not None:
            raise DroneRuntimeError(f"{self.drone}: {refusal}")

    def _open_link(self) -> None:
        """Bind the Out-Bridge (the in-bridge connects last, once every actor exists)."""
        try:
            self.link = Link(
                self.context,
                self.drone,
                self.program.mission_id,
                self.net.bind,
                self.logs.mission,
                keys=self.net.keys,
                settings=self.net.link,
            )
        except (zmq.ZMQError, KeysError) as exc:
            raise DroneRuntimeError(
                f"cannot bind the out-bridge at {self.net.bind}: {exc}"
            ) from exc
        self.out = self.link.out
        self.outbox = Outbox(self.link, self.drone, self.program.mission_id, self.logs.mission)

    def _start_board(self) -> None:
        self.services = Dispatcher(workers=1, name=f"eamos-{self.drone}-services")
        self.board = TelemetryBoard.start(
            self.services, self.drone, self.outbox, self.program.mission_id, self.failures
        )

    def _start_uniform_api(self) -> None:
        """Start the adapter behind the uniform-API actor; an unusable one stops the start."""
        board = self.board
        self.uniform = UniformSpace(self.adapter, self.logs.uniform)
        self.hal, error = start_uniform_api(
            self.uniform, lambda sample: board.tell(LocalSample(sample))
        )
        if error is not None:
            self.adapter_error = error
            raise DroneRuntimeError(f"{self.drone}: {error}")

    def _start_nodes(self) -> None:
        """One node actor per native node, on the node dispatcher (not started wired)."""
        self.dispatcher = Dispatcher(2, f"eamos-{self.drone}", self.failures.on_actor_exit)
        for key, w in program_wiring(self.program).items():
            self.nodes[key] = MissionNode.start(
                self.dispatcher,
                w.spec,
                w.routes,
                w.entry,
                w.loop,
                self.drone,
                self.logs.mission,
                w.begin_kind,
                battery_floor_pct=self.battery_reserve_pct,
            )

    def _start_executive(self) -> None:
        assert self.dispatcher is not None
        # On the nodes' dispatcher: their news (LazyMail) then wakes no other thread.
        self.executive = DroneExecutive.start(
            self.dispatcher,
            self.program,
            dict(self.nodes),
            self.outbox,
            self._to_ground,
            self.logs.mission,
            self.failures,
        )

    def _wire_nodes(self) -> None:
        """Give every node its links: all the actors it talks to exist now."""
        # Nodes call an adapter that answers at once directly (no hop through the actor).
        direct = self.uniform if answers_at_once(self.adapter) else None
        links = Links(dict(self.nodes), self.hal, self.board, self.outbox, self.executive, direct)
        for ref in self.nodes.values():
            ref.tell(Wire(links))

    def _connect(self) -> None:
        """Connect the In-Bridge to the peers; from now on messages arrive."""
        assert self.link is not None
        self.router = router = InRouter(
            self.drone,
            self.nodes,
            self.executive,
            self.board,
            self.log,
            self.abort,
            self.completed,
            self.failures,
            self.ground_handler,
        )
        topics = subscriptions(self.program, self.extra_topics)
        peers = {name: ep for name, ep in self.net.peers.items() if name != self.drone}
        try:
            # The ground station, up first, connects to a drone when it subscribes (listens).
            waits = peers if self.ground_handler is not None else ()
            self.link.connect(peers, topics, router, watch=self.watched_peers(), announced=waits)
        except (zmq.ZMQError, ValueError) as exc:
            raise DroneRuntimeError(f"cannot connect the in-bridge to {peers}: {exc}") from exc
        self.inb = self.link.inb

    def watched_peers(self) -> list[str] | None:
        """Peers whose heartbeats this participant follows (None: every peer)."""
        return watched_peers(self.program, whole_fleet=self.ground_handler is not None)

    # -- readiness ---------------------------------------------------------------------

    def destinations(self) -> list[str]:
        """Every participant this drone sends to (the ground station always)."""
        return destinations(self.program)

    def announce_ready(self, timeout_s: float, stop: threading.Event | None = None) -> bool:
        """Wait until every participant this drone sends to listens, then tell the ground
        station this drone is ready (:mod:`.readiness`); False if they never all did.

        ``stop`` (set by a signal handler) ends the wait early: a node asked to stop
        while its peers are missing must not linger for the whole timeout.
        """
        assert self.out is not None
        missing = wait_listening(self.out, self.destinations(), timeout_s, stop, self._waiting)
        if missing:
            self.log.error("mission.not_ready", waiting_for=missing)
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

    def _waiting(self, missing: list[str], waited_s: float) -> None:
        self.log.info("mission.waiting_for_peers", peers=missing, waited_s=round(waited_s, 1))
        tell_operator(self.drone, f"waiting for {', '.join(missing)} to listen ({waited_s:.0f} s)")

    # -- running -------------------------------------------------------------------------

    def fire(self) -> None:
        """Trigger the initial node (only the ground station's program has one)."""
        for node in self.program.native_nodes():
            if node.kind == "init":
                self.nodes[node.key].tell(Fire())

    def abort(self, reason: str, land: bool = True) -> None:
        """Stop the mission on this drone: no more actions; the vehicle lands.

        Landing comes first and is always reachable: if the uniform-API actor
        is dead, the adapter is told directly; a dead node actor is skipped.
        ``land=False`` (the ``hold`` end policy) stops the mission only.
        """
        with self._lock:
            if self.aborted.is_set():
                return
            self.abort_reason = reason
            self.aborted.set()
        self.log.warning("mission.abort", reason=reason, land=land)
        if land:
            land_now(self.hal, self.adapter, self.log)
        for ref in self.nodes.values():
            try:
                ref.tell(AbortMission(reason))
            except pykka.ActorDeadError:
                continue

    def _fail_safe(self, failure: RuntimeFailure) -> None:
        """The failure policy's reaction to the first exception in a part of this runtime.

        Nothing this drone's nodes do can be trusted any more: see :meth:`_give_up`.
        """
        self._give_up(failure.reason(), "mission.failure.released", land=True)

    def end_stranded(self, reason: str, policy: str = "land") -> None:
        """Apply the end policy: this drone can no longer finish its part (a peer is lost).

        Nothing here is broken, but the same holds: see :meth:`_give_up`
        (``hold``: the drone stays where it is instead of landing).
        """
        self.log.warning("mission.stranded", reason=reason, policy=policy)
        self._to_ground(stranded_progress(self.program, reason, policy))
        self._give_up(reason, "mission.stranded.released", land=policy != "hold")

    def _give_up(self, reason: str, event: str, land: bool) -> None:
        """This drone's nodes no longer speak: its out-bridge stops sending for them,
        the drone aborts (it lands), every outgoing arc outside loops not yet
        triggered gets ``failed`` (the drones waiting for this one are blocked and
        finish), and the ground station hears ``Resolved`` now."""
        if self.outbox is not None:
            self.outbox.seal()
        self.abort(reason, land=land)
        if self.outbox is not None:
            self.log.warning(event, triggers=self.outbox.release(released_arcs(self.program)))
        self._to_ground(wire.Resolved(mission=self.program.mission_id, sender=self.drone))

    def wait_landed(self, timeout_s: float) -> bool:
        """Wait (on telemetry, not polling) until the vehicle reports it is on the ground."""
        if self.board is None:
            return True
        event = threading.Event()
        self.board.tell(WhenLanded(event))
        return event.wait(timeout_s)

    def _to_ground(self, msg: Any) -> None:
        if isinstance(msg, wire.Resolved):
            with self._lock:  # the executive and the failure policy may both say it
                if self._resolved_told:
                    return
                self._resolved_told = True
        if self.ground_handler is not None:
            self.ground_handler(msg)
        elif self.outbox is not None:
            self.outbox.tell(msg)

    def send(self, msg: Any) -> None:
        """Publish a wire message through this participant's out-bridge."""
        if self.outbox is not None:
            self.outbox.tell(msg)

    # -- results ---------------------------------------------------------------------------

    def drone_report(self, final_wait_s: float = FINAL_SAMPLE_WAIT_S) -> DroneReport:
        """This drone's part of the run summary.

        The final state is the vehicle's once its last action ended: the first sample after
        the last action that could change it (waiting up to ``final_wait_s``), never one before.
        """
        from .report import DroneReport  # loaded here, at a flight's end: not before Ready

        snap = ask_snapshot(self.executive, _ASK_TIMEOUT_S)
        counts = self.outbox.counts() if self.outbox else {"triggers_sent": 0}
        return DroneReport.build(
            self.program,
            snap,
            triggers_sent=counts["triggers_sent"],
            net=self.link.stats() if self.link is not None else {},
            final=ask_final_sample(
                self.board, snap.state_changed_s, snap.state_action, final_wait_s, _ASK_TIMEOUT_S
            ),
            aborted=self.aborted.is_set(),
            abort_reason=self.abort_reason,
            adapter_error=str(self.adapter_error) if self.adapter_error else "",
        )

    def report(self) -> dict[str, Any]:
        """:meth:`drone_report` as JSON (what goes to the ground station)."""
        return self.drone_report().to_json()

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
        if self.hal is not None and not self.hal.is_alive():
            close_orphan(self.adapter, self.log)
        for dispatcher in (self.dispatcher, self.services):
            if dispatcher is not None:
                dispatcher.shutdown()
        if self.link is not None:
            self.link.close()
        if self._own_context:
            self.context.term()
        self.logs.close()


def land_now(hal: Any, adapter: Adapter, log: Any) -> None:
    """Tell the vehicle to land: through the uniform API, or the adapter if that actor died."""
    try:
        if hal is not None and hal.is_alive():
            hal.tell(HalAbort())
            return
    except pykka.ActorDeadError:
        pass
    log.error("mission.abort.direct", why="the uniform-API actor is dead")
    try:
        adapter.abort()
    except Exception as exc:  # nothing else can land it: say so loudly
        log.error("mission.abort.adapter_error", error=repr(exc))


def close_orphan(adapter: Adapter, log: Any) -> None:
    """Close the adapter a dead uniform-API actor left open (so its landing could finish)."""
    try:
        adapter.close()
    except Exception as exc:
        log.error("mission.adapter.close_error", error=repr(exc))


def stranded_progress(program: DroneProgram, reason: str, policy: str) -> wire.Progress:
    """The progress line the ground station shows when this drone applies its end policy."""
    return wire.Progress(
        mission=program.mission_id,
        sender=program.drone,
        state="stranded",
        node="",
        action=f"end policy: {policy}",
        detail={"detail": reason},
    )
