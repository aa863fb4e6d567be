"""Mission node actors: one Pykka actor per native MDG node (paper VI-B).

The actor is a thin host: what a node *does* is its pure logic
(:mod:`eamos.actors.logic`, one class per node kind).  The actor turns each
message into one input of that logic and applies the effects it returns:
triggers to local node actors or through the out-bridge, actions to the
uniform-API actor, watches to the telemetry board, records, progress,
resolutions and interrupt broadcasts to the executive, log lines to the
mission log.

A turn's mission-log lines (its own, and the Out-Bridge's ``mission.outbridge.sent``
for the triggers it sends) are written in their order after the turn's triggers to
other drones went out, and before anything is told to another actor of the drone:
a peer waiting for a trigger does not wait for the lines, and a line a local actor
writes because of this turn still comes after this turn's lines.

Failure policy (:meth:`MissionNode.on_failure`, which the dispatcher calls
when a ``tell``-ed message raises): the node logs the exception once (with its
traceback) in the mission log, resolves ``failed`` (its
successors receive ``failed``, so the rest of the mission is blocked rather
than hung, and the ground station hears of it at once), cancels an action it
had running, and from then on answers every message with a no-op.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from types import TracebackType
from typing import TYPE_CHECKING, Any, TypeAlias, TypeVar

import pykka

from ..logs import LogLine, log_line
from ..program.format import ProgramNode
from .amendable import Amendable, AmendNode
from .continuation import Replay, install_continuation
from .dispatch import Dispatcher, LazyMail, PooledActor
from .failure import tell_operator
from .logic import (
    CONDITION_KINDS,
    DO_KINDS,
    LOOP_KINDS,
    WAIT_KINDS,
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
    Route,
    StartAction,
    UnwatchTelemetry,
    WatchTelemetry,
    node_logic,
)
from .messages import (
    AbortMission,
    ActionRecord,
    Fire,
    Interrupt,
    Mailbox,
    NodeEvent,
    NodeResolved,
    PeerLost,
    Release,
    RemoteTrigger,
    SendTrigger,
    TelemetryChanged,
    Trigger,
    Unwatch,
    Watch,
)
from .pykka_seam import ExcInfo
from .state import Iteration
from .uniform_api import ActionFinished, UniformSpace
from .uniform_api import CancelAction as HalCancel
from .uniform_api import RunAction as HalRun

if TYPE_CHECKING:
    from structlog.typing import FilteringBoundLogger

T = TypeVar("T")

#: Effect type -> the MissionNode method that applies it (one table for every node:
#: a bound-method dict per actor costs ~0.6 KB a node on 600-node programs).
_APPLY: dict[type, str] = {
    Emit: "_emit",
    StartAction: "_start_action",
    CancelAction: "_cancel_action",
    WatchTelemetry: "_watch",
    UnwatchTelemetry: "_unwatch",
    Resolve: "_resolve",
    Broadcast: "_broadcast",
    Progress: "_progress",
    Record: "_record",
    ReleaseBegin: "_release_begin",
    Note: "_note",
}


def turn_order(
    effects: Sequence[Effect],
) -> tuple[list[Record | Progress], list[Emit], list[Effect]]:
    """A turn's effects in the order a node applies them: (news for the executive that
    goes before the triggers, the triggers to other drones, the rest in their order).

    Triggers to other drones go first: a peer waits for them, and nothing of this drone
    is ordered against them.  Only the turn's action records and progress go before
    them (when there are any): that peer may end the mission at once, and this drone's
    report, asked of its executive then, must hold every action whose end the trigger
    announced.  Telling the executive is an append to its inbox; no thread is woken
    (:class:`~.dispatch.LazyMail`).
    """
    external = [e for e in effects if isinstance(e, Emit) and e.route.external]
    if not external:
        return [], [], list(effects)
    first: list[Record | Progress] = []
    rest: list[Effect] = []
    for effect in effects:
        if isinstance(effect, Record | Progress):
            first.append(effect)
        elif not (isinstance(effect, Emit) and effect.route.external):
            rest.append(effect)
    return first, external, rest


__all__ = [
    "CONDITION_KINDS",
    "DO_KINDS",
    "LOOP_KINDS",
    "WAIT_KINDS",
    "BroadcastInterrupt",
    "ExecutiveNews",
    "Links",
    "MissionNode",
    "Route",
    "Wire",
    "turn_order",
]


@dataclass(frozen=True)
class Links:
    """Who a node talks to, each as what the node tells it; handed over once all actors
    of the runtime exist."""

    nodes: Mapping[str, Mailbox[Trigger | Release]]  # key -> the local native nodes
    hal: Mailbox[HalRun | HalCancel]  # the uniform-API actor
    board: Mailbox[Watch | Unwatch]  # the telemetry board
    #: The Out-Bridge: its ``send_trigger`` when it has one (the Outbox), else ``tell``.
    out_bridge: Mailbox[SendTrigger]
    executive: Mailbox[ExecutiveNews]
    #: The uniform API's bookkeeping, called directly when the adapter does not
    #: block (:func:`~.uniform_api.answers_at_once`); None: through the ``hal`` actor.
    uniform: UniformSpace | None = None


@dataclass(frozen=True)
class Wire:
    """Give a node its links (first message every node receives)."""

    links: Links


@dataclass(frozen=True)
class BroadcastInterrupt:
    """A begin node asks the executive to interrupt its body on these drones."""

    interrupt: Interrupt
    drones: tuple[str, ...]


#: What a node tells the executive: progress, records, resolutions, interrupt broadcasts.
News: TypeAlias = NodeEvent | ActionRecord | NodeResolved | BroadcastInterrupt


@dataclass(frozen=True)
class ExecutiveNews(LazyMail):
    """What one message to a node meant for the executive, in order, as one message.

    Items: :class:`~.messages.NodeEvent`, :class:`~.messages.ActionRecord`,
    :class:`~.messages.NodeResolved`, :class:`BroadcastInterrupt`.  An action that
    starts and ends in one turn of its node (an adapter that answers at once) is
    one message, not three.
    """

    items: tuple[News, ...]


class MissionNode(PooledActor):
    """The actor executing one native node of a drone's MDG (on the runtime's dispatcher)."""

    def __init__(
        self,
        dispatcher: Dispatcher,
        spec: ProgramNode,
        routes: tuple[Route, ...],
        entry: frozenset[str],
        loop: frozenset[str],
        drone: str,
        log: FilteringBoundLogger,
        begin_kind: str = "",
        logic: NodeLogic | None = None,
        battery_floor_pct: float | None = None,
        replay: Replay | None = None,
    ) -> None:
        """``logic`` replaces the one built from ``spec`` (tests inject faults this way);
        ``battery_floor_pct``: below it an action of a Try's Body fails; ``replay``: a
        restarted node's past (:class:`~.continuation.Replay`)."""
        super().__init__(dispatcher)
        self.spec = spec
        self.key = spec.key
        self.drone = drone
        self.log = log.bind(node=spec.key)
        self.logic = (
            logic if logic is not None else node_logic(spec, routes, entry, loop, begin_kind)
        )
        if isinstance(self.logic, ActionLogic):
            self.logic.battery_floor_pct = battery_floor_pct
        self._replay = replay
        if replay is not None:
            install_continuation(
                replay.continuation, {drone: {self.key: self.logic}}, replay.replaying
            )
        self.links: Links | None = None
        self.crashed = False
        self.amendable = Amendable()  # an amendment's hold on this node (.reprogram)
        self._current: object = None  # the message being handled (for the failure policy)
        enabled = getattr(self.log, "is_enabled_for", None)
        self._debug = enabled is None or bool(enabled(logging.DEBUG))
        if not self._debug:
            self.logic.debug_notes = False  # filtered anyway: not made at all
        self._news: list[News] = []  # for the executive, sent once per message handled
        self._inline: list[ActionFinished] = []  # actions the adapter ended inside run()
        self._results_held = False  # the uniform space holds result lines of this turn
        # This turn's mission-log lines (logger, method, event, fields, time), not written yet.
        self._lines: list[LogLine] = []

    # -- messages -> logic inputs ---------------------------------------------------

    def on_receive(self, message: object) -> object:
        if isinstance(message, AmendNode) and message.op in ("hold", "hold-out", "retire"):
            return self._amend_answer(message)
        try:
            if self.crashed or self.amendable.retired or self.amendable.keeps(message):
                return None  # failed, replaced, or held for an amendment: kept for later
            self._current = message
            if isinstance(message, AmendNode):
                self._amend_act(message)
            else:
                self._act(message)
            while self._inline:  # handled after the effects that started them, in order
                self._current = finished = self._inline.pop(0)
                self._act(finished)
            self._send_news()
        finally:
            if self._lines:
                self._write_lines()
            if self._results_held:
                # After the turn's work: its triggers to other drones went out first.
                self._results_held = False
                assert self.links is not None and self.links.uniform is not None
                self.links.uniform.write_results()
            if isinstance(message, RemoteTrigger):
                self._received_note(message)
        return None

    def _act(self, message: object) -> None:
        effects = self._input(message)
        self.amendable.seen(message, effects)
        self._apply(effects)

    def _amend_answer(self, message: AmendNode) -> object:
        """An amendment's question (:mod:`.amendable`): may the node be held, what it kept."""
        if message.op == "retire":
            return self.amendable.retire()
        if self.crashed:
            return False
        if message.op == "hold":
            return self.amendable.hold_in()
        return self.amendable.hold_out()

    def _amend_act(self, message: AmendNode) -> None:
        """An amendment cancelled (``release``) or applied (``reroute``): what the node
        kept goes on, to its old or its new successors."""
        if message.op == "reroute":
            self.logic.routes = message.routes
            self._apply(self.amendable.reroute(message.routes))
        elif message.op == "release":
            arrived, emits = self.amendable.release()
            self._apply(emits)
            for kept in arrived:
                self._act(kept)

    def _received_note(self, t: RemoteTrigger) -> None:
        # After the node's work (its action already started): off the trigger's path.
        self.log.info(
            "mission.inbridge.received",
            src_drone=t.src_drone,
            src=t.src,
            dst=t.dst,
            iteration=list(t.iteration),
            status=t.status,
        )

    def _line(self, method: str, event: str, **fields: Any) -> None:
        """A mission-log line of this turn (written by :meth:`_write_lines`)."""
        self._lines.append((self.log, method, event, fields, time.time()))

    def _write_lines(self) -> None:
        lines, self._lines = self._lines, []
        for log, method, event, fields, at in lines:
            log_line(log, method, event, fields, at)  # stamped when it happened

    def _send_news(self, lines: bool = True) -> None:
        if self._news and self.links is not None:
            news, self._news = tuple(self._news), []
            self._tell(self.links.executive, ExecutiveNews(news), lines)

    def on_failure(
        self,
        exception_type: type[BaseException] | None,
        exception_value: BaseException | None,
        traceback: TracebackType | None,
    ) -> None:
        """A ``tell``-ed message raised: apply the failure policy; the actor lives on."""
        if exception_type is None or exception_value is None:  # pragma: no cover - contract
            return
        self._crash(self._current, (exception_type, exception_value, traceback))

    def _input(self, message: object) -> Sequence[Effect]:
        logic = self.logic
        if isinstance(message, Trigger):
            return logic.trigger(message.src, message.iteration, message.status)
        if isinstance(message, ActionFinished):
            act: Iteration = message.token[1]  # type: ignore[index]  # our own (key, activation)
            result = message.result
            return logic.action_finished(
                act, result.status, result.reason, message.start_s, message.end_s
            )
        if isinstance(message, TelemetryChanged):
            return logic.telemetry(message.drone, message.values)
        if isinstance(message, Interrupt):
            return logic.interrupt(message)
        if isinstance(message, Release):
            return logic.release(message.iteration)
        if isinstance(message, PeerLost):
            return logic.peer_lost(message.sources)
        if isinstance(message, Fire):
            return logic.fire()
        if isinstance(message, Wire):
            self.links = message.links
        elif isinstance(message, AbortMission):
            return logic.abort()
        return ()

    # -- effects -> messages ------------------------------------------------------------

    def _apply(self, effects: Sequence[Effect]) -> None:
        first, external, rest = turn_order(self.amendable.outgoing(effects))
        for news in first:
            getattr(self, _APPLY[type(news)])(news)
        if external:
            self._send_news(lines=False)  # the turn's lines still wait for its triggers
        for emit in external:
            self._emit(emit)
        for effect in rest:
            getattr(self, _APPLY[type(effect)])(effect)

    def _tell(self, ref: Mailbox[T], message: T, lines: bool = True) -> None:
        """``ref.tell(message)``, this turn's log lines written first (``lines``: what the
        receiver writes because of it comes after them)."""
        if lines and self._lines:
            self._write_lines()
        try:
            ref.tell(message)
        except pykka.ActorDeadError:
            # Only while the runtime stops: the receiver is gone and nothing waits for it.
            self.log.debug("mission.node.receiver_gone", message=type(message).__name__)

    def _emit(self, fx: Emit) -> None:
        assert self.links is not None
        route = fx.route
        trigger = Trigger(self.key, route.dst, fx.iteration, fx.status)
        if route.external:
            out = self.links.out_bridge
            send = getattr(out, "send_trigger", None)
            if send is None:  # a stand-in taking messages only
                out.tell(SendTrigger(route.drone, trigger))
            else:
                line = send(route.drone, trigger)  # its log line comes back, for later
                if line is not None:
                    self._lines.append(line)
        else:
            self._tell(self.links.nodes[route.dst], trigger)
        if self._debug:
            self._trigger_note(fx, route)

    def _trigger_note(self, fx: Emit, route: Route) -> None:
        self._line(
            "debug",
            "mission.trigger.out",
            dst=route.dst,
            drone=route.drone,
            external=route.external,
            iteration=list(fx.iteration),
            status=fx.status,
        )

    def _start_action(self, fx: StartAction) -> None:
        assert self.links is not None
        action, args = fx.action, fx.args
        if self._replay is not None:
            ended = self._replay.ended(self.key, fx.iteration)
            if ended is not None:  # it ended before the restart: as it did, not again
                result, start_s, end_s = ended
                token = (self.key, fx.iteration)
                self._inline.append(ActionFinished(token, action, args, result, start_s, end_s))
                return
            cont = self._replay.continuation
            action, args = cont.rest(self.drone, self.key, fx.iteration, action, args, time.time())
        request = HalRun((self.key, fx.iteration), action, args, self.actor_ref)
        if self.links.uniform is None:
            self._tell(self.links.hal, request)
            return
        # On this thread: no hop.  Its result line waits for the end of the turn.
        finished = self.links.uniform.run(request, later=True)
        if finished is not None:
            self._results_held = True
            self._inline.append(finished)

    def _cancel_action(self, fx: CancelAction) -> None:
        assert self.links is not None
        token = (self.key, fx.iteration)
        if self.links.uniform is None:
            self._tell(self.links.hal, HalCancel(token))
        else:
            self.links.uniform.cancel(token)

    def _watch(self, fx: WatchTelemetry) -> None:
        assert self.links is not None
        self._tell(self.links.board, Watch(self.actor_ref, fx.drones))

    def _unwatch(self, fx: UnwatchTelemetry) -> None:
        assert self.links is not None
        self._tell(self.links.board, Unwatch(self.actor_ref))

    def _resolve(self, fx: Resolve) -> None:
        self._line("info", "mission.node.finished", iteration=list(fx.iteration), status=fx.status)
        if fx.top_level:
            self._news.append(NodeResolved(self.key, fx.status))

    def _broadcast(self, fx: Broadcast) -> None:
        self._news.append(BroadcastInterrupt(fx.interrupt, fx.drones))

    def _progress(self, fx: Progress) -> None:
        self._news.append(fx.event)

    def _record(self, fx: Record) -> None:
        self._news.append(fx.record)

    def _release_begin(self, fx: ReleaseBegin) -> None:
        assert self.links is not None
        ref = self.links.nodes.get(fx.begin)
        if ref is not None:  # a begin node on another drone keeps watching (harmless)
            self._tell(ref, Release(fx.iteration))

    def _note(self, fx: Note) -> None:
        self._line(fx.level, fx.event, **fx.fields)

    # -- failure policy -----------------------------------------------------------------

    def _crash(self, message: object, exc_info: ExcInfo) -> None:
        """Log once, resolve ``failed`` for what the node was doing, then ignore messages."""
        self.crashed = True
        self._inline.clear()
        if self._lines:
            self._write_lines()
        exc = exc_info[1]
        self.log.error(
            "mission.node.crashed",
            message=type(message).__name__,
            error=repr(exc),
            exc_info=exc_info,
        )
        tell_operator(self.drone, f"internal error in node {self.key}: {exc!r}: it resolves failed")
        if self.links is None:
            return
        acts = self._activations_at_crash(message)
        effects: list[Effect] = []
        if isinstance(self.logic, ActionLogic):
            effects += [CancelAction(act) for act in self.logic.running]
        top_level = not self.spec.loops
        for act in acts:
            effects += [Emit(route, act, "failed") for route in self.logic.routes]
            effects.append(
                Progress(
                    NodeEvent(self.key, "failed", self.spec.label, act, f"node crashed: {exc!r}")
                )
            )
            effects.append(Resolve(act, "failed", top_level and act == ()))
        try:
            self._apply(effects)
            self._send_news()
            self._write_lines()
        except Exception:
            self.log.exception("mission.node.crash_unreported")

    def _activations_at_crash(self, message: object) -> list[Iteration]:
        """The activations a crash leaves unfinished (at least one: the message's)."""
        logic = self.logic
        depth = len(self.spec.loops)
        acts: list[Iteration] = []
        if isinstance(message, Trigger):
            acts.append(message.iteration[:depth])
        elif isinstance(message, ActionFinished) and isinstance(message.token, tuple):
            acts.append(message.token[1])
        if isinstance(logic, ConditionLogic):
            acts += logic.pending
        if isinstance(logic, ActionLogic):
            acts += logic.running
        unique = list(dict.fromkeys(acts))
        return unique or [()]
