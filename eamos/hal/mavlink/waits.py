"""How the MAVLink adapter's flight procedures wait for the vehicle, and how they end.

:class:`Waiter`: every wait is ``Condition.wait_for`` on the vehicle's condition
against a ``time.monotonic()`` deadline, and ends early when the action is
finished by someone else (cancel, abort, close), when HEARTBEATs stop, or when a
guard sees that someone else took the vehicle over.  :class:`Run` is one running
action; :class:`Ended`, :class:`Failed` and :class:`TimedOut` say how it ends.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Literal

from eamos.hal.api import ActionHandle, DoneCallback
from eamos.hal.mavlink.link import LinkState
from eamos.program.uniform import Command

if TYPE_CHECKING:
    from eamos.hal.mavlink.vehicle import MavlinkVehicle


class Ended(Exception):
    """The action was already finished (cancelled, aborted, closed): just stop."""


class Failed(Exception):
    """The action fails with this reason."""


class TimedOut(Failed):
    """The action fails because its deadline passed (the vehicle should then hold)."""


RunKind = Literal["motion", "arm", "disarm", "timer", "internal"]


@dataclass(eq=False)
class Run:
    """One running action, or an internal job (hold, abort) that nobody finishes early."""

    handle: ActionHandle | None
    done: DoneCallback | None
    kind: RunKind
    started: float  # time.monotonic()
    command: Command | None = None  # None for internal jobs
    finished: bool = False  # set (condition held) by whoever finishes it


Check = Callable[[LinkState], bool]
Guard = Callable[[LinkState], str | None]


class Waiter:
    """How every flight step waits for the vehicle: on its condition, against a deadline.

    A wait ends early when the run is finished by someone else, the link
    closes, HEARTBEATs stop, or a guard sees that someone else took over.
    """

    def __init__(self, vehicle: MavlinkVehicle) -> None:
        self.v = vehicle
        self.s = vehicle.settings

    def wait(
        self,
        run: Run,
        until: Check,
        deadline: float,
        timeout_reason: Callable[[LinkState], str],
        *,
        guard: Guard | None = None,
        quiet_timeout: bool = False,
        watch_link: bool = True,
    ) -> None:
        """Wait on the condition until ``until(state)``; raise why not.

        Ends early (raising) when the run is finished by someone else, the
        link closes, HEARTBEATs stop (``watch_link``) or ``guard`` names a
        problem.  At ``deadline`` it raises ``TimedOut(timeout_reason(state))``,
        or returns quietly with ``quiet_timeout`` (a plain timer).
        """
        v, st = self.v, self.v.state
        # ``until`` and ``guard`` may read the clock (a settle window ends "now"): what
        # they said when the wait ended is the answer, not a second look a moment later
        # (a window that had arrived could slide off its target and read as a timeout).
        met = False
        problem: str | None = None

        def ready() -> bool:
            nonlocal met, problem
            if run.finished or st.closed or (watch_link and not st.link_ok):
                return True
            met = until(st)
            problem = None if met or guard is None else guard(st)
            return met or problem is not None

        with v.cond:
            v.cond.wait_for(ready, timeout=max(0.0, deadline - time.monotonic()))
            self.raise_if_over(run, watch_link=watch_link)
            if met:
                return
            if problem is not None:
                raise Failed(problem)
            if quiet_timeout:
                return
            raise TimedOut(timeout_reason(st))

    def raise_if_over(self, run: Run, watch_link: bool = True) -> None:
        """Raise if ``run`` must stop (condition held)."""
        if run.finished:
            raise Ended
        if self.v.taken_over is not None:
            raise Failed(self.v.taken_over.reason())  # a pilot has it: never command it again
        if self.v.state.closed:
            raise Failed("adapter closed")
        if watch_link and not self.v.state.link_ok:
            raise Failed(self.v.lost_reason())

    def settle_mode(self, run: Run) -> None:
        """Before commanding: wait until a mode change nobody explained yet is classified
        (a failsafe's STATUSTEXT may trail it; takeover.py), then raise if a pilot has it."""
        watch = self.v.takeover
        self.wait(
            run,
            lambda st: watch.pending is None,
            time.monotonic() + watch.grace_s + 1.0,
            lambda st: "",
            quiet_timeout=True,
        )

    def confirm_modes(self, run: Run, modes: frozenset[str], done: Check) -> None:
        """Wait until a HEARTBEAT shows one of ``modes`` (or ``done``): acks run ahead of it."""
        v = self.v
        self.wait(
            run,
            lambda st: v.mode_name(st) in modes or done(st),
            time.monotonic() + self.confirm_s(),
            lambda st: (
                f"vehicle is in mode {v.mode_name(st)}, expected {' or '.join(sorted(modes))}"
            ),
        )

    def guard(
        self, modes: frozenset[str], need_armed: bool = True, unless: Check | None = None
    ) -> Guard:
        """A check that nobody else took the vehicle over mid-action (a reason, or None)."""
        v, grace = self.v, self.s.heartbeat_timeout_s

        def check(st: LinkState) -> str | None:
            if unless is not None and unless(st):
                return None
            text = f" ({st.last_statustext})" if st.last_statustext else ""
            if need_armed and not st.armed:
                return f"vehicle disarmed{text}"
            mode = v.mode_name(st)
            if mode not in modes:
                watch = v.takeover
                if v.taken_over is not None:
                    return v.taken_over.reason()
                if watch.pending is not None:
                    return None  # whose change it is will be known within the grace
                # PX4 leaves OFFBOARD when setpoints stop for a second and comes
                # back when they resume: tolerate that after a gap or failsafe.
                if time.monotonic() < max(st.gap_ended_at, st.failsafe_at) + grace:
                    return None
                failsafe = watch.failsafe
                if failsafe is not None and failsafe.mode == mode:
                    return f"failsafe: {failsafe.why} (mode {mode})"
                return f"vehicle switched to mode {mode} under us{text}"
            return None

        return check

    def timeout_reason(self, what: str) -> Callable[[LinkState], str]:
        """The failure reason of an action that ran past ``action_timeout_s``."""
        t = self.s.action_timeout_s
        return lambda st: f"timeout after {t:g} s: {what}"

    def confirm_s(self) -> float:
        """How long a HEARTBEAT may take to confirm an acknowledged change: as long as the
        command's retries, and never less than a HEARTBEAT may be missing before the link
        counts as lost (``heartbeat_timeout_s``)."""
        s = self.s
        return max(2.5, s.command_timeout_s * s.command_retries, s.heartbeat_timeout_s)


__all__ = ["Check", "Ended", "Failed", "Guard", "Run", "RunKind", "TimedOut", "Waiter"]
