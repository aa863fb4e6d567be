"""Nodes that decide on a condition: If, Wait/Pause, Do (begin and end).

A condition is evaluated when the telemetry it reads changes (the host pushes
it after :class:`~.effects.WatchTelemetry`), never by polling.  While a
property it reads has no value yet (or went stale) the node keeps waiting.
An activation waiting on the condition is *pending* with a purpose: ``if``,
``wait``, ``do`` (decide whether Body runs), ``do-watch`` (Body runs: interrupt
it when the condition stops holding), and for loops (:mod:`.loops`) ``loop``
and ``loop-watch``.
"""

from __future__ import annotations

from collections.abc import Callable

from ...program.conditions import Unknown, evaluate, properties, to_text
from ...program.format import ProgramNode
from ..messages import Interrupt
from ..state import Fired, Iteration, holds, within
from .base import NodeLogic
from .effects import Broadcast, Effect, ReleaseBegin, Route, UnwatchTelemetry, WatchTelemetry
from .telemetry import PropertyValues

#: ``override(activation, purpose, value) -> value to use`` (see :attr:`ConditionLogic.override`).
Override = Callable[[Iteration, str, bool], bool]


class ConditionLogic(NodeLogic):
    """The watching part shared by every node with a condition.

    ``override``, when set, is asked for every decision with the value the
    condition has, and its answer is used instead: the pre-flight check takes
    both ways of a condition the simulation cannot know (a battery, a pilot).
    """

    override: Override | None = None

    def __init__(
        self,
        spec: ProgramNode,
        routes: tuple[Route, ...],
        entry: frozenset[str],
        loop: frozenset[str] = frozenset(),
    ) -> None:
        super().__init__(spec, routes, entry, loop)
        self.values: dict[str, PropertyValues] = {}
        self.pending: dict[Iteration, str] = {}  # activation -> purpose
        self.watching = False
        self.cond_drones = tuple(sorted({drone for drone, _ in properties(spec.cond)}))
        self.cond_text = to_text(spec.cond)

    def telemetry(self, drone: str, values: PropertyValues) -> list[Effect]:
        self.values[drone] = values
        for act in list(self.pending):
            self._check(act)
        return self._take()

    # -- watching -------------------------------------------------------------------

    def _await(self, act: Iteration, purpose: str) -> None:
        self.pending[act] = purpose
        self._watch()
        self._check(act)

    def _drop_pending(self, act: Iteration, purpose: str | None = None) -> None:
        if act in self.pending and (purpose is None or self.pending[act] == purpose):
            del self.pending[act]
        if not self.pending:
            self._unwatch()

    def _watch(self) -> None:
        if not self.watching and self.cond_drones:
            self.watching = True
            # Values cached while not watching are stale: decide on the host's fresh push.
            self.values.clear()
            self._fx.append(WatchTelemetry(self.cond_drones))

    def _unwatch(self) -> None:
        if self.watching:
            self.watching = False
            self._fx.append(UnwatchTelemetry())

    def _lookup(self, drone: str, prop: str) -> float | bool | None:
        return self.values.get(drone, {}).get(prop)

    def _value(self) -> bool | None:
        if self.spec.cond is None:
            return None
        try:
            return bool(evaluate(self.spec.cond, self._lookup))
        except Unknown:
            return None

    def _check(self, act: Iteration) -> None:
        purpose = self.pending.get(act)
        if purpose is None or self.aborted:
            return
        value = self._value()
        if value is None:
            return  # a property it reads has no value yet: the next telemetry decides
        if self.override is not None:
            value = self.override(act, purpose, value)
        self._decide(act, purpose, value)

    def _decide(self, act: Iteration, purpose: str, value: bool) -> None:
        """The condition has a value while ``act`` waits for ``purpose``."""
        raise NotImplementedError

    def _skip(self, act: Iteration, purpose: str) -> None:
        """An interrupt reached ``act`` while it waited for ``purpose``."""

    def _interrupt_within(self, scope_iteration: Iteration) -> None:
        for act, purpose in list(self.pending.items()):
            if within(act, scope_iteration):
                self._drop_pending(act)
                self._skip(act, purpose)

    def _on_abort(self) -> None:
        self.pending.clear()
        self._unwatch()

    def _decided(self, act: Iteration, value: bool, event: str = "mission.condition") -> None:
        self._note("info", event, cond=self.cond_text, value=value, iteration=list(act))

    def _broadcast_interrupt(self, iteration: Iteration, mode: str) -> None:
        self._fx.append(
            Broadcast(Interrupt(self.spec.meg, iteration, mode), self.spec.interrupt_drones)
        )


