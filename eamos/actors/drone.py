"""One drone's part of a mission, from its config: what ``eamos-node`` does on a drone.

Load the program, start the drone runtime, report ready to the ground station
once every participant it sends to listens, execute until the ground station
declares the mission complete (or aborts), send the final report (and wait,
bounded, until it is acknowledged).  A ``stop`` event (a signal) aborts the
mission on this drone: the vehicle lands before this returns.
"""

from __future__ import annotations

import dataclasses
import enum
import json
import threading
import time
from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Any

import zmq

from eamos.config import ConfigError, NodeConfig
from eamos.hal import make_adapter
from eamos.logs import LogWriter, close_logger, make_logger, report_write_error
from eamos.net import wire
from eamos.net.receive_host import ReceiveHost
from eamos.net.reports import report_messages
from eamos.net.sockets import participant_context
from eamos.net.timers import TimerHost
from eamos.net.wire import WireError
from eamos.net.zap import ZapHandler
from eamos.program.format import DroneProgram, load_program
from eamos.program.uniform import GROUND_STATION

from .board import WhenSettled, ask_final_sample
from .continuation import Continuation, Replay, activations, continuation
from .executive import ask_activity, ask_snapshot
from .failure import tell_operator
from .messages import PeerLost
from .rejoin import NodeJournal, say
from .runtime import DroneRuntime, NetSettings, StartGateSettings
from .stranded import (
    EndOnOwn,
    activity_matters,
    caught_lost_peer,
    end_on_own,
    silent_since,
    trigger_sources,
)

if TYPE_CHECKING:
    from pathlib import Path

    from eamos.hal.sim import SimClock
    from eamos.net.link import Link

#: How long the drone's loop waits for the executive's answer (it answers in ms).
ASK_TIMEOUT_S = 30.0
REPORT_ACK_TIMEOUT_S = 60.0
"""How long a drone offers its final report until the ground station acknowledges it:
as long as the ground station waits for reports after a mission's end (a connection that
a lossy network cut takes seconds to come back, and the report goes again at once when
it does).  A ground station that leaves ends the wait sooner."""
REPORT_ACK_STOPPED_S = 10.0
"""... once a signal stopped the node; after this long the drone also says it still waits."""
VEHICLE_SILENT_S = 10.0
"""Landing, a vehicle that sends no telemetry sample for this long (wall seconds) is
silent (its link lost, its autopilot dead): the drone stops waiting for it to land."""


class NodeStop(threading.Event):
    """The node's stop: set by a signal (SIGINT, SIGTERM), which it names for the operator."""

    def __init__(self) -> None:
        super().__init__()
        self.name = ""

    def signal(self, name: str) -> None:
        """Stop because of the signal ``name`` (e.g. ``"SIGTERM"``); the first one is kept."""
        if not self.is_set():
            self.name = name
        self.set()


@dataclasses.dataclass(frozen=True)
class ProcessShare:
    """What the drones of one process share instead of having one each.

    One log writer (its thread writes every drone's lines, in batches), one
    clock stepping every simulated vehicle, one ZeroMQ context (one set of libzmq
    I/O and reaper threads) and its ZAP handler (one authenticator thread; each
    drone answers in a domain of its own: :class:`eamos.net.zap.ZapHandler`), and one
    thread ticking every drone's link (:class:`eamos.net.timers.TimerHost`) and one
    reading every drone's In-Bridge (:class:`eamos.net.receive_host.ReceiveHost`).
    :meth:`open` makes them, :meth:`close` ends them once every drone has stopped.
    """

    writer: LogWriter
    sim_clock: SimClock
    context: zmq.Context[Any]
    zap: ZapHandler
    timers: TimerHost
    receivers: ReceiveHost

    @classmethod
    def open(cls) -> ProcessShare:
        """A new set, for the drones about to start in this process."""
        from eamos.hal.sim import SimClock  # here: a process of one drone never loads it

        context = participant_context()
        return cls(
            LogWriter(),
            SimClock("sim-clock"),
            context,
            ZapHandler(context),
            TimerHost(),
            ReceiveHost(context),
        )

    def close(self) -> None:
        """End them (every drone stopped: its sockets are closed); the writer last."""
        self.sim_clock.close()
        self.timers.stop()
        self.receivers.stop()
        self.zap.stop()
        self.context.term()
        self.writer.close()


