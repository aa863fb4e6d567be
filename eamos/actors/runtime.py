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

How each part is built is :mod:`.startup`'s business, how they stop
:mod:`.teardown`'s, how the drone's report is gathered :mod:`.reporting`'s and
how it announces itself ready :mod:`.readiness`'s; the runtime holds the parts,
starts them in order and runs the mission on this drone (fire, abort, give up).
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pykka
import zmq

from ..hal.api import Adapter, AdapterError, AdapterNotice, taken_over, vehicle_facts
from ..logs import DroneLogs, EventLog, LogWriter
from ..net import wire
from ..net.bridges import InBridge, OutBridge
from ..net.link import Delivered, Link
from ..net.receive_host import ReceiveHost
from ..net.sockets import participant_context
from ..net.timers import TimerHost
from ..net.zap import ZapHandler
from ..program.format import DroneProgram
from .board import TelemetryBoard, WhenLanded
from .continuation import Replay
from .dispatch import Dispatcher
from .errors import DroneRuntimeError
from .executive import PROGRESS_INTERVAL_S as PROGRESS_INTERVAL_S
from .executive import DroneExecutive as DroneExecutive
from .failure import FailurePolicy, RuntimeFailure, tell_operator
from .inbound import InRouter
from .logic.telemetry import stale_values as stale_values
from .logic.telemetry import telemetry_values as telemetry_values
from .messages import AbortMission, Fire
from .node import MissionNode
from .operator import Operate
from .outbox import Outbox
from .readiness import announce_ready
from .reporting import gather_report
from .reprogram import Reprogramming
from .startup import NetSettings, RuntimeStartup, StartGateSettings
from .teardown import tear_down
from .uniform_api import Abort as HalAbort
from .uniform_api import UniformAPI, UniformSpace
from .wiring import destinations, released_arcs

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
    "StartGateSettings",
    "TelemetryBoard",
    "stale_values",
    "telemetry_values",
]