class IfLogic(ConditionLogic):
    """``If(cond, Then, Else)``: ``done`` down the branch taken, ``skipped`` down the other."""

    def _start(self, act: Iteration) -> None:
        self._await(act, "if")

    def _decide(self, act: Iteration, purpose: str, value: bool) -> None:
        self._drop_pending(act)
        self._decided(act, value)
        branch = "then" if value else "else"
        # The operator sees which way it went (a "decided" progress line).
        self._event(act, "decided", f"{branch}: {self.cond_text} is {str(value).lower()}")
        self._emit(
            act,
            lambda r: (
                "done"
                if r.kind == branch
                else ("skipped" if r.kind in ("then", "else") else "done")
            ),
        )
        self._resolved(act, "done")

    def _skip(self, act: Iteration, purpose: str) -> None:
        self._event(act, "skipped")
        self._emit(act, lambda r: "skipped")
        self._resolved(act, "skipped")


class WaitLogic(ConditionLogic):
    """``Wait*``/``Pause*``: hand on once the While condition is false (Until: true)."""

    interrupted_by_waits = True

    def _start(self, act: Iteration) -> None:
        self._event(act, "waiting", self.cond_text)
        self._await(act, "wait")

    def _decide(self, act: Iteration, purpose: str, value: bool) -> None:
        if holds(self.spec.kind, value):
            return
        self._drop_pending(act)
        self._decided(act, value)
        self._event(act, "ok")
        self._emit(act, lambda r: "done")
        self._resolved(act, "done")

    def _skip(self, act: Iteration, purpose: str) -> None:
        self._event(act, "skipped")
        self._emit(act, lambda r: "skipped")
        self._resolved(act, "skipped")


class DoLogic(ConditionLogic):
    """A Do's begin node: Body runs if the condition holds, and is interrupted when it stops."""

    def _start(self, act: Iteration) -> None:
        self._await(act, "do")

    def release(self, iteration: Iteration) -> list[Effect]:
        self._drop_pending(iteration, "do-watch")
        return self._take()

    def _decide(self, act: Iteration, purpose: str, value: bool) -> None:
        go = holds(self.spec.kind, value)
        if purpose == "do":
            self._drop_pending(act)
            self._decided(act, value)
            self._emit(act, lambda r: ("done" if go else "skipped") if r.kind == "body" else "done")
            self._resolved(act, "done")
            if go:
                self._await(act, "do-watch")
        elif purpose == "do-watch" and not go:
            self._drop_pending(act, "do-watch")
            self._decided(act, value, "mission.interrupt")
            self._broadcast_interrupt(act, "all")

    def _skip(self, act: Iteration, purpose: str) -> None:
        if purpose == "do":
            self._emit(act, lambda r: "skipped")
            self._resolved(act, "skipped")


class DoEndLogic(NodeLogic):
    """A Do's end node: joins Body and decides whether the Exit block runs.

    Exit runs (``done`` on its arcs) only if Body was interrupted (some of it
    skipped); a Body that completed skips Exit.  It also releases the begin node.
    """

    def _activate(self, act: Iteration, fired: Fired) -> None:
        begin_key = f"n{self.spec.begin}"
        begin_status = fired.statuses.get(begin_key, "done")
        body = [s for src, s in fired.statuses.items() if src != begin_key]
        self._fx.append(ReleaseBegin(begin_key, act))
        if begin_status != "done":
            self._emit(act, lambda r: begin_status)
            self._resolved(act, begin_status)
            return
        if "failed" in body:
            self._emit(act, lambda r: "failed")
            self._resolved(act, "failed")
            return
        completed = all(s == "done" for s in body)
        self._note("info", "mission.do.end", iteration=list(act), interrupted=not completed)
        self._emit(
            act, lambda r: ("skipped" if completed else "done") if r.kind == "exit" else "done"
        )
        self._resolved(act, "done")