class DroneEnd(enum.Enum):
    """How a drone's part ended (the command line maps it to an exit code)."""

    DONE = "done"  # the mission part finished, the report says ok
    FAILED = "failed"  # the mission failed or was aborted on this drone
    UNREACHABLE = "unreachable"  # the peers never listened: the mission never started
    REFUSED = "refused"  # restarted mid-mission: it refuses to rejoin (.rejoin)


def load_node_program(config: NodeConfig) -> DroneProgram:
    """The program ``config`` names; ConfigError when it is another drone's."""
    program = load_program(config.program)
    if program.drone != config.drone:
        raise ConfigError(
            f"{config.path}: drone: is {config.drone!r} but the program is for {program.drone!r}"
        )
    return program


def report_ack_limit(stop: threading.Event) -> float:
    """How long a drone offers its final report: :data:`REPORT_ACK_STOPPED_S` once a
    signal stopped the node (``stop``), else :data:`REPORT_ACK_TIMEOUT_S`."""
    return REPORT_ACK_STOPPED_S if stop.is_set() else REPORT_ACK_TIMEOUT_S


def report_acknowledged(
    link: Link, stop: threading.Event, notice: Callable[[str], None] | None = None
) -> bool:
    """Wait until the ground station acknowledged the final report (True), for at most
    :data:`REPORT_ACK_TIMEOUT_S`, or :data:`REPORT_ACK_STOPPED_S` once a signal stopped
    the node (``stop``); a ground station that left ends the wait as acknowledged (the
    link waits for no peer that left).  ``notice`` is told once, after
    :data:`REPORT_ACK_STOPPED_S`, that the drone still waits."""
    began = time.monotonic()
    told = False
    while True:
        waited = time.monotonic() - began
        limit = report_ack_limit(stop)
        if waited >= limit:
            return False
        if notice is not None and not told and waited >= REPORT_ACK_STOPPED_S:
            told = True
            notice(
                f"the ground station has not acknowledged the report yet: it is offered for "
                f"up to {REPORT_ACK_TIMEOUT_S:g} s (Ctrl-C ends the wait)"
            )
        # In slices only so that a signal is noticed.
        if link.flush(min(limit - waited, 1.0), peers=[GROUND_STATION]):
            return True


def net_settings(config: NodeConfig) -> NetSettings:
    """The runtime's network settings from a node config (keys, or plain on loopback)."""
    return NetSettings(config.bind, config.peers, keys=config.keys, link=config.link)


def keep_amended(path: Path, program: DroneProgram, journal: NodeJournal) -> None:
    """An applied amendment switched this drone to ``program``: it becomes the node's
    program file and its record's program, so a restart resumes the amended program."""
    try:
        program.save(path)
    except OSError as exc:
        say(
            program.drone,
            f"cannot keep the amended program in {path} ({exc}): a restart "
            "of this node would run the program as rolled out",
        )
    journal.program = program.checksum
    journal.mark("running")