#: How long the report waits for the vehicle's first sample after its last
#: state-changing action (adapters send one when the state changes).
FINAL_SAMPLE_WAIT_S = 0.5


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
        zap: ZapHandler | None = None,
        timers: TimerHost | None = None,
        receivers: ReceiveHost | None = None,
        ground_handler: Callable[[Delivered], None] | None = None,
        extra_topics: tuple[bytes, ...] = (),
        battery_reserve_pct: float | None = None,
        log_writer: LogWriter | None = None,
        start_gate: StartGateSettings | None = None,
        replay: Replay | None = None,
        journal: Callable[[list[dict[str, Any]]], None] | None = None,
        on_reprogrammed: Callable[[DroneProgram], None] | None = None,
    ) -> None:
        """``log_writer``: the process's log writer when several runtimes share a process;
        ``context``, ``zap``: a ZeroMQ context and its ZAP handler that several runtimes
        share (:class:`~eamos.net.zap.ZapHandler`; None: its own context); ``timers``: the
        process's link timer thread that several runtimes share (None: the link's own);
        ``receivers``: the process's In-Bridge receive thread, likewise;
        ``start_gate``: a drone's node takes only its own deployment's Start, and acts on
        nothing before it (:class:`~.inbound.StartGate`; None: no gate); ``replay``: a
        node restarted mid-mission replays what it reported (:mod:`.continuation`);
        ``journal``: receives each batch of progress reported (:mod:`.rejoin`);
        ``on_reprogrammed``: told each program an amendment switched to (:mod:`.reprogram`)."""
        self.program = program
        self.on_reprogrammed = on_reprogrammed
        self.battery_reserve_pct = battery_reserve_pct  # a Try's Body fails below it
        self.drone = program.drone
        self.adapter = adapter
        self.net = net
        self.log_dir = log_dir
        self._own_context = context is None
        self.context: zmq.Context[Any] = context if context is not None else participant_context()
        self.ground_handler = ground_handler  # set on the ground station: receives drone reports
        self.extra_topics = extra_topics
        self.logs = DroneLogs.open(log_dir, self.drone, log_writer)
        self.log: EventLog = self.logs.mission
        self.failures = FailurePolicy(self.log, self._fail_safe, self.drone)
        self._startup = RuntimeStartup(
            program,
            adapter,
            net,
            self.logs,
            self.failures,
            self.context,
            ground_handler=ground_handler,
            extra_topics=extra_topics,
            battery_reserve_pct=battery_reserve_pct,
            start_gate=start_gate,
            replay=replay,
            journal=journal,
            zap=zap,
            timers=timers,
            receivers=receivers,
        )
        # The parts, as far as they are built (None: not yet, or the start failed before).
        self.link: Link | None = None
        self.out: OutBridge | None = None
        self.inb: InBridge | None = None
        self.outbox: Outbox | None = None
        self.board: pykka.ActorRef[TelemetryBoard] | None = None
        self.hal: pykka.ActorRef[UniformAPI] | None = None
        self.uniform: UniformSpace | None = None
        self.executive: pykka.ActorRef[DroneExecutive] | None = None
        self.nodes: dict[str, pykka.ActorRef[MissionNode]] = {}
        self.router: InRouter | None = None  # the in-bridge's callback, once connected
        self.dispatcher: Dispatcher | None = None  # the node actors'
        self.services: Dispatcher | None = None  # the telemetry board's (one actor: one worker)
        self.completed = threading.Event()
        self.aborted = threading.Event()
        self.part_resolved = threading.Event()  # set by the executive: every top-level node ended
        self.abort_reason = ""
        # Paused or held by the operator (until a resume): only the ground station resumes.
        self.held_by_operator = False
        self.adapter_error: AdapterError | None = None
        self._lock = threading.Lock()
        self._resolved_told = self._stopped = False
        self.started_at = 0.0

    # -- building -------------------------------------------------------------------

    def start(self) -> None:
        """Build every actor and bridge; raise :class:`DroneRuntimeError` if the drone can't run."""
        self.started_at = time.monotonic()
        try:
            self._build()
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

    def _build(self) -> None:
        """The parts in the order they need each other (:class:`.startup.RuntimeStartup`),
        each kept as soon as it exists: a failed start stops what was built."""
        build = self._startup
        build.check_settings()
        self.link = link = build.open_link()
        self.out = link.out
        self.outbox = outbox = build.outbox(link)
        self.services = build.services()
        self.board = board = build.start_board(self.services, outbox)
        self.uniform = space = build.uniform_space()
        space.on_notice = self._notice  # a pilot's takeover, slow telemetry: to the ground
        space.on_status = self._autopilot_status  # its mode, its STATUSTEXTs: to the ground
        self.hal, self.adapter_error = build.start_uniform_api(space, board)
        if self.adapter_error is not None:  # an unusable adapter stops the start
            raise DroneRuntimeError(f"{self.drone}: {self.adapter_error}")
        self.dispatcher = build.node_dispatcher()
        build.start_nodes(self.dispatcher, self.nodes)
        self.executive = build.start_executive(
            self.dispatcher, self.nodes, outbox, self._to_ground, self.part_resolved
        )
        build.wire_nodes(self.nodes, self.hal, board, outbox, self.executive, space)
        # A drone takes amendments from its ground station (the ground station none).
        amend = None
        if self.ground_handler is None:
            amend = Reprogramming(self, build, self.on_reprogrammed).handle
        self.router = build.router(
            self.nodes, self.executive, board, self.abort, self.completed, self.operate, amend
        )
        self.inb = build.connect(link, self.router)

    # -- readiness ---------------------------------------------------------------------

    def destinations(self) -> list[str]:
        """Every participant this drone sends to (the ground station always)."""
        return destinations(self.program)

    def announce_ready(self, timeout_s: float, stop: threading.Event | None = None) -> bool:
        """Wait until every participant this drone sends to listens, then tell the ground
        station this drone is ready (:func:`.readiness.announce_ready`); False if they
        never all did.  ``stop`` (set by a signal handler) ends the wait early."""
        assert self.out is not None
        return announce_ready(self.out, self.program, self._to_ground, self.log, timeout_s, stop)

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

    def operate(self, msg: wire.Operator) -> None:
        """The operator's command (:mod:`.operator`): logged with its origin, carried out by
        the uniform API (on its thread: a MAVLink adapter is called from there only), and
        shown at the ground station."""
        self.log.warning(
            "mission.operator", command=msg.command, target=msg.target, origin=msg.origin
        )
        self.held_by_operator = msg.command in ("pause", "hold")
        try:
            if self.hal is not None and self.hal.is_alive():
                self.hal.tell(Operate(msg.command))
            elif self.uniform is not None:
                self.uniform.operate(msg.command)
        except pykka.ActorDeadError:
            if self.uniform is not None:
                self.uniform.operate(msg.command)
        self._to_ground(operator_progress(self.program, msg))

    def _autopilot_status(self, mode: str, texts: list[tuple[int, str]]) -> None:
        """The autopilot's own mode and new STATUSTEXTs (severity, text): to the ground
        station, for the operator's page (progress state ``autopilot``)."""
        self._to_ground(
            wire.Progress(
                mission=self.program.mission_id,
                sender=self.drone,
                state="autopilot",
                node="",
                action=f"autopilot: {mode}",
                detail={"mode": mode, "statustext": [list(t) for t in texts], "at": time.time()},
            )
        )

    def _notice(self, notice: AdapterNotice) -> None:
        """What the adapter has for the operator (a pilot took the vehicle, telemetry
        too slow): the mission log, this node's stderr and the ground station's display."""
        self.log.warning("mission.adapter_notice", kind=notice.kind, text=notice.text)
        tell_operator(self.drone, notice.text)
        self._to_ground(notice_progress(self.program, notice))

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

    def stop_mission(self, reason: str) -> None:
        """Stop the mission on this drone for good (its node was told to stop: a signal).

        It lands, and the drones waiting for it are released at once (``failed`` on its
        outgoing arcs), as in :meth:`_give_up`; but it does not say ``Resolved``: its
        report, then its node's exit, end its part at the ground station, which counts
        them as a failure before the mission's end.
        """
        if self.outbox is not None:
            self.outbox.seal()
        self.abort(reason)
        if self.outbox is not None:
            released = self.outbox.release(released_arcs(self.program))
            self.log.warning("mission.stopped.released", triggers=released)

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
        """Wait (on telemetry, not polling) until the vehicle reports it is on the ground.

        False at once for a vehicle a pilot took over: nobody here lands it.
        """
        if self.board is None:
            return True
        if taken_over(self.adapter) is not None or (self.uniform and self.uniform.released):
            self.log.warning("mission.abort.taken_over", note="the pilot has it: not landed")
            return False
        event = threading.Event()
        self.board.tell(WhenLanded(event))
        return event.wait(timeout_s)

    def _to_ground(self, msg: wire.Message) -> None:
        if isinstance(msg, wire.Resolved):
            with self._lock:  # the executive and the failure policy may both say it
                if self._resolved_told:
                    return
                self._resolved_told = True
        if self.ground_handler is not None:
            self.ground_handler(msg)
        elif self.outbox is not None:
            self.outbox.tell(msg)

    def send(self, msg: wire.Message) -> None:
        """Publish a wire message through this participant's out-bridge."""
        if self.outbox is not None:
            self.outbox.tell(msg)

    # -- results ---------------------------------------------------------------------------

    def drone_report(self, final_wait_s: float = FINAL_SAMPLE_WAIT_S) -> DroneReport:
        """This drone's part of the run summary (:func:`.reporting.gather_report`).

        The final state is the vehicle's once its last action ended: the first sample after
        the last action that could change it (waiting up to ``final_wait_s``), never one before.
        """
        return gather_report(
            self.program,
            self.executive,
            self.board,
            self.outbox,
            self.link,
            final_wait_s=final_wait_s,
            aborted=self.aborted.is_set(),
            abort_reason=self.abort_reason,
            adapter_error=str(self.adapter_error) if self.adapter_error else "",
            vehicle=self._vehicle_facts(),
        )

    def _vehicle_facts(self) -> dict[str, Any]:
        """The adapter's facts; a vehicle the operator released is the pilot's, as after a
        takeover (the summary says where it was left)."""
        facts = vehicle_facts(self.adapter)
        released = self.uniform.released if self.uniform is not None else None
        if released is not None and "taken_over" not in facts:
            facts["taken_over"] = released.to_json()
        return facts

    def report(self) -> dict[str, Any]:
        """:meth:`drone_report` as JSON (what goes to the ground station)."""
        return self.drone_report().to_json()

    def stop(self) -> None:
        """Stop every actor and close the bridges (:func:`.teardown.tear_down`); idempotent."""
        if self._stopped:
            return
        self._stopped = True
        tear_down(
            self.link,
            [*self.nodes.values(), self.executive, self.board],
            self.hal,
            self.adapter,
            (self.dispatcher, self.services),
            self.log,
        )
        if self._own_context:
            self.context.term()
        self.logs.close()


