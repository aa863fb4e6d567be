"""The common part of every node's logic, and the two simplest kinds.

:class:`NodeLogic` counts preconditions (:class:`~eamos.actors.state.Preconditions`),
applies dead-path elimination (a node whose predecessors were all skipped is
skipped, one with a failed predecessor is blocked) and interrupts; subclasses
say what a node does once it runs (:meth:`NodeLogic._start`).  Every input
returns the effects it caused, in order (:mod:`.effects`); nothing here sends a
message, reads a clock or starts a thread.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, ClassVar

from ...program.format import ProgramNode
from ..messages import Interrupt, NodeEvent
from ..state import Fired, Iteration, Preconditions, Status, within
from .effects import Broadcast, Effect, Emit, Note, Progress, Resolve, Route
from .telemetry import PropertyValues


class NodeLogic:
    """Pure state machine of one native MDG node (see module docstring).

    Inputs: :meth:`trigger`, :meth:`fire`, :meth:`action_finished`,
    :meth:`telemetry`, :meth:`interrupt`, :meth:`release`, :meth:`abort`;
    each returns the list of effects the host must apply, in order.
    """

    #: Whether an interrupt in mode ``"waits"`` (a Repeat ending) reaches this kind.
    interrupted_by_waits: ClassVar[bool] = False

    def __init__(
        self,
        spec: ProgramNode,
        routes: tuple[Route, ...],
        entry: frozenset[str],
        loop: frozenset[str] = frozenset(),
    ) -> None:
        self.spec = spec
        self.key = spec.key
        self.routes = routes
        self.pre = Preconditions(entry=entry, loop=loop, depth=len(spec.loops))
        self.interrupts: set[tuple[int, Iteration]] = set()
        self.aborted = False
        self._fx: list[Effect] = []
        # True when nobody reads the node's log notes and progress events (a
        # virtual run without a log): they are then not made at all.
        self.quiet = False
        # False when the host's log drops debug lines: debug notes are then not made.
        self.debug_notes = True

    # -- inputs ------------------------------------------------------------------

    def trigger(self, src: str, iteration: Iteration, status: Status) -> list[Effect]:
        """A precondition arc from ``src`` delivered ``status`` for ``iteration``."""
        if self.debug_notes:
            self._note(
                "debug", "mission.trigger.in", src=src, iteration=list(iteration), status=status
            )
        fired = self.pre.receive(src, iteration, status)
        if fired is None:
            if self.debug_notes:
                self._note(
                    "debug",
                    "mission.precondition",
                    src=src,
                    waiting=sorted(map(str, self.pre.waiting())),
                )
        else:
            self._fired(fired)
        return self._take()

    def fire(self) -> list[Effect]:
        """The start trigger of a node without entry arcs (the initial node)."""
        fired = self.pre.fire_without_arcs()
        if fired is not None:
            self._fired(fired)
        return self._take()

    def action_finished(
        self, iteration: Iteration, status: str, reason: str, start_s: float, end_s: float
    ) -> list[Effect]:
        """The action started for ``iteration`` ended (only action nodes run actions)."""
        return []

    def telemetry(self, drone: str, values: PropertyValues) -> list[Effect]:
        """New property values of ``drone`` (only condition nodes watch telemetry)."""
        return []

    def release(self, iteration: Iteration) -> list[Effect]:
        """A Do's body ended (only Do begin nodes care)."""
        return []

    def interrupt(self, interrupt: Interrupt) -> list[Effect]:
        """A structure around this node interrupts its body for one of its activations."""
        if interrupt.scope not in self.spec.scopes:
            return []
        if interrupt.mode in ("suspend", "resume"):
            # A Whenever's Handler runs (or ended): only running actions care.
            self._hold(interrupt.scope, interrupt.iteration, interrupt.mode == "suspend")
            return self._take()
        if interrupt.mode != "all" and not self.interrupted_by_waits:
            return []
        self.interrupts.add((interrupt.scope, interrupt.iteration))
        self._note(
            "info",
            "mission.node.interrupted",
            scope=interrupt.scope,
            iteration=list(interrupt.iteration),
            mode=interrupt.mode,
        )
        self._interrupt_within(interrupt.iteration)
        return self._take()

    def peer_lost(self, sources: frozenset[str]) -> list[Effect]:
        """The drone hosting the nodes ``sources`` (keys) is lost for good.

        Inside a Try's Body the arcs this node still waits for from them are
        completed as ``failed`` (the Try catches it: see :mod:`.handlers`) and
        the Try's Body is interrupted on all its drones, as for a failed action.
        Outside a Try nothing changes (empty list): the drone's end policy
        applies.  Only activations outside loops (or already partly triggered)
        are known here.
        """
        spec = self.spec
        if spec.catch is None or self.aborted:
            return []
        waits = {act: missing for (group, act), missing in self.pre.waiting().items()}
        if not spec.loops and () not in waits and not self.pre.has_fired("entry", ()):
            waits[()] = self.pre.entry
        caught = False
        for act, missing in waits.items():
            for src in sorted(missing & sources):
                caught = True
                fired = self.pre.receive(src, act, "failed")
                if fired is not None:
                    self._fired(fired)
        if caught:
            self._note("warning", "mission.try.peer_lost", sources=sorted(sources))
            act = next(iter(waits))
            self._fx.append(
                Broadcast(Interrupt(spec.catch, act[: spec.catch_loops], "all"), spec.catch_drones)
            )
        return self._take()

    def abort(self) -> list[Effect]:
        """Stop: no more actions, no more triggers (actions still report their record)."""
        self.aborted = True
        self._on_abort()
        self._note("warning", "mission.node.aborted")
        return self._take()

    # -- transitions subclasses refine ----------------------------------------------

    def _fired(self, fired: Fired) -> None:
        if self.aborted:
            return
        if fired.group == "loop":
            self._body_done(fired)
            return
        act = fired.activation
        self._note(
            "info",
            "mission.node.triggered",
            iteration=list(act),
            status=fired.status,
            preconditions=dict(sorted(fired.statuses.items())),
        )
        self._activate(act, fired)

    def _activate(self, act: Iteration, fired: Fired) -> None:
        status = fired.status
        if status == "done" and self._interrupted(act):
            status = "skipped"
        if status != "done":
            self._pass_on(act, status)
        else:
            self._start(act)

    def _pass_on(self, act: Iteration, status: Status) -> None:
        """Dead-path elimination: hand a ``skipped``/``failed`` on without running."""
        self._emit(act, lambda r: status)
        self._resolved(act, status)

    def _start(self, act: Iteration) -> None:
        """Run the node for this activation (all predecessors done, not interrupted)."""
        self._emit(act, lambda r: "done")
        self._resolved(act, "done")

    def _body_done(self, fired: Fired) -> None:
        """A loop body's back arcs completed (only loop begin nodes have them)."""

    def _interrupt_within(self, scope_iteration: Iteration) -> None:
        """Stop what runs inside the interrupted activation (nothing, for a pass-through)."""

    def _on_abort(self) -> None:
        """Drop what waits (nothing, for a pass-through)."""

    def _hold(self, scope: int, scope_iteration: Iteration, suspend: bool) -> None:
        """A Whenever around the node suspends (or resumes) its drone: only actions care."""

    # -- helpers ---------------------------------------------------------------------

    def _take(self) -> list[Effect]:
        out, self._fx = self._fx, []
        return out

    def _interrupted(self, act: Iteration) -> bool:
        # Tested first: on every activation, and almost always empty.
        return bool(self.interrupts) and any(within(act, it) for _, it in self.interrupts)

    def _emit(
        self,
        act: Iteration,
        status_for: Callable[[Route], Status | None],
        body_iteration: Iteration | None = None,
    ) -> None:
        for route in self.routes:
            status = status_for(route)
            if status is None:
                continue
            iteration = (
                body_iteration if (route.kind == "body" and body_iteration is not None) else act
            )
            self._fx.append(Emit(route, iteration, status))

    def _resolved(self, act: Iteration, status: Status) -> None:
        if status == "failed" and self.spec.catch is not None:
            # Inside a Try's Body a failure is caught by the Try's end (which hands on
            # the failure itself if the Try was blocked from outside): not a blocked node.
            status = "skipped"
        self._fx.append(Resolve(act, status, not self.spec.loops and act == ()))

    def _event(self, act: Iteration, state: str, detail: str = "") -> None:
        if not self.quiet:
            self._fx.append(Progress(NodeEvent(self.key, state, self.spec.label, act, detail)))

    def _note(self, level: str, event: str, **fields: Any) -> None:
        if not self.quiet and (self.debug_notes or level != "debug"):
            self._fx.append(Note(level, event, fields))


class PassThrough(NodeLogic):
    """The initial node, forks and joins (``init``, ``fork``, ``end``): trigger on."""
