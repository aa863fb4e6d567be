"""The synchronous driver: a whole mission in one thread, in virtual time.

Every native node of every participant's program gets its pure logic
(:mod:`eamos.actors.logic`); their effects are applied here instead of by
actors: triggers (local and external arcs alike) and interrupts go through one
in-memory queue, telemetry goes through a board like the runtime's (latest
values per drone, pushed to the condition nodes watching them when they
change), actions run on one vehicle per drone stepped in virtual time (the
simulator's pure core by default), and the ground station's pauses run on a
virtual timer.  The queue is drained completely between two vehicle steps,
so messages take no virtual time; the run ends when every participant has
resolved, or at the virtual-time limit (then :attr:`VirtualRun.waiting` says
what was still waiting).  No sockets, threads, actors or clock reads: a
paper experiment takes milliseconds to a few hundred of CPU.
"""

from __future__ import annotations

import functools
from collections import deque
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

from ..actors.continuation import Continuation, install_continuation
from ..actors.logic import (
    ActionLogic,
    Broadcast,
    CancelAction,
    ConditionLogic,
    Effect,
    Emit,
    NodeLogic,
    Note,
    Progress,
    Record,
    ReleaseBegin,
    Resolve,
    StartAction,
    UnwatchTelemetry,
    WatchTelemetry,
    program_wiring,
)
from ..actors.logic.telemetry import PropertyValues, telemetry_values
from ..actors.messages import ActionRecord
from ..actors.state import Iteration
from ..hal.api import ActionHandle, ActionResult, Telemetry
from ..program.format import DroneProgram
from ..program.uniform import GROUND_STATION, CommandError, decode_command
from .decisions import FAILED_ON_PURPOSE, Decide, FailHook, install_decide
from .result import DroneOutcome, VirtualRun, Waiting
from .vehicles import (
    STEP_S,
    GroundPauses,
    IdleVehicle,
    LazyVehicle,
    Vehicle,
    VehicleFactory,
    WakeQueue,
    settles,
    sim_vehicles,
)

#: Default bound on virtual time (seconds): longer than any mission of the paper.
TIME_LIMIT_S = 1800.0

NodeId = tuple[str, str]  # (drone, node key)


@dataclass
class _Participant:
    """One drone (or the ground station) of the run."""

    program: DroneProgram
    logic: dict[str, NodeLogic]
    vehicle: Vehicle | None
    top_level: frozenset[str]
    scope_index: dict[int, list[str]]
    resolved: dict[str, str] = field(default_factory=dict)
    records: list[ActionRecord] = field(default_factory=list)
    running: dict[tuple[str, Iteration], ActionHandle] = field(default_factory=dict)
    triggers_sent: int = 0
    triggers_received: int = 0

    @property
    def all_resolved(self) -> bool:
        return self.top_level <= self.resolved.keys()


class _Board:
    """Latest property values per drone; pushes changes to the nodes watching them."""

    def __init__(self) -> None:
        self.latest: dict[str, PropertyValues] = {}
        self.watchers: dict[NodeId, tuple[str, ...]] = {}
        self._readers: dict[str, int] = {}  # how many watchers read each drone
        # The vehicles that rest through battery-only samples while nobody reads them.
        self.resting: dict[str, LazyVehicle] = {}

    def read(self, drone: str) -> bool:
        """True while some node watches ``drone``'s telemetry."""
        return self._readers.get(drone, 0) > 0

    def watch(
        self, node: NodeId, drones: tuple[str, ...], publish: Callable[[str, Telemetry], None]
    ) -> None:
        """``node`` watches ``drones`` (instead of what it watched).

        A drone nobody read until now first hands over (``publish``) the latest
        sample it would have sent meanwhile: the latest values the node is told.
        """
        for drone in sorted(set(drones)):
            vehicle = self.resting.get(drone)
            if vehicle is not None and not self.read(drone):
                sample = vehicle.unsent()
                if sample is not None:
                    publish(drone, sample)
                vehicle.read_again()
        self.unwatch(node)
        self.watchers[node] = drones
        for drone in set(drones):
            self._readers[drone] = self._readers.get(drone, 0) + 1

    def unwatch(self, node: NodeId) -> None:
        """``node`` watches nothing."""
        for drone in set(self.watchers.pop(node, ())):
            self._readers[drone] -= 1

    def publish(self, drone: str, values: PropertyValues) -> list[NodeId]:
        """Record ``values``; the watchers to tell (none if nothing a condition reads changed)."""
        old = self.latest.get(drone)
        self.latest[drone] = values
        if old is not None and all(
            old.get(k) == v for k, v in values.items() if not k.startswith("_")
        ):
            return []
        return [node for node, drones in self.watchers.items() if drone in drones]


