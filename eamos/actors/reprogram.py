"""An amendment applied to a flying drone: its not-yet-started node actors replaced.

``eamos amend RUN_DIR NEW.go --apply`` (or the monitor's Apply) has the ground station
send each drone the amendment touches its renumbered program (:mod:`eamos.compiler.amendment`:
a node whose place by content is the same keeps its key), in two phases
(:class:`~eamos.net.wire.Amend`):

``prepare``
    :func:`program_change` says which node actors go (removed, or changed: action,
    condition, incoming arcs), which come (added, changed) and which are *redirected*
    (only what follows them changes).  Each one that goes is held (:mod:`.amendable`);
    if one has begun, everything held is released and the answer is ``refused``, naming
    the node.  Each redirected one holds the triggers it would send; if one has ended,
    the same.  The new actors are started and wired, reachable by the new arcs only, and
    the In-Bridge takes triggers on the new arcs from now on: a peer that switches first
    may send on them.
``commit``
    The drone switches: every kept node talks to the new actors, the In-Bridge hands
    triggers to them, each replaced actor hands what it kept (the triggers of arcs the
    new program keeps, in order) to its replacement and stops, each redirected node sends
    what it held to its new successors, and the executive runs the new program.
``cancel``
    Everything held acts as if it had never been (the new actors stop).

Nothing here interrupts a running action or touches a node the amendment does not
change.  :func:`change_refusal` (pure) refuses what needs a link the roll-out did not
make (a new peer to send to, a drone's telemetry not read before).
"""

from __future__ import annotations

import contextlib
import threading
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol, cast

import pykka

from ..net import wire
from ..program.format import DroneProgram, ProgramError, program_from_bytes
from .amendable import AmendNode, Kept
from .executive import NewProgram
from .inbound import incoming_arcs
from .logic import NodeWiring, program_wiring
from .messages import Trigger
from .node import Links, MissionNode, Wire
from .uniform_api import answers_at_once
from .wiring import destinations

if TYPE_CHECKING:
    from ..hal.api import Adapter
    from ..logs import EventLog
    from .board import TelemetryBoard
    from .dispatch import Dispatcher
    from .executive import DroneExecutive
    from .failure import FailurePolicy
    from .inbound import InRouter
    from .outbox import Outbox
    from .startup import RuntimeStartup
    from .uniform_api import UniformAPI, UniformSpace

__all__ = [
    "ProgramChange",
    "Reprogrammable",
    "Reprogramming",
    "change_refusal",
    "program_change",
]

#: How long one node actor may take to answer (a turn is short; a loaded machine is slow).
ASK_TIMEOUT_S = 10.0
#: A prepared amendment neither committed nor cancelled within this is cancelled here:
#: a ground station lost between the phases does not leave the drone's nodes held.
PREPARED_FOR_S = 120.0


@dataclass(frozen=True)
class ProgramChange:
    """What an amended program changes in one drone's node actors (keys, program order)."""

    program: DroneProgram
    wiring: Mapping[str, NodeWiring]  # the new program's native nodes
    start: tuple[str, ...]  # new actors: nodes added or changed
    retire: tuple[str, ...]  # actors that go: nodes removed or changed
    reroute: tuple[str, ...]  # kept actors whose successors change

    @property
    def added(self) -> tuple[str, ...]:
        return tuple(k for k in self.start if k not in self.retire)

    @property
    def removed(self) -> tuple[str, ...]:
        return tuple(k for k in self.retire if k not in self.start)


def program_change(old: DroneProgram, new: DroneProgram) -> ProgramChange:
    """Compare a drone's running program with its amended one, node by node (pure)."""
    before, after = program_wiring(old), program_wiring(new)
    changed = [k for k, w in after.items() if k in before and _decides(w) != _decides(before[k])]
    added = [k for k in after if k not in before]
    removed = [k for k in before if k not in after]
    reroute = [
        k for k in after if k in before and k not in changed and after[k].routes != before[k].routes
    ]
    return ProgramChange(
        new, after, tuple(added + changed), tuple(removed + changed), tuple(reroute)
    )


def _decides(w: NodeWiring) -> tuple[object, ...]:
    """What of a node's wiring decides what it does (not where it is written)."""
    return (w.spec.executed(), w.entry, w.loop, w.begin_kind)


def change_refusal(old: DroneProgram, new: DroneProgram) -> str:
    """Why ``new`` cannot replace ``old`` on a flying drone ("" when it can; pure)."""
    if (new.drone, new.mission_id) != (old.drone, old.mission_id):
        return (
            f"the program is {new.drone}'s of mission {new.mission_id}, not {old.drone}'s "
            f"of {old.mission_id}"
        )
    if new.fleet != old.fleet:
        return "the amended program has another fleet"
    more = sorted(set(destinations(new)) - set(destinations(old)))
    if more:
        return f"it would send to {', '.join(more)}, which the roll-out did not link it to"
    reads = sorted(set(new.telemetry_from) - set(old.telemetry_from))
    if reads:
        return f"it would read the telemetry of {', '.join(reads)}, which it does not receive"
    return ""