def run_drone(
    config: NodeConfig,
    program: DroneProgram,
    stop: threading.Event,
    shared: ProcessShare | None = None,
) -> DroneEnd:
    """Run one drone until the mission completes or is aborted, or it must end on its own.

    A drone stranded by a lost peer, or left without ``Complete`` by a silent
    ground station, ends after ``peer_wait_limit_s`` (see :mod:`.stranded`).
    ``shared``: what the drones of the process share (:class:`ProcessShare`) when
    several do; without it, this drone has its own log writer, ZeroMQ context and
    (simulated) clock.
    """
    journal = NodeJournal(
        config.log_dir, config.drone, program.mission_id, program.checksum, config.deployment
    )
    decision = journal.decide(cannot_resume=resume_refusal(config.hal))
    if not decision.join:
        # Before the vehicle or the network is touched: nothing is commanded.
        say(
            config.drone,
            f"{config.drone} restarted mid-mission: {decision.reason}; it refuses to rejoin "
            "(nothing is commanded: if its vehicle flies, land it with `eamos abort` or by "
            "hand, then roll out again)",
        )
        return DroneEnd.REFUSED
    if decision.restarted:
        say(config.drone, f"{config.drone} restarted: {decision.reason}")
    config.log_dir.mkdir(parents=True, exist_ok=True)
    replay = None
    if decision.resume:
        # What the node before reported, replayed: its record stays "running".
        replay = Replay(past_of(journal.past(), program), config.drone, journal.acknowledged())
        say(config.drone, f"{config.drone} replays {len(replay.pending)} action(s) that had ended")
    else:
        journal.mark("ready")
    journal.begin(resume=decision.resume)
    writer = shared.writer if shared is not None else LogWriter()
    adapter_log = make_logger(config.log_dir / "adapter.log", writer=writer, drone=config.drone)
    sim_clock = shared.sim_clock if shared is not None else None
    adapter = make_adapter(config.drone, config.hal, adapter_log, sim_clock)
    runtime = DroneRuntime(
        program,
        adapter,
        net_settings(config),
        config.log_dir,
        battery_reserve_pct=config.battery_reserve_pct,
        log_writer=writer,
        context=shared.context if shared is not None else None,
        zap=shared.zap if shared is not None else None,
        timers=shared.timers if shared is not None else None,
        receivers=shared.receivers if shared is not None else None,
        # Nothing acts before this deployment's Start; the first trigger to reach a
        # node is recorded first (a restart then knows something ran).
        start_gate=StartGateSettings(config.deployment, lambda: journal.mark("running")),
        replay=replay,
        journal=journal.reported,
        on_reprogrammed=lambda amended: keep_amended(config.program, amended, journal),
    )
    policy = end_policy(config)
    try:
        runtime.start()
        if not runtime.announce_ready(config.ready_timeout_s, stop):
            if stop.is_set():
                return DroneEnd.FAILED
            tell_operator(
                config.drone,
                f"peers never subscribed: {', '.join(runtime.destinations())} "
                f"(waited {config.ready_timeout_s:g} s)",
            )
            return DroneEnd.UNREACHABLE
        ending = _execute(runtime, config, program, stop, policy)
        held = ending is not None and ending.kind == "stranded" and policy == "hold"
        landed = True
        if runtime.aborted.is_set() and not held:
            # The report is sent after the landing: it tells where the vehicle ended.
            landing = wait_landing(runtime, config.land_timeout_s)
            landed = landing == "landed"
            if landing == "silent":
                runtime.log.error("mission.abort.vehicle_silent", silent_s=VEHICLE_SILENT_S)
                tell_operator(
                    config.drone,
                    f"its vehicle has sent nothing for {VEHICLE_SILENT_S:g} s while landing: "
                    "it cannot be landed from here (the report tells where it was last)",
                )
            elif not landed:
                runtime.log.error("mission.abort.not_landed", timeout_s=config.land_timeout_s)
        if landed and config.disarm_wait_s > 0 and not wait_settled(runtime, config.disarm_wait_s):
            # Its autopilot disarms a moment after landing: the report tells what it is left in.
            runtime.log.warning("mission.end.armed_on_ground", waited_s=config.disarm_wait_s)
        report = runtime.drone_report()
        data = report.to_json()
        try:
            (config.log_dir / "report.json").write_text(json.dumps(data, indent=1) + "\n")
        except OSError as exc:  # a full disk: the ground station still gets the report
            report_write_error(config.log_dir / "report.json", exc, "the report is still sent")
        # Every action goes to the ground station, in parts when it is large (beyond
        # 64 MiB, the folded report, which always fits).
        try:
            msgs = report_messages(program.mission_id, config.drone, report.to_json(fold=False))
        except WireError:
            msgs = report_messages(program.mission_id, config.drone, data)
        for msg in msgs:
            runtime.send(msg)
        # The report is the last word: retransmitted until acknowledged (bounded),
        # unless the ground station is known to be gone.
        gone = ending is not None and ending.kind == "no_complete"
        if (
            not gone
            and runtime.link is not None
            and not report_acknowledged(
                runtime.link, stop, lambda text: tell_operator(config.drone, text)
            )
        ):
            runtime.log.warning("mission.report.unacknowledged", timeout_s=report_ack_limit(stop))
        journal.mark("ended")
        return DroneEnd.DONE if report.ok else DroneEnd.FAILED
    finally:
        runtime.stop()
        journal.close()
        close_logger(adapter_log)
        if shared is None:
            writer.close()


