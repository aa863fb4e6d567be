"""Mission node actors: one Pykka actor per native MDG node (paper VI-B).

A node waits until all its precondition arcs delivered a trigger for one
activation (:class:`~.state.Preconditions`), does its work (an action through
the uniform API, a condition, a fork), then triggers its successors, locally
by message or through the out-bridge.  Conditions are evaluated when the
telemetry they read changes (pushed by the telemetry board), never by polling.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

from ..program.conditions import Unknown, evaluate, properties, to_text
from ..program.format import ProgramNode
from .dispatch import Dispatcher, PooledActor
from .messages import (
    AbortMission,
    ActionRecord,
    Fire,
    Interrupt,
    NodeEvent,
    NodeResolved,
    Release,
    SendTrigger,
    TelemetryChanged,
    Trigger,
    Unwatch,
    Watch,
)
from .state import Fired, Iteration, Preconditions, Status, holds, within
from .uniform_api import ActionFinished, CancelAction, RunAction

LOOP_KINDS = frozenset({"repeat_while", "repeat_until", "repeat_for"})
DO_KINDS = frozenset({"do_while", "do_until"})
WAIT_KINDS = frozenset({"wait_while", "wait_until", "pause_while", "pause_until"})
CONDITION_KINDS = frozenset({"if"}) | LOOP_KINDS | DO_KINDS | WAIT_KINDS

_RESULT_STATUS: dict[str, Status] = {"ok": "done", "failed": "failed", "cancelled": "skipped"}


@dataclass(frozen=True)
class Route:
    """One outgoing arc of a node."""

    dst: str
    drone: str
    kind: str
    external: bool


@dataclass(frozen=True)
class Links:
    """Who a node talks to; handed over once all actors of the runtime exist."""

    nodes: Mapping[str, Any]  # key -> ActorRef of the local native nodes
    hal: Any
    board: Any
    out_bridge: Any
    executive: Any


@dataclass(frozen=True)
class Wire:
    """Give a node its links (first message every node receives)."""

    links: Links


@dataclass(frozen=True)
class BroadcastInterrupt:
    """A begin node asks the executive to interrupt its body on these drones."""

    interrupt: Interrupt
    drones: tuple[str, ...]


@dataclass
class _Loop:
    counter: int = 0
    in_body: bool = False
    interrupted: bool = False  # by an enclosing Do: leave with "skipped"
    stop_sent: bool = False  # the waits of this iteration were interrupted already


@dataclass
class _Pending:
    """An activation waiting for its condition to decide something."""

    purpose: str  # "if", "wait", "loop", "do", "loop-watch", "do-watch"
    since: float = field(default_factory=time.monotonic)


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
        log: Any,
        begin_kind: str = "",
    ) -> None:
        super().__init__(dispatcher)
        self.spec = spec
        self.key = spec.key
        self.routes = routes
        self.drone = drone
        self.log = log.bind(node=spec.key)
        self.pre = Preconditions(entry=entry, loop=loop, depth=len(spec.loops))
        self.links: Links | None = None
        self.values: dict[str, dict[str, Any]] = {}
        self.pending: dict[Iteration, _Pending] = {}
        self.loops: dict[Iteration, _Loop] = {}
        self.running: dict[Iteration, tuple[Any, float]] = {}
        self.interrupts: set[tuple[int, Iteration]] = set()
        self.watching = False
        self.aborted = False
        self.begin_kind = begin_kind  # for end nodes: the kind of their begin node
        self.cond_drones = tuple(sorted({drone for drone, _ in properties(spec.cond)}))

    # -- dispatch -------------------------------------------------------------

    def on_receive(self, message: Any) -> Any:
        if isinstance(message, Trigger):
            self.log.debug(
                "mission.trigger.in",
                src=message.src,
                iteration=list(message.iteration),
                status=message.status,
            )
            fired = self.pre.receive(message.src, message.iteration, message.status)
            if fired is None:
                self.log.debug(
                    "mission.precondition",
                    src=message.src,
                    waiting=sorted(map(str, self.pre.waiting())),
                )
            else:
                self._fired(fired)
        elif isinstance(message, ActionFinished):
            self._action_finished(message)
        elif isinstance(message, TelemetryChanged):
            self.values[message.drone] = message.values
            self._reevaluate()
        elif isinstance(message, Interrupt):
            self._interrupt(message)
        elif isinstance(message, Release):
            self._drop_pending(message.iteration, "do-watch")
        elif isinstance(message, Fire):
            fired = self.pre.fire_without_arcs()
            if fired is not None:
                self._fired(fired)
        elif isinstance(message, Wire):
            self.links = message.links
        elif isinstance(message, AbortMission):
            self._abort()
        return None

    # -- activation -----------------------------------------------------------

    def _fired(self, fired: Fired) -> None:
        if self.aborted:
            return
        spec = self.spec
        act = fired.activation
        if fired.group == "loop":
            self._loop_body_done(fired)
            return
        status = fired.status
        self.log.info(
            "mission.node.triggered",
            iteration=list(act),
            status=status,
            preconditions=dict(sorted(fired.statuses.items())),
        )
        if spec.kind == "end" and self._begin_kind() in DO_KINDS:
            self._do_end(act, fired)
            return
        if status == "done" and self._interrupted(act):
            status = "skipped"
        if status != "done":
            if spec.kind in LOOP_KINDS:
                self._emit(act, lambda r: status if r.kind == "exit" else None)
            else:
                self._emit(act, lambda r: status)
            if spec.kind == "action":
                self._event(act, "blocked" if status == "failed" else "skipped")
            self._resolved(act, status)
            return
        kind = spec.kind
        if kind in ("init", "fork", "end"):
            self._emit(act, lambda r: "done")
            self._resolved(act, "done")
        elif kind == "action":
            self._run_action(act)
        elif kind == "if":
            self._await(act, "if")
        elif kind in WAIT_KINDS:
            self._event(act, "waiting", to_text(spec.cond))
            self._await(act, "wait")
        elif kind in LOOP_KINDS:
            self.loops[act] = _Loop()
            self._loop_decide(act)
        elif kind in DO_KINDS:
            self._await(act, "do")
        else:  # pragma: no cover - program loading rejects unknown kinds
            self.log.error("mission.node.unknown_kind", kind=kind)

    def _begin_kind(self) -> str:
        return self.begin_kind

    # -- emitting ---------------------------------------------------------------

    def _emit(
        self,
        act: Iteration,
        status_for: Callable[[Route], Status | None],
        body_iteration: Iteration | None = None,
    ) -> None:
        assert self.links is not None
        for route in self.routes:
            status = status_for(route)
            if status is None:
                continue
            iteration = (
                body_iteration if (route.kind == "body" and body_iteration is not None) else act
            )
            trigger = Trigger(self.key, route.dst, iteration, status)
            if route.external:
                self.links.out_bridge.tell(SendTrigger(route.drone, trigger))
            else:
                self.links.nodes[route.dst].tell(trigger)
            self.log.debug(
                "mission.trigger.out",
                dst=route.dst,
                drone=route.drone,
                external=route.external,
                iteration=list(iteration),
                status=status,
            )

    def _resolved(self, act: Iteration, status: Status) -> None:
        self.log.info("mission.node.finished", iteration=list(act), status=status)
        if not self.spec.loops and act == () and self.links is not None:
            self.links.executive.tell(NodeResolved(self.key, status))

    def _event(self, act: Iteration, state: str, detail: str = "") -> None:
        if self.links is not None:
            self.links.executive.tell(NodeEvent(self.key, state, self.spec.label, act, detail))

    # -- actions ------------------------------------------------------------------

    def _run_action(self, act: Iteration) -> None:
        assert self.links is not None and self.spec.action is not None
        token = (self.key, act)
        self.running[act] = (token, time.time())
        self._event(act, "running")
        self.links.hal.tell(RunAction(token, self.spec.action, self.spec.args, self.actor_ref))

    def _action_finished(self, msg: ActionFinished) -> None:
        act: Iteration = msg.token[1]  # type: ignore[index]  # our own (key, activation)
        if self.running.pop(act, None) is None:
            return
        assert self.links is not None
        result = msg.result
        # The record doubles as the "finished" progress event (one message, not two).
        self.links.executive.tell(
            ActionRecord(
                self.key,
                msg.action,
                tuple(msg.args),
                act,
                msg.start_s,
                msg.end_s,
                result.status,
                result.reason,
            )
        )
        if self.aborted:
            return
        status = _RESULT_STATUS[result.status]
        if result.status == "failed":
            self.log.error(
                "mission.action.failed",
                action=msg.action,
                reason=result.reason,
                iteration=list(act),
            )
        self._emit(act, lambda r: status)
        self._resolved(act, status)

    # -- conditions -----------------------------------------------------------------

    def _lookup(self, drone: str, prop: str) -> Any:
        return self.values.get(drone, {}).get(prop)

    def _value(self) -> bool | None:
        if self.spec.cond is None:
            return None
        try:
            return bool(evaluate(self.spec.cond, self._lookup))
        except Unknown:
            return None

    def _await(self, act: Iteration, purpose: str) -> None:
        self.pending[act] = _Pending(purpose)
        self._watch()
        self._check(act)

    def _drop_pending(self, act: Iteration, purpose: str | None = None) -> None:
        entry = self.pending.get(act)
        if entry is not None and (purpose is None or entry.purpose == purpose):
            del self.pending[act]
        if not self.pending:
            self._unwatch()

    def _watch(self) -> None:
        if not self.watching and self.links is not None and self.cond_drones:
            self.watching = True
            # Values cached while not watching are stale: decide on the board's fresh push.
            self.values.clear()
            self.links.board.tell(Watch(self.actor_ref, self.cond_drones))

    def _unwatch(self) -> None:
        if self.watching and self.links is not None:
            self.watching = False
            self.links.board.tell(Unwatch(self.actor_ref))

    def _reevaluate(self) -> None:
        for act in list(self.pending):
            self._check(act)

    def _check(self, act: Iteration) -> None:
        entry = self.pending.get(act)
        if entry is None or self.aborted:
            return
        spec = self.spec
        maybe = self._value()
        if maybe is None:
            return  # a property it reads has no value yet: the next telemetry decides
        value = maybe
        purpose = entry.purpose
        if purpose == "if":
            self._drop_pending(act)
            self.log.info(
                "mission.condition", cond=to_text(spec.cond), value=value, iteration=list(act)
            )
            branch = "then" if value else "else"
            self._emit(
                act,
                lambda r: (
                    "done"
                    if r.kind == branch
                    else ("skipped" if r.kind in ("then", "else") else "done")
                ),
            )
            self._resolved(act, "done")
        elif purpose == "wait":
            if holds(spec.kind, value):
                return
            self._drop_pending(act)
            self.log.info(
                "mission.condition", cond=to_text(spec.cond), value=value, iteration=list(act)
            )
            self._event(act, "ok")
            self._emit(act, lambda r: "done")
            self._resolved(act, "done")
        elif purpose == "loop":
            self._drop_pending(act)
            self._loop_go(act, holds(spec.kind, value))
        elif purpose == "loop-watch":
            state = self.loops.get(act)
            if (
                state is not None
                and state.in_body
                and not state.stop_sent
                and not holds(spec.kind, value)
            ):
                state.stop_sent = True
                self._drop_pending(act, "loop-watch")
                self._broadcast_interrupt((*act, state.counter), "waits")
        elif purpose == "do":
            self._drop_pending(act)
            go = holds(spec.kind, value)
            self.log.info(
                "mission.condition", cond=to_text(spec.cond), value=value, iteration=list(act)
            )
            self._emit(act, lambda r: ("done" if go else "skipped") if r.kind == "body" else "done")
            self._resolved(act, "done")
            if go:
                self.pending[act] = _Pending("do-watch")
                self._watch()
                self._check(act)
        elif purpose == "do-watch" and not holds(spec.kind, value):
            self._drop_pending(act, "do-watch")
            self.log.info(
                "mission.interrupt", cond=to_text(spec.cond), value=value, iteration=list(act)
            )
            self._broadcast_interrupt(act, "all")

    def _broadcast_interrupt(self, iteration: Iteration, mode: str) -> None:
        assert self.links is not None
        self.links.executive.tell(
            BroadcastInterrupt(
                Interrupt(self.spec.meg, iteration, mode), self.spec.interrupt_drones
            )
        )

    # -- loops -------------------------------------------------------------------------

    def _loop_decide(self, act: Iteration) -> None:
        if self.spec.kind == "repeat_for":
            state = self.loops[act]
            self._loop_go(act, state.counter < (self.spec.count or 0))
        else:
            self._await(act, "loop")

    def _loop_go(self, act: Iteration, go: bool) -> None:
        state = self.loops[act]
        if state.interrupted:
            go = False
        if go:
            state.in_body = True
            state.stop_sent = False
            self.log.info("mission.loop.iteration", iteration=list(act), counter=state.counter)
            self._emit(act, lambda r: "done" if r.kind == "body" else None, (*act, state.counter))
            if self.spec.interrupt_drones and self.spec.kind != "repeat_for":
                self.pending[act] = _Pending("loop-watch")
                self._watch()
                self._check(act)
        else:
            final: Status = "skipped" if state.interrupted else "done"
            self.log.info(
                "mission.loop.exit", iteration=list(act), counter=state.counter, status=final
            )
            del self.loops[act]
            self._emit(act, lambda r: final if r.kind == "exit" else None)
            self._resolved(act, final)

    def _loop_body_done(self, fired: Fired) -> None:
        act = fired.activation[:-1]
        state = self.loops.get(act)
        if state is None or fired.activation[-1] != state.counter:
            return
        state.in_body = False
        self._drop_pending(act, "loop-watch")
        if fired.status == "failed":
            del self.loops[act]
            self._emit(act, lambda r: "failed" if r.kind == "exit" else None)
            self._resolved(act, "failed")
            return
        state.counter += 1
        self._loop_decide(act)

    # -- Do -----------------------------------------------------------------------------

    def _do_end(self, act: Iteration, fired: Fired) -> None:
        begin_key = f"n{self.spec.begin}"
        begin_status = fired.statuses.get(begin_key, "done")
        body = [s for src, s in fired.statuses.items() if src != begin_key]
        assert self.links is not None
        if begin_key in self.links.nodes:
            self.links.nodes[begin_key].tell(Release(act))
        if begin_status != "done":
            self._emit(act, lambda r: begin_status)
            self._resolved(act, begin_status)
            return
        if "failed" in body:
            self._emit(act, lambda r: "failed")
            self._resolved(act, "failed")
            return
        completed = all(s == "done" for s in body)
        self.log.info("mission.do.end", iteration=list(act), interrupted=not completed)
        self._emit(
            act, lambda r: ("skipped" if completed else "done") if r.kind == "exit" else "done"
        )
        self._resolved(act, "done")

    # -- interruption and abort ---------------------------------------------------------

    def _applies(self, mode: str) -> bool:
        return mode == "all" or self.spec.kind in WAIT_KINDS

    def _interrupted(self, act: Iteration) -> bool:
        return any(within(act, it) for _, it in self.interrupts)

    def _interrupt(self, msg: Interrupt) -> None:
        if msg.scope not in self.spec.scopes or not self._applies(msg.mode):
            return
        self.interrupts.add((msg.scope, msg.iteration))
        self.log.info(
            "mission.node.interrupted",
            scope=msg.scope,
            iteration=list(msg.iteration),
            mode=msg.mode,
        )
        assert self.links is not None
        for act, (token, _) in list(self.running.items()):
            if within(act, msg.iteration):
                self.links.hal.tell(CancelAction(token))
        for act, entry in list(self.pending.items()):
            if not within(act, msg.iteration):
                continue
            purpose = entry.purpose
            self._drop_pending(act)
            if purpose in ("if", "wait"):
                self._event(act, "skipped")
                self._emit(act, lambda r: "skipped")
                self._resolved(act, "skipped")
            elif purpose == "do":
                self._emit(act, lambda r: "skipped")
                self._resolved(act, "skipped")
            elif purpose == "loop":
                self.loops[act].interrupted = True
                self._loop_go(act, False)
        for act, state in self.loops.items():
            if within(act, msg.iteration):
                state.interrupted = True

    def _abort(self) -> None:
        self.aborted = True
        self.pending.clear()
        self._unwatch()
        self.log.warning("mission.node.aborted")
