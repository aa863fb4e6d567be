"""Exception handlers: the end node of ``Try(Body, OnFailure)``.

A Try is shaped like a Do in the graphs (begin C, Body, end E, OnFailure
hanging from E's ``exit`` arcs).  Its begin node is a pass-through.  An action
that fails inside Body (:class:`~.base.ActionLogic`, which knows its
innermost Try from its program record) interrupts Body on every drone of it
and hands ``failed`` on as always; the failure reaches E through Body's arcs
(data, not a race with the interrupt).  E then *catches* it: OnFailure runs
(``done`` on E's ``exit`` arcs) and E hands ``done`` on, so the mission goes
on.  A Body that completed skips OnFailure (``skipped``), as a Do skips its
Exit: every arc still carries one trigger (dead-path elimination).
"""

from __future__ import annotations

from ..state import Fired, Iteration
from .base import NodeLogic


class TryEndLogic(NodeLogic):
    """A Try's end node: joins Body and runs OnFailure only if Body failed."""

    def _activate(self, act: Iteration, fired: Fired) -> None:
        begin_key = f"n{self.spec.begin}"
        begin_status = fired.statuses.get(begin_key, "done")
        if begin_status != "done" or self._interrupted(act):
            # The Try itself did not run (or an enclosing structure interrupted it):
            # hand that on, OnFailure included.
            status = begin_status if begin_status != "done" else "skipped"
            self._emit(act, lambda r: status)
            self._resolved(act, status)
            return
        body = [s for src, s in fired.statuses.items() if src != begin_key]
        caught = "failed" in body
        if caught:
            self._note("warning", "mission.try.caught", iteration=list(act), line=self.spec.line)
            self._event(act, "decided", "Body failed: the failure is caught, OnFailure runs")
        else:
            self._note("info", "mission.try.end", iteration=list(act), caught=False)
        self._emit(act, lambda r: ("done" if caught else "skipped") if r.kind == "exit" else "done")
        self._resolved(act, "done")