def resume_refusal(hal: Mapping[str, Any]) -> str:
    """Why a node with these adapter settings cannot resume mid-mission ("": it can).

    Only a vehicle that outlives the node (a MAVLink autopilot, or its simulated
    stand-in in a process of its own) is still where the node before left it.
    """
    adapter = hal.get("adapter", "sim")
    if adapter == "mavlink":
        return ""
    return (
        f"its vehicle (adapter {adapter!r}) ran inside the node that stopped: a new one "
        "would start on the ground at home"
    )


def past_of(events: list[dict[str, Any]], program: DroneProgram) -> Continuation:
    """A restarted node's past: what the node before reported (its progress journal)."""
    return continuation(
        {
            "mission_id": program.mission_id,
            "t": time.time(),
            "why": "restart",
            "participants": {program.drone: {"activations": activations(events)}},
        },
        "the node's progress journal",
    )


def wait_landing(runtime: DroneRuntime, timeout_s: float) -> str:
    """Wait (on telemetry) until the vehicle is on the ground: ``"landed"``; ``"timeout"``
    after ``timeout_s``; ``"silent"`` as soon as no sample came for :data:`VEHICLE_SILENT_S`
    (a landing vehicle moves, and says so: a silent one -- its link lost, its autopilot
    dead -- will not be landed by waiting)."""
    if runtime.board is None:
        return "landed"
    deadline = time.monotonic() + timeout_s
    latest = ask_final_sample(runtime.board, None, None, 0.0, ASK_TIMEOUT_S)
    while True:
        left = deadline - time.monotonic()
        if left <= 0:
            return "timeout"
        slice_s = min(left, VEHICLE_SILENT_S)
        if runtime.wait_landed(slice_s):
            return "landed"
        sample = ask_final_sample(runtime.board, None, None, 0.0, ASK_TIMEOUT_S)
        if sample is latest and slice_s >= VEHICLE_SILENT_S:
            return "silent"  # still the sample of a whole slice before: nothing arrived
        latest = sample


def wait_settled(runtime: DroneRuntime, timeout_s: float) -> bool:
    """Wait (on telemetry) until the vehicle does not stand armed on the ground.

    Autopilots (and the simulated drone) disarm by themselves a moment after a
    landing; the report must tell the state the vehicle is left in.  False if it
    still stands armed after ``timeout_s``.
    """
    if runtime.board is None:
        return True
    snap = ask_snapshot(runtime.executive, ASK_TIMEOUT_S)
    event = threading.Event()
    runtime.board.tell(WhenSettled(event, snap.state_changed_s, snap.state_action))
    return event.wait(timeout_s)


def peer_wait_limit(config: NodeConfig) -> float:
    """``peer_wait_limit_s`` of the node config."""
    return config.peer_wait_limit_s


def end_policy(config: NodeConfig) -> str:
    """``on_stranded`` of the node config (``return`` lands for now: no path home yet)."""
    return "hold" if config.on_stranded == "hold" else "land"