class Reprogrammable(Protocol):
    """The parts of a drone runtime an amendment changes or uses (a
    :class:`~.runtime.DroneRuntime`)."""

    program: DroneProgram
    drone: str
    nodes: dict[str, pykka.ActorRef[MissionNode]]  # shared with the In-Bridge's router
    router: InRouter | None
    dispatcher: Dispatcher | None
    hal: pykka.ActorRef[UniformAPI] | None
    board: pykka.ActorRef[TelemetryBoard] | None
    outbox: Outbox | None
    executive: pykka.ActorRef[DroneExecutive] | None
    uniform: UniformSpace | None
    adapter: Adapter
    log: EventLog
    failures: FailurePolicy

    def send(self, msg: wire.Message) -> None: ...


@dataclass
class _Pending:
    """A prepared amendment: what was held and started, until commit or cancel."""

    number: int
    change: ProgramChange
    fresh: dict[str, pykka.ActorRef[MissionNode]]
    nodes: dict[str, pykka.ActorRef[MissionNode]]  # the new program's, by key
    links: Links
    held: list[str]


class Reprogramming:
    """A drone runtime's side of an amendment (module docstring).

    :meth:`handle` is called on the In-Bridge's thread; each phase runs on a thread of
    its own (it waits for the node actors, whose turns that thread may run), one at a
    time, and answers the ground station.
    """

    def __init__(
        self,
        runtime: Reprogrammable,
        startup: RuntimeStartup,
        switched: Callable[[DroneProgram], None] | None = None,
    ) -> None:
        """``switched`` is told each program the drone switched to (its node keeps it, so
        that a restart resumes the amended program)."""
        self.runtime = runtime
        self.startup = startup
        self.switched = switched
        self.log = runtime.log
        self._lock = threading.Lock()
        self._pending: _Pending | None = None
        self._done = (-1, "")  # the last amendment committed or cancelled here, and how

    def handle(self, msg: wire.Amend) -> None:
        """One phase from the ground station: done on its own thread, then answered."""
        threading.Thread(
            target=self._run, args=(msg,), name=f"eamos-amend-{self.runtime.drone}", daemon=True
        ).start()

    def _run(self, msg: wire.Amend) -> None:
        with self._lock:
            try:
                phase, reason = self._phase(msg)
            except Exception as exc:  # the runtime's failure policy: this drone lands
                self.runtime.failures("reprogramming", exc)
                phase, reason = "refused", f"internal error: {exc!r}"
        self._answer(msg.number, msg.sender, phase, reason)

    def _answer(self, number: int, dest: str, phase: str, reason: str = "") -> None:
        """Log the phase's outcome and tell the ground station ``dest``."""
        level = "warning" if phase == "refused" or reason else "info"
        getattr(self.log, level)(
            "mission.amendment", number=number, phase=phase, reason=reason or None
        )
        self.runtime.send(
            wire.Amend(
                mission=self.runtime.program.mission_id,
                sender=self.runtime.drone,
                dest=dest,
                number=number,
                phase=phase,  # type: ignore[arg-type]  # one of the answers
                reason=reason,
            )
        )

    def _phase(self, msg: wire.Amend) -> tuple[str, str]:
        pending = self._pending
        if msg.phase == "prepare":
            if pending is not None:
                return "refused", f"amendment {pending.number} is being applied"
            return self._prepare(msg)
        if pending is None or pending.number != msg.number:
            # Done already (its answer was lost and the order repeated) or never prepared.
            if self._done == (msg.number, msg.phase):
                return ("committed" if msg.phase == "commit" else "cancelled"), ""
            return "refused", f"amendment {msg.number} is not prepared here"
        self._pending = None
        self._done = (msg.number, msg.phase)
        if msg.phase == "commit":
            self._commit(pending)
            return "committed", ""
        self._cancel(pending)
        return "cancelled", ""

    # -- prepare ---------------------------------------------------------------------------

    def _prepare(self, msg: wire.Amend) -> tuple[str, str]:
        runtime = self.runtime
        try:
            new = program_from_bytes(msg.program, f"amendment {msg.number}")
        except ProgramError as exc:
            return "refused", str(exc)
        why = change_refusal(runtime.program, new)
        if why:
            return "refused", why
        change = program_change(runtime.program, new)
        held: list[str] = []
        for key, op in [
            *((k, "hold") for k in change.retire),
            *((k, "hold-out") for k in change.reroute),
        ]:
            node = runtime.program.node(key)
            try:
                free = runtime.nodes[key].ask(AmendNode(op), timeout=ASK_TIMEOUT_S) is True
            except (pykka.Timeout, pykka.ActorDeadError):
                # Nothing changed yet: refused, not a failure (the mission flies on as is).
                self._release(held)
                return "refused", f"{key} {node.label} did not answer within {ASK_TIMEOUT_S:g} s"
            if not free:
                self._release(held)
                state = "has begun" if op == "hold" else "has ended"
                return "refused", f"{key} {node.label} {state}, and the amendment changes it"
            held.append(key)
        fresh = self._start(change)
        current = dict(runtime.nodes)
        nodes = {k: fresh.get(k) or current[k] for k in change.wiring}
        links = self._links(nodes)
        for ref in fresh.values():
            ref.tell(Wire(links))
        for key in change.added:  # reachable by the new arcs only, until the commit
            runtime.nodes[key] = fresh[key]
        assert runtime.router is not None
        runtime.router.accept_arcs(incoming_arcs(new))
        self._pending = _Pending(msg.number, change, fresh, nodes, links, held)
        expiry = threading.Timer(PREPARED_FOR_S, self._expire, args=(msg.number, msg.sender))
        expiry.daemon = True
        expiry.start()
        return "prepared", ""

    def _expire(self, number: int, ground: str) -> None:
        """Cancel amendment ``number`` if it is still only prepared (see PREPARED_FOR_S),
        and tell the ground station."""
        with self._lock:
            pending = self._pending
            if pending is None or pending.number != number:
                return
            self._pending = None
            self._done = (number, "cancel")
            self._cancel(pending)
        self._answer(number, ground, "cancelled", f"no commit within {PREPARED_FOR_S:g} s")

    def _start(self, change: ProgramChange) -> dict[str, pykka.ActorRef[MissionNode]]:
        runtime, startup = self.runtime, self.startup
        assert runtime.dispatcher is not None
        fresh = {}
        for key in change.start:
            w = change.wiring[key]
            fresh[key] = MissionNode.start(
                runtime.dispatcher,
                w.spec,
                w.routes,
                w.entry,
                w.loop,
                runtime.drone,
                runtime.log,
                w.begin_kind,
                battery_floor_pct=startup.battery_reserve_pct,
            )
        return fresh

    def _links(self, nodes: dict[str, pykka.ActorRef[MissionNode]]) -> Links:
        runtime = self.runtime
        assert runtime.hal is not None and runtime.board is not None
        assert runtime.outbox is not None and runtime.executive is not None
        direct = runtime.uniform if answers_at_once(runtime.adapter) else None
        return Links(nodes, runtime.hal, runtime.board, runtime.outbox, runtime.executive, direct)

    # -- commit and cancel -----------------------------------------------------------------

    def _commit(self, pending: _Pending) -> None:
        runtime, change = self.runtime, pending.change
        nodes = pending.nodes
        # Kept nodes talk to the new actors (asked: once answered, none tells an old one).
        for key, ref in nodes.items():
            if key not in pending.fresh:
                ref.ask(Wire(pending.links), timeout=ASK_TIMEOUT_S)
        # The In-Bridge hands triggers to the new actors; the old ones hand on what they kept.
        old = {key: runtime.nodes[key] for key in change.retire}
        for key in change.removed:
            del runtime.nodes[key]
        runtime.nodes.update(pending.fresh)
        assert runtime.router is not None
        runtime.router.keep_arcs(incoming_arcs(change.program))
        for key, ref in old.items():
            kept = cast(tuple[Kept, ...], ref.ask(AmendNode("retire"), timeout=ASK_TIMEOUT_S))
            ref.stop(block=False)
            if key in pending.fresh:
                for message in self._carried(kept, change.wiring[key]):
                    pending.fresh[key].tell(message)
        for key in change.reroute:
            nodes[key].ask(AmendNode("reroute", change.wiring[key].routes), timeout=ASK_TIMEOUT_S)
        assert runtime.executive is not None
        runtime.executive.ask(NewProgram(change.program, nodes), timeout=ASK_TIMEOUT_S)
        runtime.program = self.startup.program = change.program
        self.startup.pace_telemetry(change.program)
        if self.switched is not None:
            self.switched(change.program)

    @staticmethod
    def _carried(kept: tuple[Kept, ...], wiring: NodeWiring) -> list[Kept]:
        """What a replaced node kept that its replacement counts: triggers of kept arcs."""
        arcs = wiring.entry | wiring.loop
        return [m for m in kept if not isinstance(m, Trigger) or m.src in arcs]

    def _cancel(self, pending: _Pending) -> None:
        runtime = self.runtime
        for key in pending.change.added:
            runtime.nodes.pop(key, None)
        assert runtime.router is not None
        runtime.router.keep_arcs(incoming_arcs(runtime.program))
        for ref in pending.fresh.values():
            ref.stop(block=False)
        self._release(pending.held)

    def _release(self, held: list[str]) -> None:
        for key in held:
            with contextlib.suppress(pykka.ActorDeadError):  # only while the drone stops
                self.runtime.nodes[key].tell(AmendNode("release"))
