"""When a MAVLink vehicle is at rest, and when a move has arrived: the settle window.

:class:`Settling` judges one vehicle's LOCAL_POSITION_NED over the settle window (its
mean position and speed): at rest (a brake's end), or arrived within a move's tolerance
(:mod:`eamos.hal.mavlink.completion`, which says what the tolerance of a move is), and
logs what completed each move (``adapter.arrived``).  Methods that take a
:class:`~eamos.hal.mavlink.state.LinkState` run with the vehicle's condition held.
"""

from __future__ import annotations

import threading
import time
from typing import TYPE_CHECKING, Protocol

from eamos.hal.mavlink.completion import Arrival
from eamos.hal.mavlink.frames import NedOrigin, Vector, ned_to_mission
from eamos.hal.mavlink.state import LinkState

if TYPE_CHECKING:
    from eamos.hal.mavlink.autopilots import Autopilot
    from eamos.hal.mavlink.settings import MavlinkSettings
    from eamos.logs import EventLog


class SettlingOwner(Protocol):
    """What :class:`Settling` reads of its vehicle (:class:`~eamos.hal.mavlink.vehicle.
    MavlinkVehicle`)."""

    settings: MavlinkSettings
    autopilot: Autopilot
    origin: NedOrigin | None
    cond: threading.Condition
    log: EventLog


class Settling:
    """One vehicle's settle window: at rest, arrived (see module docstring)."""

    def __init__(self, vehicle: SettlingOwner) -> None:
        self.v = vehicle
        #: The window that completed the last move (condition held), for log_arrival.
        self._arrived_window: tuple[Vector, float] | None = None

    @property
    def tolerance_m(self) -> float:
        """Completion tolerance of a long move: the settings', else the autopilot's."""
        return self.v.settings.tolerance_m or self.v.autopilot.tolerance_m

    @property
    def settle_speed_mps(self) -> float:
        """Settle speed: the settings', else the autopilot's."""
        return self.v.settings.settle_speed_mps or self.v.autopilot.settle_speed_mps

    @property
    def settle_s(self) -> float:
        """Settle window (vehicle seconds): the settings', else the autopilot's."""
        s = self.v.settings.settle_s
        return self.v.autopilot.settle_s if s is None else s

    def arrival(
        self, start: Vector, target: Vector, since: float, vertical: bool = False
    ) -> Arrival:
        """What "arrived" means for a move from ``start`` to ``target`` commanded at ``since``
        (:mod:`eamos.hal.mavlink.completion`: the tolerance scaled for short moves)."""
        floor = min(self.tolerance_m, self.v.autopilot.min_tolerance_m)
        return Arrival.of_move(start, target, self.tolerance_m, since, vertical, floor)

    def window(
        self, st: LinkState, now: float, since: float | None = None
    ) -> tuple[Vector, float] | None:
        """Mean mission position and speed over the settle window ending ``now``, or None
        until LOCAL_POSITION_NED has been heard for the whole window (a single sample of
        a wandering estimate proves nothing), or while the window reaches back before
        ``since``."""
        span = self.v.settings.scaled(self.settle_s)
        if since is not None and now - span < since:
            return None
        seen = st.window(now, span)
        if seen is None or st.local is None:
            return None
        origin = self.v.origin or NedOrigin(st.local[0], st.local[1], st.local[2])
        return ned_to_mission(seen[0], origin), seen[1]

    def settled(self, st: LinkState) -> bool:
        """At rest over the settle window."""
        seen = self.window(st, time.monotonic())
        return seen is not None and seen[1] <= self.settle_speed_mps

    def arrived(self, st: LinkState, arrival: Arrival) -> bool:
        """Within ``arrival``'s tolerance of its target and slow, over a settle window
        that lies wholly after the command."""
        seen = self.window(st, time.monotonic(), arrival.since)
        if seen is None or not arrival.reached(seen[0], seen[1], self.settle_speed_mps):
            return False
        self._arrived_window = seen  # what completed it, for log_arrival
        return True

    def log_arrival(self, action: str, arrival: Arrival) -> None:
        """``adapter.arrived``: the settle window's mean position, its error and the
        tolerance it met (what completed the move)."""
        with self.v.cond:
            seen, self._arrived_window = self._arrived_window, None
        if seen is None:
            return
        mean, speed = seen
        self.v.log.info(
            "adapter.arrived",
            action=action,
            target=[round(c, 3) for c in arrival.target],
            mean=[round(c, 3) for c in mean],
            error_m=round(arrival.error_m(mean), 3),
            tolerance_m=round(arrival.tolerance_m, 3),
            speed_mps=round(speed, 3),
        )


__all__ = ["Settling", "SettlingOwner"]