def _execute(
    runtime: DroneRuntime,
    config: NodeConfig,
    program: DroneProgram,
    stop: threading.Event,
    policy: str,
) -> EndOnOwn | None:
    """Run until Complete, an abort, a signal, or until the drone must end on its own (how).

    However the part ends short of an abort (Complete, the drone's own resolution, a
    silent ground station), the stranded check runs first (:func:`strand_if_airborne`):
    a part that ended blocked by a failure with the vehicle in the air applies the end
    policy before the report is sent, never left to the adapter's land-on-close.
    """
    limit_s = peer_wait_limit(config)
    sources = trigger_sources(program)
    checked_airborne = False
    caught: set[str] = set()  # lost peers a Try here has caught (once each)
    while not (runtime.completed.is_set() or runtime.aborted.is_set()):
        if stop.is_set():
            stopped_by_signal(runtime, config.drone, stop)
            return None
        # Bounded only so a signal (which sets `stop`) and a silent peer are noticed;
        # the runtime's events are set by the in-bridge thread.
        if runtime.completed.wait(0.5) or runtime.link is None:
            continue
        silent = silent_since(list(runtime.link.peer_events), time.time(), time.monotonic())
        if not activity_matters(silent, runtime.part_resolved.is_set(), checked_airborne):
            continue
        activity = ask_activity(runtime.executive, ASK_TIMEOUT_S)
        activity = dataclasses.replace(activity, held=runtime.held_by_operator)
        if activity.resolved and not checked_airborne:
            checked_airborne = True
            # Held and alone, the hold is what strands it, even when a peer that ended
            # the same way a moment earlier failed this part's last nodes.
            ending = None
            if activity.held:
                ending = end_on_own(time.monotonic(), activity, silent, sources, limit_s)
            if ending is None:
                ending = left_airborne(runtime)
        else:
            ending = end_on_own(time.monotonic(), activity, silent, sources, limit_s)
        if ending is None:
            continue
        peer = ending.peer
        lost = caught_lost_peer(program, peer) if peer and peer not in caught else frozenset()
        if peer and lost:
            # A Try's Body waits on the lost peer: its failure to catch, not a stranding.
            caught.add(peer)
            runtime.log.warning("mission.try.peer_lost", peer=peer, reason=ending.reason)
            for node in runtime.nodes.values():
                node.tell(PeerLost(lost))
            continue
        tell_operator(config.drone, ending.reason)
        if ending.kind != "stranded":
            runtime.log.warning("mission.complete.missing", reason=ending.reason)
            return ending
        runtime.end_stranded(ending.reason, policy)
        return ending
    if runtime.aborted.is_set() or checked_airborne:
        return None
    # Complete came first (always, for the last drone to resolve): check now.
    return strand_if_airborne(runtime, config.drone, policy)


def stopped_by_signal(runtime: DroneRuntime, drone: str, stop: threading.Event) -> None:
    """A signal ends the mission on this drone: said in ``node.out`` and to the ground
    station at once; the drones waiting for it are released, and it lands."""
    name = stop.name if isinstance(stop, NodeStop) and stop.name else "a signal"
    text = f"stopped by {name}: the mission is aborted on this drone; it lands, then reports"
    tell_operator(drone, text)
    runtime.send(
        wire.Progress(
            mission=runtime.program.mission_id,
            sender=drone,
            state="stopped",
            node="",
            action=f"stopped by {name}",
            detail={"detail": text},
        )
    )
    runtime.stop_mission("stopped by signal")


def strand_if_airborne(runtime: DroneRuntime, drone: str, policy: str) -> EndOnOwn | None:
    """Apply the end policy if the part ended blocked with the vehicle in the air (how)."""
    ending = left_airborne(runtime)
    if ending is None:
        return None
    tell_operator(drone, ending.reason)
    runtime.end_stranded(ending.reason, policy)
    return ending


def left_airborne(runtime: DroneRuntime) -> EndOnOwn | None:
    """The drone's part ended blocked by a failure with the vehicle in the air (None: not).

    Nothing in its program will land it any more: it is stranded, and applies
    its end policy at once rather than hover until the whole mission ends.
    """
    snap = ask_snapshot(runtime.executive, ASK_TIMEOUT_S)
    failed = sum(1 for status in snap.resolved.values() if status == "failed")
    if not failed:
        return None
    sample = ask_final_sample(runtime.board, None, None, 0.0, ASK_TIMEOUT_S)
    if sample is None or sample.landed:
        return None
    return EndOnOwn(
        "stranded",
        f"stranded: its part ended with {failed} node(s) failed or blocked, "
        f"the vehicle in the air at z = {sample.z_m:.1f} m",
    )
