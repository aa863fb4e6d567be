"""Setting the drone type's speeds on a vehicle, and putting the old values back.

:class:`ParamKeeper` carries out :func:`eamos.hal.mavlink.params.speed_plan`
over a :class:`~eamos.hal.mavlink.link.MavlinkLink` (the parameter protocol,
:mod:`~eamos.hal.mavlink.param_protocol`: PARAM_REQUEST_READ, then PARAM_SET
confirmed by the PARAM_VALUE echo), remembers what it found and
writes it back at :meth:`ParamKeeper.restore`.  Every step is logged; the
values are speeds, never secrets.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING

from eamos.hal.mavlink.param_protocol import ParamProtocol
from eamos.hal.mavlink.params import (
    MAV_PARAM_TYPE_REAL32,
    ParamChange,
    from_wire,
    speed_plan,
    to_wire,
)

if TYPE_CHECKING:
    from eamos.hal.mavlink.link import MavlinkLink
    from eamos.hal.mavlink.settings import MavlinkSettings
    from eamos.logs import EventLog


class ParamKeeper:
    """The parameters the adapter changed on one vehicle (see module docstring)."""

    def __init__(
        self,
        link: MavlinkLink,
        settings: MavlinkSettings,
        log: EventLog,
        blocked: Callable[[], bool] = lambda: False,
    ) -> None:
        self.link = link
        #: True once the adapter may no longer command the vehicle (a pilot took it):
        #: nothing is written then.
        self.blocked = blocked
        self.params = ParamProtocol(link)
        self.settings = settings
        self.log = log
        self.changes: list[ParamChange] = []
        self._bytewise = False  # PX4 carries integers byte-wise in the float

    def _exchange(
        self, name: str, value: float | None, param_type: int = MAV_PARAM_TYPE_REAL32
    ) -> ParamChange | None:
        """Read ``name`` (``value`` None) or set it; what the vehicle answers, or None."""
        s = self.settings
        if value is not None and self.blocked():
            return None  # a pilot has the vehicle: never written again
        write = None if value is None else (to_wire(value, param_type, self._bytewise), param_type)
        answer = self.params.request(
            name,
            write,
            timeout_s=s.command_timeout_s,
            retries=s.command_retries,
            abandon=lambda: not self.link.state.link_ok,
        )
        if answer is None:
            return None
        got = from_wire(answer[0], answer[1], self._bytewise)
        return ParamChange(name, got, got, answer[1])

    def apply_speeds(self, autopilot: str) -> None:
        """Set the drone type's speeds, remembering the old values.

        A parameter the vehicle does not answer for is logged and skipped: the
        vehicle then flies at its own speed for that axis.
        """
        s = self.settings
        self._bytewise = autopilot == "px4"
        if not s.set_speeds:
            self.log.info("adapter.param.speeds", applied=False, reason="hal.set_speeds = false")
            return
        plan = speed_plan(autopilot, s.horizontal_speed_mps, s.climb_speed_mps, s.descent_speed_mps)
        found: list[ParamChange] = []
        for name, value in plan:
            before = self._exchange(name, None)
            if before is None:
                self.log.warning(
                    "adapter.param.missing",
                    name=name,
                    note="no PARAM_VALUE: the vehicle keeps its own speed for this",
                )
                continue
            found.append(ParamChange(name, before.before, value, before.param_type))
        if self.blocked() or not found:
            return
        # Written as one burst, as restore() writes them back (ParamProtocol.set_all).
        answers = self.params.set_all(
            [(c.name, to_wire(c.after, c.param_type, self._bytewise), c.param_type) for c in found],
            timeout_s=s.command_timeout_s,
            retries=s.command_retries,
            abandon=lambda: not self.link.state.link_ok or self.blocked(),
        )
        for change in found:
            answer = answers.get(change.name)
            echoed = None if answer is None else from_wire(*answer, self._bytewise)
            if echoed is None or not math.isclose(echoed, change.after, rel_tol=1e-3, abs_tol=1e-3):
                self.log.warning(
                    "adapter.param.refused", name=change.name, value=change.after, echoed=echoed
                )
                if echoed is not None and not math.isclose(echoed, change.before, abs_tol=1e-3):
                    # The vehicle took another value (a clamp): it is still put back.
                    self.changes.append(
                        ParamChange(change.name, change.before, echoed, change.param_type)
                    )
                continue
            self.changes.append(change)
            self.log.info(
                "adapter.param.set", name=change.name, before=change.before, value=change.after
            )

    def set_param(self, name: str, value: float) -> bool:
        """Set one parameter for an action (ReturnHome's return altitude, Orbit's circle,
        SetSpeed), remembering the value found the first time so :meth:`restore` puts it
        back; False when the vehicle does not answer or refuses (logged)."""
        known = next((c for c in self.changes if c.name == name), None)
        if known is None:
            before = self._exchange(name, None)
            if before is None:
                self.log.warning("adapter.param.missing", name=name, note="no PARAM_VALUE")
                return False
            known = ParamChange(name, before.before, before.before, before.param_type)
        after = self._exchange(name, value, known.param_type)
        if after is None or not math.isclose(after.before, value, rel_tol=1e-3, abs_tol=1e-3):
            self.log.warning("adapter.param.refused", name=name, value=value)
            return False
        self.changes = [c for c in self.changes if c.name != name]
        self.changes.append(ParamChange(name, known.before, value, known.param_type))
        self.log.info("adapter.param.set", name=name, before=known.before, value=value)
        return True

    def restore(self) -> None:
        """Write back what the adapter found, as one burst in the order it set them (see
        :meth:`ParamProtocol.set_all` for why a burst), each confirmed by its echo; log
        each.

        In that order a limit comes back before what it limits: PX4 keeps MPC_XY_CRUISE
        at or below MPC_XY_VEL_MAX (it clamps the cruise speed by itself, after the
        echo), so putting the cruise speed back first left it clamped.  A value the
        vehicle echoes otherwise is written again after the others.
        """
        if not self.changes or self.blocked():
            return  # a pilot's vehicle keeps them; the adapter says which at close
        changes, self.changes = self.changes, []
        s = self.settings
        pending = list(changes)
        for attempt in range(2):
            answers = self.params.set_all(
                [
                    (c.name, to_wire(c.before, c.param_type, self._bytewise), c.param_type)
                    for c in pending
                ],
                timeout_s=s.command_timeout_s,
                retries=s.command_retries,
                abandon=lambda: not self.link.state.link_ok or self.blocked(),
            )
            again: list[ParamChange] = []
            for change in pending:
                answer = answers.get(change.name)
                echoed = None if answer is None else from_wire(*answer, self._bytewise)
                if echoed is None:
                    self.log.error(
                        "adapter.param.restore_failed", name=change.name, value=change.before
                    )
                elif not math.isclose(echoed, change.before, rel_tol=1e-3, abs_tol=1e-3):
                    if attempt == 0:
                        again.append(change)
                    else:
                        self.log.error(
                            "adapter.param.restore_failed",
                            name=change.name,
                            value=change.before,
                            echoed=echoed,
                        )
                else:
                    self.log.info("adapter.param.restore", name=change.name, value=change.before)
            pending = again
            if not pending:
                break


__all__ = ["ParamKeeper"]
