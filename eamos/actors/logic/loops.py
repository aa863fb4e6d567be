"""A Repeat's begin node: runs Body once per iteration while it should, then Exit.

Each iteration re-arms Body with a new counter (its activation is the loop's
own plus the counter); Body's end comes back on the ``loop`` arcs.  RepeatWhile/
Until decide before every iteration; while Body runs they watch the condition
and, when it ends the loop, interrupt the Wait/Pause nodes of Body (mode
``"waits"``) so no drone waits forever for a loop that is over.  RepeatFor
counts.  An enclosing Do's interrupt makes the loop leave with ``skipped``.

A back arc may arrive before its iteration began: a node restarted mid-mission
(:mod:`eamos.actors.rejoin`) hears its peers resend every trigger they sent it
at once, the back arcs of iterations its own replay has not reached yet among
them.  Such a back arc is kept, and taken as that iteration's end when the
iteration begins (its body is then replayed: the back arc says it all ended).
"""

from __future__ import annotations

from dataclasses import dataclass

from ...program.format import ProgramNode
from ..state import Fired, Iteration, Status, holds, within
from .conditions import ConditionLogic
from .effects import Route


@dataclass
class LoopState:
    """One activation of a loop."""

    counter: int = 0
    in_body: bool = False
    interrupted: bool = False  # by an enclosing Do: leave with "skipped"
    stop_sent: bool = False  # the waits of this iteration were interrupted already


class LoopLogic(ConditionLogic):
    """``RepeatWhile``/``RepeatUntil``/``RepeatFor`` (see module docstring)."""

    def __init__(
        self,
        spec: ProgramNode,
        routes: tuple[Route, ...],
        entry: frozenset[str],
        loop: frozenset[str] = frozenset(),
    ) -> None:
        super().__init__(spec, routes, entry, loop)
        self.loops: dict[Iteration, LoopState] = {}
        self.counted = spec.kind == "repeat_for"
        # Back arcs that came before their iteration began, by (loop activation, counter).
        self._early: dict[tuple[Iteration, int], Fired] = {}
        self._due: list[Fired] = []  # early back arcs whose iteration began, to take in order
        self._taking = False

    def _pass_on(self, act: Iteration, status: Status) -> None:
        self._emit(act, lambda r: status if r.kind == "exit" else None)
        self._resolved(act, status)

    def _start(self, act: Iteration) -> None:
        self.loops[act] = LoopState()
        self._next(act)

    def _next(self, act: Iteration) -> None:
        """Decide whether another iteration runs (RepeatFor counts; the others ask)."""
        if self.counted:
            self._go(act, self.loops[act].counter < (self.spec.count or 0))
        else:
            self._await(act, "loop")

    def _decide(self, act: Iteration, purpose: str, value: bool) -> None:
        if purpose == "loop":
            self._drop_pending(act)
            self._go(act, holds(self.spec.kind, value))
        elif purpose == "loop-watch":
            state = self.loops.get(act)
            if (
                state is not None
                and state.in_body
                and not state.stop_sent
                and not holds(self.spec.kind, value)
            ):
                state.stop_sent = True
                self._drop_pending(act, "loop-watch")
                self._broadcast_interrupt((*act, state.counter), "waits")

    def _go(self, act: Iteration, go: bool) -> None:
        state = self.loops[act]
        if state.interrupted:
            go = False
        if go:
            state.in_body = True
            state.stop_sent = False
            self._note("info", "mission.loop.iteration", iteration=list(act), counter=state.counter)
            self._emit(act, lambda r: "done" if r.kind == "body" else None, (*act, state.counter))
            if self.spec.interrupt_drones and not self.counted:
                self._await(act, "loop-watch")
            early = self._early.pop((act, state.counter), None)
            if early is not None:
                self._take_early(early)
        else:
            final: Status = "skipped" if state.interrupted else "done"
            self._note(
                "info",
                "mission.loop.exit",
                iteration=list(act),
                counter=state.counter,
                status=final,
            )
            del self.loops[act]
            self._emit(act, lambda r: final if r.kind == "exit" else None)
            self._resolved(act, final)

    def _take_early(self, fired: Fired) -> None:
        """An early back arc's iteration began: its body ended.  A work list, not
        recursion (each taken back arc begins the next iteration, which may have one)."""
        self._due.append(fired)
        if self._taking:
            return
        self._taking = True
        try:
            while self._due:
                self._body_done(self._due.pop(0))
        finally:
            self._taking = False

    def _body_done(self, fired: Fired) -> None:
        act = fired.activation[:-1]
        counter = fired.activation[-1]
        state = self.loops.get(act)
        if (
            state is None
            or counter > state.counter
            or (counter == state.counter and not state.in_body)
        ):
            self._early[(act, counter)] = fired  # before its iteration began (see above)
            return
        if counter != state.counter:
            return
        state.in_body = False
        self._drop_pending(act, "loop-watch")
        if fired.status == "failed":
            del self.loops[act]
            self._emit(act, lambda r: "failed" if r.kind == "exit" else None)
            self._resolved(act, "failed")
            return
        state.counter += 1
        self._next(act)

    def _skip(self, act: Iteration, purpose: str) -> None:
        if purpose == "loop":
            self.loops[act].interrupted = True
            self._go(act, False)

    def _interrupt_within(self, scope_iteration: Iteration) -> None:
        super()._interrupt_within(scope_iteration)
        for act, state in self.loops.items():
            if within(act, scope_iteration):
                state.interrupted = True
