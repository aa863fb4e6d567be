"""The simulator's scripted pilot: a hand-flown drone stands in as a waypoint list.

Split from :mod:`eamos.hal.sim.core` (see :mod:`eamos.hal.sim.adapter` for its rules).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Literal

from eamos.hal.kinematics import Quadcopter
from eamos.hal.sim.settings import SimSettings, Waypoint
from eamos.hal.sim.telemetry import EPS_S

if TYPE_CHECKING:
    from eamos.logs import EventLog


class ScriptedPilot:
    """The scripted pilot: flies its waypoints in order, holding at each (a hand-flown drone)."""

    def __init__(self, path: tuple[Waypoint, ...], settings: SimSettings, log: EventLog) -> None:
        self._path = path
        self._settings = settings
        self._log = log
        self.state: Literal["idle", "flying", "done"] = "idle" if path else "done"
        self._index = 0
        self._hold_until: float | None = None

    @property
    def flying(self) -> bool:
        """True while the pilot has the controls."""
        return self.state == "flying"

    def take_off(self, model: Quadcopter) -> None:
        """The mission's Takeoff completed: the pilot takes the controls (once)."""
        if self.state != "idle" or model.landed:
            return
        self.state = "flying"
        self._index = 0
        self._hold_until = None
        self._log.info("adapter.pilot.start", waypoints=len(self._path))
        self._fly_to(model, self._path[0])

    def abort(self) -> None:
        """Abort takes the controls back at once."""
        if self.state == "flying":
            self._log.info("adapter.pilot.end", reason="aborted")
        self.state = "done"

    def update(self, t_s: float, model: Quadcopter) -> bool:
        """After a step at ``t_s``; True when the path has just ended."""
        if self.state != "flying":
            return False
        s = self._settings
        wp = self._path[self._index]
        if self._hold_until is None:
            if model.at_target(s.tolerance_m, s.settle_speed_mps):
                self._hold_until = t_s + wp.hold_s
                x, y, z = model.position
                self._log.info(
                    "adapter.pilot.waypoint",
                    index=self._index,
                    x_m=round(x, 3),
                    y_m=round(y, 3),
                    z_m=round(z, 3),
                    t_sim=round(t_s, 3),
                )
            return False
        if t_s < self._hold_until - EPS_S:
            return False
        self._index += 1
        self._hold_until = None
        if self._index < len(self._path):
            self._fly_to(model, self._path[self._index])
            return False
        self.state = "done"
        self._log.info("adapter.pilot.end", reason="path finished", t_sim=round(t_s, 3))
        return True

    @staticmethod
    def _fly_to(model: Quadcopter, wp: Waypoint) -> None:
        model.set_target(wp.x_m, wp.y_m, wp.z_m)


__all__ = ["ScriptedPilot"]
