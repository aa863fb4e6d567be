"""The seam for payload plugin actions on MAVLink (family ``"mavlink"``, docs/plugins.md).

A plugin action (:class:`~eamos.program.uniform.PluginAction`) whose plugin names a
``"mavlink"`` implementation ``"module:callable"`` is run by the adapter on the
action's own thread as::

    result = implementation(ctx, command)   # -> ActionResult

with a :class:`PayloadContext`.  The implementation returns the action's
:class:`~eamos.hal.api.ActionResult` (``ActionResult("ok")``), or raises
:class:`~eamos.hal.mavlink.waits.Failed` with a reason (a refused command raises
:class:`~eamos.hal.mavlink.autopilots.CommandRejected` by itself); the adapter
calls the mission's ``done`` exactly once either way, and a cancel, the link lost
or the adapter closed end the action early (every ``ctx`` call then raises).  It
must not keep threads of its own.  The project's camera and gimbal actions
(:mod:`eamos.hal.mavlink.camera`) are written against this seam.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, TypeVar

from eamos.hal.mavlink.control import RunControl
from eamos.hal.mavlink.frames import Vector
from eamos.hal.mavlink.link import LinkState
from eamos.hal.mavlink.vehicle import MavlinkVehicle
from eamos.hal.mavlink.waits import Run, Waiter

if TYPE_CHECKING:
    from eamos.logs import EventLog

T = TypeVar("T")


@dataclass(frozen=True)
class PayloadContext:
    """What a ``"mavlink"`` plugin implementation may do with the vehicle (module docstring)."""

    drone: str
    #: ``"px4"`` or ``"ardupilot"``.
    autopilot: str
    #: The adapter log (``log.info("adapter.<event>", **fields)``).
    log: EventLog
    _vehicle: MavlinkVehicle
    _control: RunControl
    _waiter: Waiter
    _run: Run

    def command(self, command: int, params: tuple[float, ...]) -> None:
        """COMMAND_LONG (7 params) to the autopilot; returns at MAV_RESULT_ACCEPTED, raises
        CommandRejected (with the vehicle's STATUSTEXT) or Failed (no COMMAND_ACK)."""
        self._control.command(command, params)

    def read(self, what: Callable[[LinkState], T]) -> T:
        """``what(state)`` evaluated on the vehicle's state as last heard (consistently)."""
        with self._vehicle.cond:
            return what(self._vehicle.state)

    def wait(self, until: Callable[[LinkState], bool], timeout_s: float, why: str) -> None:
        """Wait until ``until(state)`` (checked at every message); after ``timeout_s``
        seconds of vehicle time raise TimedOut(``why``)."""
        deadline = time.monotonic() + self._vehicle.settings.scaled(timeout_s)
        self._waiter.wait(self._run, until, deadline, lambda st: why)

    def position(self) -> Vector | None:
        """Where the vehicle is in the mission frame (x north, y east, z up), or None."""
        with self._vehicle.cond:
            if self._vehicle.state.local is None or self._vehicle.origin is None:
                return None
            return self._vehicle.mission_position()


def payload_context(vehicle: MavlinkVehicle, control: RunControl, run: Run) -> PayloadContext:
    """The context of one running plugin action."""
    return PayloadContext(
        vehicle.drone,
        vehicle.autopilot.name,
        vehicle.log,
        vehicle,
        control,
        control.waiter,
        run,
    )


__all__ = ["PayloadContext", "payload_context"]