class VirtualMission:
    """One virtual-time run of a compiled mission (build, then :meth:`run` once)."""

    def __init__(
        self,
        programs: Mapping[str, DroneProgram] | Iterable[DroneProgram],
        vehicles: VehicleFactory | None = None,
        time_limit_s: float = TIME_LIMIT_S,
        log: Any = None,
        decide: Decide | None = None,
        fail: FailHook | None = None,
        battery_floor_pct: float | None = None,
        continuation: Continuation | None = None,
    ) -> None:
        """``programs``: every participant's program (the ground station's included).

        ``vehicles(drone, clock)`` builds each drone's vehicle (default: the
        simulator core with default settings); ``log``, if given, receives the
        nodes' mission-log lines (bound with ``drone`` and ``node``); ``decide``,
        if given, decides every condition, and ``fail`` whether an action of a
        Try's Body fails (see :mod:`eamos.virtual.decisions`);
        ``battery_floor_pct``: below it a Try's Body action fails, as on the drones
        (the fleet's ``[safety] battery_reserve_pct``; see
        :mod:`eamos.actors.logic.actions`).  ``continuation``: go on from a mission's
        snapshot (:mod:`eamos.actors.continuation`); the default vehicles then start
        where it saw them (a given factory places its own).
        """
        progs = list(programs.values()) if isinstance(programs, Mapping) else list(programs)
        if not progs:
            raise ValueError("no programs to run")
        self.mission = progs[0].mission
        self.time_limit_s = time_limit_s
        self.log = log
        self.t = 0.0
        self.steps = 0
        self._queue: deque[tuple[NodeId, Callable[..., list[Effect]], tuple[Any, ...]]] = deque()
        self._board = _Board()
        self._ground = GroundPauses()
        self._wakes = WakeQueue()
        self._continuation = continuation
        self.replaying = False  # True while the snapshot's past is replayed (at the start)
        self.replayed: list[tuple[str, str, Iteration]] = []
        factory = vehicles or sim_vehicles(
            start=None if continuation is None else continuation.vehicle
        )

        def make(drone: str) -> Vehicle:
            vehicle = factory(drone, self.clock)
            if not isinstance(vehicle, IdleVehicle):
                return vehicle
            # Idle steps are skipped, not stepped; unread, also battery-only samples.
            read = functools.partial(self._board.read, drone)
            lazy = LazyVehicle(vehicle, lambda: self.steps, self._horizon, self._wakes.note, read)
            self._board.resting[drone] = lazy
            return lazy

        self.participants: dict[str, _Participant] = {}
        for program in progs:
            wiring = program_wiring(program)
            scope_index: dict[int, list[str]] = {}
            for key, wired in wiring.items():
                for scope in wired.spec.scopes:
                    scope_index.setdefault(scope, []).append(key)
            self.participants[program.drone] = _Participant(
                program=program,
                logic={key: wired.logic() for key, wired in wiring.items()},
                vehicle=None if program.drone == GROUND_STATION else make(program.drone),
                top_level=frozenset(k for k, w in wiring.items() if not w.spec.loops),
                scope_index=scope_index,
            )
        for part in self.participants.values():
            for logic in part.logic.values():
                if isinstance(logic, ActionLogic):
                    logic.battery_floor_pct = battery_floor_pct
        if log is None:
            # Nobody reads notes or progress in this run: the logic need not make them.
            for part in self.participants.values():
                for logic in part.logic.values():
                    logic.quiet = True
        self._fail = fail
        if decide is not None:
            for drone, part in self.participants.items():
                for logic in part.logic.values():
                    if isinstance(logic, ConditionLogic):
                        install_decide(drone, logic, decide)
        if continuation is not None:
            nodes = {drone: part.logic for drone, part in self.participants.items()}
            install_continuation(continuation, nodes, lambda: self.replaying)
        self._vehicles = [(d, p.vehicle) for d, p in sorted(self.participants.items()) if p.vehicle]
        # Jumping over steps, and stepping only the vehicles due, need them all lazy.
        lazy = [v for _, v in self._vehicles if isinstance(v, LazyVehicle)]
        self._lazy = lazy if len(lazy) == len(self._vehicles) else []
        if self._lazy:
            self._wakes.follow(self._lazy)  # a step costs the vehicles due, not the fleet
        self.jumped = 0  # steps jumped over at once (counted in ``steps`` too)
        self._apply_one: dict[type, Callable[[NodeId, Any], None]] = {
            Emit: self._emit,
            StartAction: self._start_action,
            CancelAction: self._cancel_action,
            WatchTelemetry: self._watch,
            UnwatchTelemetry: self._unwatch,
            Resolve: self._resolve,
            Broadcast: self._broadcast,
            Progress: self._ignore,
            Record: self._record,
            ReleaseBegin: self._release,
            Note: self._note,
        }
        self._ran = False

    def clock(self) -> float:
        """Virtual seconds since the start (stamped on telemetry samples)."""
        return self.t

    # -- the loop -------------------------------------------------------------------

    def run(self) -> VirtualRun:
        """Run the mission until every participant resolved or the time limit."""
        if self._ran:
            raise RuntimeError("a VirtualMission runs once; build another")
        self._ran = True
        return self._run()

    def _run(self) -> VirtualRun:
        for drone, vehicle in self._vehicles:
            self._publish(drone, vehicle.start())
        for drone, part in sorted(self.participants.items()):
            for key, logic in part.logic.items():
                if logic.spec.kind == "init":
                    self._post((drone, key), logic.fire)
        # A continuation's past is replayed here, in no virtual time (its actions end at once).
        self.replaying = self._continuation is not None
        self._drain()
        self.replaying = False
        timed_out = False
        while not all(p.all_resolved for p in self.participants.values()):
            if self.t >= self.time_limit_s - 1e-9:
                timed_out = True
                break
            self._advance()
            self._drain()
        ended = self.t
        if not timed_out:
            self._settle()
        return VirtualRun(
            mission=self.mission,
            drones={drone: _outcome(drone, part) for drone, part in self.participants.items()},
            duration_s=ended,
            timed_out=timed_out,
            waiting=_waiting(self.participants) if timed_out else (),
            steps=self.steps,
            replayed=tuple(self.replayed),
        )

    def _settle(self) -> None:
        """After the mission: step on while a vehicle still changes by itself (within the limit).

        A simulated drone disarms by itself a moment after its landing, as real
        autopilots do; the final states are those it is left in.
        """
        settling = [s for _, v in self._vehicles if (s := settles(v)) is not None]
        while self.t < self.time_limit_s - 1e-9 and any(s.settling for s in settling):
            self._advance()
            self._drain()

    def _advance(self) -> None:
        """One vehicle step (or, with no vehicle, a jump to the next pause's end).

        Idle vehicles sleep through their steps (:class:`LazyVehicle`); when
        all of them sleep, the steps before the first wakes (or a ground
        pause ends) are jumped over at once.
        """
        if self._lazy:
            self._jump()
        self.steps += 1
        if self._vehicles:
            self.t = self.steps * STEP_S
        else:
            due = self._ground.next_due()
            self.t = min(self.time_limit_s, due if due is not None else self.time_limit_s)
        for drone, vehicle in self._due():
            finished, samples = vehicle.step()
            for done, result in finished:
                done(result)
            for sample in samples:
                self._publish(drone, sample)
        for done, result in self._ground.expire(self.t):
            done(result)

    def _horizon(self) -> int:
        """Steps left before the time limit (vehicles sleep no further)."""
        return max(0, int((self.time_limit_s - self.t) / STEP_S) - 2)

    def _due(self) -> list[tuple[str, Vehicle]]:
        """The vehicles to step now, in the drones' order (all, unless all are lazy)."""
        if not self._lazy:
            return self._vehicles
        return [self._vehicles[i] for i in self._wakes.due(self.steps)]

    def _jump(self) -> None:
        """Jump to the step before the first vehicle wakes or a ground pause ends."""
        first = self._wakes.first()
        target = (self.steps + 1 + self._horizon() if first is None else first) - 1
        due = self._ground.next_due()
        if due is not None:
            target = min(target, self.steps + int((due - self.t) / STEP_S) - 2)
        target = min(target, self.steps + self._horizon())
        if target > self.steps:
            self.jumped += target - self.steps
            self.steps = target
            self.t = self.steps * STEP_S

    def _post(self, node: NodeId, method: Callable[..., list[Effect]], *args: Any) -> None:
        self._queue.append((node, method, args))

    def _drain(self) -> None:
        queue = self._queue
        apply_one = self._apply_one
        while queue:
            node, method, args = queue.popleft()
            for effect in method(*args):
                apply_one[type(effect)](node, effect)

    def _publish(self, drone: str, sample: Telemetry) -> None:
        values = telemetry_values(sample)
        for node in self._board.publish(drone, values):
            self._post(node, self._logic(node).telemetry, drone, values)

    def _logic(self, node: NodeId) -> NodeLogic:
        return self.participants[node[0]].logic[node[1]]

    # -- effects ----------------------------------------------------------------------

    def _emit(self, node: NodeId, fx: Emit) -> None:
        route = fx.route
        target = self.participants[route.drone]
        if route.external:
            self.participants[node[0]].triggers_sent += 1
            target.triggers_received += 1
        self._post(
            (route.drone, route.dst),
            target.logic[route.dst].trigger,
            node[1],
            fx.iteration,
            fx.status,
        )

    def _start_action(self, node: NodeId, fx: StartAction) -> None:
        drone, key = node
        part = self.participants[drone]
        start_s = self.t
        logic = part.logic[key]
        running = part.running

        def done(result: ActionResult) -> None:
            running.pop((key, fx.iteration), None)
            self._post(
                node,
                logic.action_finished,
                fx.iteration,
                result.status,
                result.reason,
                start_s,
                self.t,
            )

        action, args = fx.action, fx.args
        cont = self._continuation
        if cont is not None:
            ended = cont.ended(drone, key, fx.iteration)
            if ended is not None:  # it ran before the snapshot: not again
                self.replayed.append((drone, key, fx.iteration))
                done(ended)
                return
            action, args = cont.rest(drone, key, fx.iteration, action, args)
        try:
            # Plugin actions decode with the parameter list of the vehicle's plugins.
            plugins = getattr(part.vehicle, "plugins", None)
            command = decode_command(action, args, plugins.specs() if plugins is not None else None)
        except CommandError as exc:
            done(ActionResult("failed", str(exc)))
            return
        if (
            self._fail is not None
            and isinstance(logic, ActionLogic)
            and logic.spec.catch is not None
            and self._fail(drone, logic, fx.iteration)
        ):
            done(ActionResult("failed", FAILED_ON_PURPOSE))
            return
        if part.vehicle is None:
            handle = self._ground.run(self.t, command, done)
        else:
            handle = part.vehicle.run(command, done)
        if handle is not None:
            running[(key, fx.iteration)] = handle

    def _cancel_action(self, node: NodeId, fx: CancelAction) -> None:
        part = self.participants[node[0]]
        handle = part.running.get((node[1], fx.iteration))
        if handle is None:
            return
        if part.vehicle is None:
            self._ground.cancel(handle)
        else:
            part.vehicle.cancel(handle)

    def _watch(self, node: NodeId, fx: WatchTelemetry) -> None:
        self._board.watch(node, fx.drones, self._publish)
        logic = self._logic(node)
        for drone in fx.drones:
            values = self._board.latest.get(drone)
            if values is not None:
                self._post(node, logic.telemetry, drone, values)

    def _unwatch(self, node: NodeId, fx: UnwatchTelemetry) -> None:
        self._board.unwatch(node)

    def _resolve(self, node: NodeId, fx: Resolve) -> None:
        if fx.top_level:
            self.participants[node[0]].resolved[node[1]] = fx.status

    def _broadcast(self, node: NodeId, fx: Broadcast) -> None:
        for drone in fx.drones:
            part = self.participants.get(drone)
            if part is None:
                continue
            for key in part.scope_index.get(fx.interrupt.scope, ()):
                self._post((drone, key), part.logic[key].interrupt, fx.interrupt)

    def _record(self, node: NodeId, fx: Record) -> None:
        self.participants[node[0]].records.append(fx.record)

    def _release(self, node: NodeId, fx: ReleaseBegin) -> None:
        logic = self.participants[node[0]].logic.get(fx.begin)
        if logic is not None:  # as on a drone: only a begin node on the same drone hears it
            self._post((node[0], fx.begin), logic.release, fx.iteration)

    def _note(self, node: NodeId, fx: Note) -> None:
        if self.log is not None:
            getattr(self.log, fx.level)(fx.event, drone=node[0], node=node[1], **fx.fields)

    def _ignore(self, node: NodeId, fx: Effect) -> None:
        pass

    # -- the result -------------------------------------------------------------------


