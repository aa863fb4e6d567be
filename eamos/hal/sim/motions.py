"""The simulated vehicle's rules and its guided motions (pure: no thread, no clock).

Split from :mod:`eamos.hal.sim.core`.  :func:`refusal` says why the vehicle
refuses a command now.  The guided motions move the kinematic model's setpoint
a little every step instead of setting it once:

* ``Orbit(radius_m, turns)``: the centre is ``radius_m`` ahead along the heading; a
  setpoint runs clockwise (seen from above: north, east, south, west) around it at the
  orbit speed (the cruise speed, lowered so the centripetal acceleration stays within
  half the model's acceleration limit), the vehicle facing the centre; after ``turns``
  turns the setpoint stops (whole turns: exactly where the orbit started; a fractional
  last turn: where it ends on the circle, never flying across it), and the action
  completes there like any move (within ``tolerance_m`` and settled).
* ``Yaw(heading_deg)``: the heading turns the shorter way at :data:`YAW_RATE_DEG_S`.
* ``ReturnHome``: a move to above home at the current height, then a landing.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from eamos.hal.kinematics import Quadcopter
from eamos.hal.sim.settings import SimSettings
from eamos.program.uniform import (
    Command,
    Disarm,
    Hold,
    Land,
    Orbit,
    PauseFor,
    Payload,
    SetSpeed,
    Takeoff,
)

#: How fast the simulated vehicle turns on the spot (degrees per second).
YAW_RATE_DEG_S = 90.0
#: The share of the acceleration limit an orbit's centripetal acceleration may use.
ORBIT_ACCEL_SHARE = 0.5


def refusal(
    command: Command, settings: SimSettings, model: Quadcopter, busy: bool, aborting: bool
) -> str | None:
    """Why the vehicle refuses ``command`` now (its rules), or None.

    ``busy``: a motion action runs (one at a time); ``aborting``: an abort
    is landing the vehicle.
    """
    if command.action in settings.reject_actions:
        return "rejected by vehicle"
    if aborting and not isinstance(command, Payload | PauseFor):
        return "aborting"
    if isinstance(command, PauseFor | Hold) and command.duration_s < 0:
        return "duration_s must be >= 0"
    if isinstance(command, SetSpeed) and not command.speed_m_s > 0:
        return "speed_m_s must be > 0"
    if isinstance(command, Hold):
        # Hold mode hovers: only in the air, and it would stop a running move.
        if model.landed:
            return "not flying"
        if busy:
            return "busy"
    if isinstance(command, Disarm) and model.armed:
        if not model.landed:
            return "in the air"
        if busy:
            return "busy"  # e.g. a Takeoff about to lift off
    if not command.moves:
        return None
    if busy:
        return "busy"  # one motion action at a time
    if isinstance(command, Orbit) and not (command.radius_m > 0 and command.turns > 0):
        return "radius_m and turns must be > 0"
    if isinstance(command, Takeoff):
        if command.height_m <= 0:
            return "height_m must be > 0"
        if not model.armed:
            return "not armed"
    elif not isinstance(command, Land) and model.landed:
        return "not flying"
    return None


def turn_towards(heading_deg: float, target_deg: float, max_step_deg: float) -> float:
    """``heading_deg`` turned the shorter way towards ``target_deg`` by at most ``max_step_deg``.

    Headings are compass degrees in [0, 360); the result arrives exactly on the target.
    """
    target = target_deg % 360.0
    delta = (target - heading_deg + 180.0) % 360.0 - 180.0
    if abs(delta) <= max_step_deg:
        return target
    return (heading_deg + math.copysign(max_step_deg, delta)) % 360.0


def orbit_speed_mps(cruise_mps: float, accel_mps2: float, radius_m: float) -> float:
    """The speed an orbit of ``radius_m`` is flown at: cruise, or slower on a tight circle."""
    return min(cruise_mps, math.sqrt(ORBIT_ACCEL_SHARE * accel_mps2 * radius_m))


@dataclass
class OrbitGuide:
    """The moving setpoint of one orbit (see module doc); bearings in radians from north."""

    centre_x_m: float
    centre_y_m: float
    z_m: float
    radius_m: float
    start_rad: float  # the bearing from the centre to the start point
    total_rad: float  # 2 pi * turns
    rate_rad_s: float
    swept_rad: float = 0.0

    @classmethod
    def start(
        cls,
        position: tuple[float, float, float],
        heading_deg: float,
        command: Orbit,
        speed_mps: float,
    ) -> OrbitGuide:
        """The orbit ``command`` flown from ``position`` facing ``heading_deg``."""
        x, y, z = position
        h = math.radians(heading_deg)
        r = command.radius_m
        return cls(
            centre_x_m=x + r * math.cos(h),
            centre_y_m=y + r * math.sin(h),
            z_m=z,
            radius_m=r,
            start_rad=h + math.pi,
            total_rad=2.0 * math.pi * command.turns,
            rate_rad_s=speed_mps / r,
        )

    @property
    def finished(self) -> bool:
        """True once the setpoint has swept every turn (it then rests on the start point)."""
        return self.swept_rad >= self.total_rad

    @property
    def duration_s(self) -> float:
        """How long the setpoint takes to sweep the orbit."""
        return self.total_rad / self.rate_rad_s

    def point(self, swept_rad: float) -> tuple[float, float, float]:
        """The point on the circle ``swept_rad`` clockwise from the start."""
        bearing = self.start_rad + min(swept_rad, self.total_rad)
        return (
            self.centre_x_m + self.radius_m * math.cos(bearing),
            self.centre_y_m + self.radius_m * math.sin(bearing),
            self.z_m,
        )

    def advance(self, dt_s: float) -> tuple[float, float, float]:
        """Move the setpoint on by ``dt_s``; the new setpoint."""
        self.swept_rad = min(self.total_rad, self.swept_rad + self.rate_rad_s * dt_s)
        return self.point(self.swept_rad)

    def heading_deg(self) -> float:
        """The heading facing the centre from the setpoint."""
        return math.degrees(self.start_rad + self.swept_rad + math.pi) % 360.0


__all__ = [
    "ORBIT_ACCEL_SHARE",
    "YAW_RATE_DEG_S",
    "OrbitGuide",
    "orbit_speed_mps",
    "refusal",
    "turn_towards",
]
