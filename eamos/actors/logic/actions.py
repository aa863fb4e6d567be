"""A node running one uniform action; its outcome decides what it hands on.

Inside a Try's Body (``spec.catch``) a failure is reported as *caught* and
interrupts the Body on every drone of it (see :mod:`.handlers`).  Inside the
statements a Whenever guards, on a drone its Handler uses
(``spec.suspendable``), a firing *suspends* the action: it is cancelled (the
drone holds), and re-issued when the Handler ended; an activation triggered
while suspended waits for the resume.  A relative move (``FlyByX/Y/Z``) is
re-issued for what is left of it: the node watches its own drone's position
while it runs, and the re-issued distance is the original target (position at
the start plus the distance) minus the position at the resume.  A Handler's
own action refused ``busy`` (it reached the vehicle before the cancel of the
suspended one) is re-issued at the drone's next telemetry push, at most
:data:`BUSY_RETRIES` times: event-driven, no timer.

A Try also catches a low battery: when the host sets :attr:`ActionLogic.battery_floor_pct`
(the fleet's ``[safety] battery_reserve_pct``), an action of a Try's Body watches its
own drone's battery while it runs; a sample below the floor cancels it (the drone
holds) and the action ends ``failed`` ("battery 18.2 % below the reserve of 20 %"),
which the Try catches like any other failure.  Outside a Try the floor changes
nothing: the pre-flight check reports a reserve breach, the mission decides with
its own conditions.
"""

from __future__ import annotations

from ...program.format import ProgramNode
from ..messages import ActionRecord, Interrupt
from ..state import Iteration, Status, within
from .base import NodeLogic
from .effects import (
    Broadcast,
    CancelAction,
    Effect,
    Record,
    Route,
    StartAction,
    UnwatchTelemetry,
    WatchTelemetry,
)
from .telemetry import PropertyValues

_RESULT_STATUS: dict[str, Status] = {"ok": "done", "failed": "failed", "cancelled": "skipped"}
#: Relative moves and the property their distance is measured on.
RELATIVE_AXES = {"FlyByX": "X", "FlyByY": "Y", "FlyByZ": "Z"}
#: How often a Handler's action refused ``busy`` is re-issued.
BUSY_RETRIES = 3
SUSPENDED = "suspended: a Whenever handler runs"