def _outcome(drone: str, part: _Participant) -> DroneOutcome:
    """One participant's outcome: its records in time order, resolutions, final state."""
    return DroneOutcome(
        drone=drone,
        actions=tuple(sorted(part.records, key=lambda r: (r.start, r.node))),
        resolved=dict(part.resolved),
        all_resolved=part.all_resolved,
        triggers_sent=part.triggers_sent,
        triggers_received=part.triggers_received,
        final=part.vehicle.state() if part.vehicle is not None else None,
    )


def _waiting(participants: Mapping[str, _Participant]) -> tuple[Waiting, ...]:
    """What each participant still waits for (a run that reached its time limit)."""
    out: list[Waiting] = []
    for drone, part in sorted(participants.items()):
        for key, logic in part.logic.items():
            why = _why_waiting(logic)
            if why is None and key in part.top_level and key not in part.resolved:
                why = "never triggered"
            if why is not None:
                out.append(Waiting(drone, key, logic.spec.label, why))
    return tuple(out)


def _why_waiting(logic: NodeLogic) -> str | None:
    reasons: list[str] = []
    if isinstance(logic, ActionLogic) and logic.running:
        reasons.append(f"running {logic.action} for {sorted(logic.running)}")
    if isinstance(logic, ConditionLogic) and logic.pending:
        purposes = ", ".join(f"{p} {list(a)}" for a, p in logic.pending.items())
        reasons.append(f"condition {logic.cond_text} undecided ({purposes})")
    for (group, act), missing in sorted(logic.pre.waiting().items()):
        reasons.append(f"{group} {list(act)} waits for {', '.join(sorted(missing))}")
    return "; ".join(reasons) or None


def run_virtual(
    programs: Mapping[str, DroneProgram] | Iterable[DroneProgram],
    vehicles: VehicleFactory | None = None,
    time_limit_s: float = TIME_LIMIT_S,
    log: Any = None,
) -> VirtualRun:
    """Run a compiled mission (every participant's program) in virtual time, in this thread.

    ``vehicles(drone, clock)`` builds each drone's vehicle (default: the
    simulator core, :func:`~eamos.virtual.vehicles.sim_vehicles`); the run
    stops at ``time_limit_s`` virtual seconds if not every participant resolved.
    """
    return VirtualMission(programs, vehicles, time_limit_s, log).run()