def land_now(hal: pykka.ActorRef[UniformAPI] | None, adapter: Adapter, log: EventLog) -> None:
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


#: The action column of an adapter notice's progress line, by kind.
NOTICE_ACTIONS = {"taken_over": "the pilot has the vehicle", "warning": "adapter warning"}


def notice_progress(program: DroneProgram, notice: AdapterNotice) -> wire.Progress:
    """The progress line the ground station shows for an adapter's notice
    (state ``taken_over`` or ``warning``; the words in ``detail``)."""
    return wire.Progress(
        mission=program.mission_id,
        sender=program.drone,
        state=notice.kind,
        node="",
        action=NOTICE_ACTIONS.get(notice.kind, notice.kind),
        detail={"detail": notice.text, "at": time.time()},
    )


#: The state a drone shows after each operator command.
OPERATOR_STATES = {
    "pause": "paused",
    "hold": "held",
    "resume": "resumed",
    "land": "landing (operator)",
    "return-home": "returning home (operator)",
    "release": "released to a pilot",
}


def operator_progress(program: DroneProgram, msg: wire.Operator) -> wire.Progress:
    """The progress line the ground station shows when this drone obeys an operator command."""
    state = OPERATOR_STATES.get(msg.command, msg.command)
    return wire.Progress(
        mission=program.mission_id,
        sender=program.drone,
        state=state,
        node="",
        action=f"operator: {msg.command}",
        detail={
            "detail": f"{state}: {msg.command} from {msg.origin or msg.sender}",
            "command": msg.command,
            "origin": msg.origin,
            "at": time.time(),
        },
    )


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
