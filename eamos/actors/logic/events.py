"""Event handlers: ``Whenever(cond, Handler)``, its end node, and ``Abandon()``.

Shape (see :mod:`eamos.compiler.execution_graph`): the Whenever's begin node C
starts the statements it guards (R, on its ``body`` arcs) at once and watches
its condition while R runs.  Each time the condition *becomes* true (a rising
edge; true at the start counts), C suspends the running actions of the drones
the Handler uses (``Interrupt(C, act, "suspend")`` to ``suspend_drones``: see
:mod:`.actions`) and runs the Handler (its ``handler`` arcs) with a new counter,
like a loop body; when the Handler's last nodes come back on the ``loop`` arcs
it resumes them (``"resume"``).  A rising edge while the Handler runs is not
queued.  ``Abandon()`` in the Handler interrupts R on every drone of it
(``"all"``, as a Do does): the rest of R is skipped and the block ends.

The end node E joins R and C's ``begin`` arc.  When all of R has arrived, E
tells C (a local release: E is on C's drone); C stops watching and, once no
Handler runs, sends ``begin``: the statement after the block never starts
while a Handler still runs.
"""

from __future__ import annotations

from dataclasses import dataclass

from ..messages import Interrupt
from ..state import Fired, Iteration, Status
from .base import NodeLogic
from .conditions import ConditionLogic
from .effects import Broadcast, Effect, Emit, ReleaseBegin


@dataclass
class _Watch:
    """One activation of a Whenever."""

    counter: int = 0  # firings so far (the Handler's iteration counter)
    last: bool = False  # the condition's last value (for the rising edge)
    in_handler: bool = False
    released: bool = False  # R has ended: watch no more
    failed: bool = False  # a Handler failed


class WheneverLogic(ConditionLogic):
    """A Whenever's begin node (see module docstring)."""

    def __init__(self, *args: object, **kw: object) -> None:
        super().__init__(*args, **kw)  # type: ignore[arg-type]
        self.watches: dict[Iteration, _Watch] = {}

    def _pass_on(self, act: Iteration, status: Status) -> None:
        self._emit(act, lambda r: None if r.kind == "handler" else status)
        self._resolved(act, status)

    def _start(self, act: Iteration) -> None:
        self.watches[act] = _Watch()
        self._emit(act, lambda r: "done" if r.kind == "body" else None)
        self._await(act, "whenever")

    def _decide(self, act: Iteration, purpose: str, value: bool) -> None:
        watch = self.watches.get(act)
        if watch is None or purpose != "whenever":
            return
        rising = value and not watch.last
        watch.last = value
        if not rising or watch.in_handler or watch.released:
            return
        watch.in_handler = True
        self._decided(act, value, "mission.whenever.fired")
        self._event(act, "decided", f"{self.cond_text} became true: Handler runs")
        if self.spec.suspend_drones:
            self._suspend(act, "suspend")
        for route in self.routes:
            if route.kind == "handler":
                self._fx.append(Emit(route, (*act, watch.counter), "done"))

    def _body_done(self, fired: Fired) -> None:
        act = fired.activation[:-1]
        watch = self.watches.get(act)
        if watch is None or fired.activation[-1] != watch.counter:
            return
        watch.in_handler = False
        watch.counter += 1
        watch.failed = watch.failed or fired.status == "failed"
        self._note("info", "mission.whenever.handled", iteration=list(act), count=watch.counter)
        if self.spec.suspend_drones:
            self._suspend(act, "resume")
        if watch.released:
            self._finish(act)

    def release(self, iteration: Iteration) -> list[Effect]:
        watch = self.watches.get(iteration)
        if watch is not None and not watch.released:
            watch.released = True
            self._drop_pending(iteration)
            if not watch.in_handler:
                self._finish(iteration)
        return self._take()

    def _finish(self, act: Iteration) -> None:
        watch = self.watches.pop(act)
        status: Status = "failed" if watch.failed else "done"
        self._emit(act, lambda r: status if r.kind == "begin" else None)
        self._resolved(act, status)

    def _suspend(self, act: Iteration, mode: str) -> None:
        self._fx.append(Broadcast(Interrupt(self.spec.meg, act, mode), self.spec.suspend_drones))

    def _skip(self, act: Iteration, purpose: str) -> None:
        """An enclosing structure (a Do, a Try) interrupted the block.

        The watch is dropped already (no more firings); R and a running Handler
        are interrupted too and come back ``skipped``, and E's release then ends
        the activation as usual.
        """


class WheneverEndLogic(NodeLogic):
    """A Whenever's end node: tells its begin when R ended, then joins them."""

    def __init__(self, *args: object, **kw: object) -> None:
        super().__init__(*args, **kw)  # type: ignore[arg-type]
        self.begin_key = f"n{self.spec.begin}"
        self.released: set[Iteration] = set()

    def trigger(self, src: str, iteration: Iteration, status: Status) -> list[Effect]:
        out = super().trigger(src, iteration, status)
        for (_, act), missing in self.pre.waiting().items():
            if missing == {self.begin_key} and act not in self.released:
                self.released.add(act)
                out.append(ReleaseBegin(self.begin_key, act))
        return out

    def _activate(self, act: Iteration, fired: Fired) -> None:
        self.released.discard(act)
        begin_status = fired.statuses.get(self.begin_key, "done")
        rest = [s for src, s in fired.statuses.items() if src != self.begin_key]
        status: Status = begin_status
        if begin_status == "done" and "failed" in rest:
            status = "failed"
        # R skipped by an Abandon() still ends the block normally: the mission goes on.
        self._emit(act, lambda r: status)
        self._resolved(act, status)


class AbandonLogic(NodeLogic):
    """``Abandon()``: skip the rest of the block its Whenever guards, on every drone of it."""

    def _start(self, act: Iteration) -> None:
        begin = self.spec.begin
        assert begin is not None
        depth = self.spec.loops.index(begin) if begin in self.spec.loops else len(act)
        self._note("warning", "mission.whenever.abandon", iteration=list(act[:depth]))
        self._event(act, "decided", "Abandon(): the rest of the block is skipped")
        self._fx.append(Broadcast(Interrupt(begin, act[:depth], "all"), self.spec.interrupt_drones))
        super()._start(act)