class ActionLogic(NodeLogic):
    """A node running one uniform action (see module docstring)."""

    def __init__(
        self,
        spec: ProgramNode,
        routes: tuple[Route, ...],
        entry: frozenset[str],
        loop: frozenset[str] = frozenset(),
    ) -> None:
        super().__init__(spec, routes, entry, loop)
        if spec.action is None:
            raise ValueError(f"action node {spec.key} has no action")
        self.action: str = spec.action
        self.running: dict[Iteration, None] = {}  # activations with an action out (ordered)
        self.issued: dict[Iteration, tuple[float, ...]] = {}  # the arguments sent
        # Whenever: holds in force, activations waiting for a resume, cancels for a suspend.
        self.held: set[tuple[int, Iteration]] = set()
        self.suspended: dict[Iteration, None] = {}
        self.suspending: set[Iteration] = set()
        self.axis = RELATIVE_AXES.get(self.action) if spec.suspendable else None
        self.origin: dict[Iteration, float] = {}  # the axis value when a relative move started
        self.position: PropertyValues = {}
        self.watching = False
        self.retries: dict[Iteration, int] = {}
        self.retry_at_next_sample: list[Iteration] = []
        #: Set by the host: a Try's Body action fails below this battery (percent).
        self.battery_floor_pct: float | None = None
        self.low_battery: dict[Iteration, str] = {}  # activations cancelled for the battery

    def _pass_on(self, act: Iteration, status: Status) -> None:
        self._emit(act, lambda r: status)
        # Inside a Try's Body a blocked node is part of the Body the failure cancels.
        blocked = status == "failed" and self.spec.catch is None
        self._event(act, "blocked" if blocked else "skipped")
        self._resolved(act, status)

    def _start(self, act: Iteration) -> None:
        if self.held and any(within(act, it) for _, it in self.held):
            self.suspended[act] = None
            self._event(act, "waiting", SUSPENDED)
            return
        if self.axis is not None:
            self.origin.pop(act, None)
            self._watch_own()
        self._issue(act, self.spec.args)

    def _issue(self, act: Iteration, args: tuple[float, ...]) -> None:
        self.running[act] = None
        self.issued[act] = args
        self._event(act, "running")
        self._fx.append(StartAction(act, self.action, args))
        if self._guards_battery():
            self._watch_own()

    def _guards_battery(self) -> bool:
        """True when a low battery is a failure of this action (inside a Try, floor set)."""
        return self.spec.catch is not None and self.battery_floor_pct is not None

    def action_finished(
        self, iteration: Iteration, status: str, reason: str, start_s: float, end_s: float
    ) -> list[Effect]:
        if iteration not in self.running:
            return []
        del self.running[iteration]
        low = self.low_battery.pop(iteration, None)
        if low is not None and status == "cancelled":
            status, reason = "failed", low
        args = self.issued.pop(iteration, self.spec.args)
        if iteration in self.suspending:
            self.suspending.discard(iteration)
            if status == "cancelled" and not self.aborted:
                self._record(iteration, args, start_s, end_s, "cancelled", SUSPENDED)
                self.suspended[iteration] = None
                self._event(iteration, "waiting", SUSPENDED)
                return self._take()
        if (
            status == "failed"
            and reason == "busy"
            and self.spec.in_handler
            and self.retries.get(iteration, 0) < BUSY_RETRIES
            and not self.aborted
        ):
            # It overtook the cancel of a suspended action: again at the next sample.
            self.retries[iteration] = self.retries.get(iteration, 0) + 1
            self.retry_at_next_sample.append(iteration)
            self.issued[iteration] = args
            self.running[iteration] = None
            self._watch_own()
            return self._take()
        self.retries.pop(iteration, None)
        result = status
        if status == "failed" and self.spec.catch is not None and not self.aborted:
            # Reported as caught, with the Try that catches it: not a failure of the run.
            result = "caught"
            where = (
                f"line {self.spec.catch_line}" if self.spec.catch_line else f"n{self.spec.catch}"
            )
            reason = f"{reason}; caught by the Try at {where}"
        self._record(iteration, args, start_s, end_s, result, reason)
        self.origin.pop(iteration, None)
        self._maybe_unwatch()
        if self.aborted:
            return self._take()
        outcome = _RESULT_STATUS[status]
        if status == "failed":
            self._note(
                "error",
                "mission.action.failed",
                action=self.action,
                reason=reason,
                iteration=list(iteration),
                **({"caught_by": self.spec.catch} if self.spec.catch is not None else {}),
            )
            if self.spec.catch is not None:
                self._catch(iteration)
        self._emit(iteration, lambda r: outcome)
        self._resolved(iteration, outcome)
        return self._take()

    def _record(
        self,
        act: Iteration,
        args: tuple[float, ...],
        start_s: float,
        end_s: float,
        result: str,
        reason: str,
    ) -> None:
        self._fx.append(
            Record(
                ActionRecord(
                    self.key, self.action, tuple(args), act, start_s, end_s, result, reason
                )
            )
        )

    def _catch(self, iteration: Iteration) -> None:
        """A failure inside a Try's Body: cancel the rest of Body on every drone of it.

        The ``failed`` this node hands on still flows to the Try's end (that is
        how the end knows Body failed: data, not a race with the interrupt);
        the interrupt makes the other drones' parts of Body stop at once.
        """
        spec = self.spec
        assert spec.catch is not None
        scope_iteration = iteration[: spec.catch_loops]
        self._fx.append(Broadcast(Interrupt(spec.catch, scope_iteration, "all"), spec.catch_drones))

    # -- Whenever: suspend and resume ------------------------------------------------

    def _hold(self, scope: int, scope_iteration: Iteration, suspend: bool) -> None:
        if suspend:
            self.held.add((scope, scope_iteration))
            for act in list(self.running):
                if within(act, scope_iteration) and act not in self.suspending:
                    self.suspending.add(act)
                    self._fx.append(CancelAction(act))
            return
        self.held.discard((scope, scope_iteration))
        for act in list(self.suspended):
            if within(act, scope_iteration) and not any(within(act, i) for _, i in self.held):
                del self.suspended[act]
                self._issue(act, self._remaining(act))

    def _remaining(self, act: Iteration) -> tuple[float, ...]:
        """The arguments to re-issue: a relative move's distance is what is left of it."""
        if self.axis is None:
            return self.spec.args
        origin = self.origin.get(act)
        now = self.position.get(self.axis)
        if origin is None or now is None:
            return self.spec.args  # never moved (it waited for the resume): all of it
        return (round(origin + self.spec.args[0] - float(now), 3),)

    def telemetry(self, drone: str, values: PropertyValues) -> list[Effect]:
        self.position = values
        here = values.get(self.axis) if self.axis is not None else None
        if here is not None:
            for act in self.running:
                self.origin.setdefault(act, float(here))
        if self._guards_battery():
            self._check_battery(values.get("Battery"))
        retry, self.retry_at_next_sample = self.retry_at_next_sample, []
        for act in retry:
            if act in self.running:
                self._fx.append(StartAction(act, self.action, self.issued[act]))
        self._maybe_unwatch()
        return self._take()

    def _check_battery(self, battery: float | bool | None) -> None:
        floor = self.battery_floor_pct
        if battery is None or floor is None or float(battery) >= floor:
            return
        for act in self.running:
            if act not in self.low_battery and act not in self.suspending:
                self.low_battery[act] = (
                    f"battery {float(battery):.1f} % below the reserve of {floor:g} %"
                )
                self._fx.append(CancelAction(act))

    def _watch_own(self) -> None:
        if not self.watching:
            self.watching = True
            self._fx.append(WatchTelemetry((self.spec.drone,)))

    def _maybe_unwatch(self) -> None:
        needed = self.retry_at_next_sample or (
            (self.axis is not None or self._guards_battery()) and self.running
        )
        if self.watching and not needed and not self.suspended:
            self.watching = False
            self._fx.append(UnwatchTelemetry())

    def _interrupt_within(self, scope_iteration: Iteration) -> None:
        for act in list(self.running):
            if within(act, scope_iteration):
                # Cancelled for good (a Do, a Try, an Abandon): no longer a suspension.
                self.suspending.discard(act)
                self._fx.append(CancelAction(act))
        for act in list(self.suspended):
            if within(act, scope_iteration):
                del self.suspended[act]
                self.origin.pop(act, None)
                self._event(act, "skipped")
                self._emit(act, lambda r: "skipped")
                self._resolved(act, "skipped")
        self._maybe_unwatch()
