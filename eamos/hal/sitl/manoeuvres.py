"""The simulated vehicle's heading, return to launch and orbits, as each autopilot flies them.

What the MAVLink adapter's ReturnHome, Yaw, SetSpeed and Orbit use, and how the
real autopilots answer (docs/flying-real-drones.md):

* Heading: the vehicle turns at :data:`YAW_RATE_DPS` towards a target heading;
  ATTITUDE.yaw reports it.  PX4 takes the yaw of an OFFBOARD setpoint
  (SET_POSITION_TARGET_LOCAL_NED without the yaw-ignore bit); ArduCopter takes
  MAV_CMD_CONDITION_YAW in GUIDED (param1 degrees, param3 direction, param4 relative).
* Return to launch (MAV_CMD_NAV_RETURN_TO_LAUNCH or the mode): climb to the
  return altitude if lower (PX4 RTL_RETURN_ALT in m, ArduCopter RTL_ALT in cm),
  fly over the boot point, then land there (and disarm after touchdown).
* Orbit: PX4 MAV_CMD_DO_ORBIT (param1 radius, positive clockwise; param2 speed;
  x/y the centre) in its Orbit mode; ArduCopter CIRCLE mode, whose centre is
  CIRCLE_RADIUS (cm) ahead of the nose when the mode is entered, at CIRCLE_RATE
  (deg/s, positive clockwise).  The nose points at the centre meanwhile.
* ArduCopter's MAV_CMD_DO_CHANGE_SPEED (param2 m/s) holds until the next mode change.

:class:`Manoeuvres` holds that state for one :class:`~eamos.hal.sitl.core.VehicleCore`
and is stepped by it; nothing here owns a thread or a clock.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol

from eamos.hal.kinematics import Quadcopter

if TYPE_CHECKING:
    from eamos.logs import EventLog


class VehicleCore(Protocol):
    """What manoeuvres need of :class:`eamos.hal.sitl.core.VehicleCore`."""

    model: Quadcopter
    t: float
    log: EventLog

    def steer(self, x: float, y: float, z: float) -> None:
        """A new position target."""
        ...

    def text(self, text: str, severity: int = ...) -> None:
        """STATUSTEXT."""
        ...


#: How fast the simulated vehicle turns (deg/s): ArduCopter's and PX4's yaw rate limits
#: are higher, but their default yaw acceleration makes a turn take about this long.
YAW_RATE_DPS = 60.0
#: Within this horizontal distance (m) and speed (m/s) of the point over home, RTL descends.
RTL_ARRIVED_M = 0.3
RTL_ARRIVED_MPS = 0.3
#: The orbit's carrot leads the vehicle by this much time (s) along the circle.
ORBIT_LEAD_S = 0.5


def wrap_deg(angle: float) -> float:
    """An angle in degrees as [0, 360)."""
    return angle % 360.0


def turn_towards(heading: float, target: float, max_step: float) -> float:
    """``heading`` turned the shortest way towards ``target`` by at most ``max_step`` (pure)."""
    error = (target - heading + 180.0) % 360.0 - 180.0
    if abs(error) <= max_step:
        return wrap_deg(target)
    return wrap_deg(heading + math.copysign(max_step, error))


@dataclass
class Orbit:
    """A circle being flown: centre (model x north, y east), radius, tangential speed."""

    cx: float
    cy: float
    radius_m: float
    speed_mps: float
    clockwise: bool = True


class Manoeuvres:
    """Heading, RTL and orbit state of one simulated vehicle (see module docstring)."""

    def __init__(self) -> None:
        self.heading_deg = 0.0
        self.yaw_target_deg: float | None = None
        self.orbit: Orbit | None = None
        self.rtl_height_m: float | None = None  # set while returning (before the descent)
        self.speed_override_mps: float | None = None  # ArduCopter DO_CHANGE_SPEED

    # -- orders ------------------------------------------------------------------------

    def yaw_to(self, heading_deg: float) -> None:
        """Turn to the compass heading ``heading_deg``."""
        self.yaw_target_deg = wrap_deg(heading_deg)

    def start_orbit(self, v: VehicleCore, orbit: Orbit) -> None:
        """Start circling ``orbit``."""
        self.orbit = orbit
        v.log.info(
            "vehicle.orbit",
            cx=round(orbit.cx, 2),
            cy=round(orbit.cy, 2),
            radius_m=orbit.radius_m,
            speed_mps=round(orbit.speed_mps, 2),
            t_sim=round(v.t, 3),
        )

    def orbit_ahead(self, v: VehicleCore, radius_m: float, speed_mps: float) -> Orbit:
        """An orbit whose centre is ``radius_m`` ahead of the nose (ArduCopter CIRCLE)."""
        x, y, _ = v.model.position
        h = math.radians(self.heading_deg)
        return Orbit(x + radius_m * math.cos(h), y + radius_m * math.sin(h), radius_m, speed_mps)

    def start_rtl(self, v: VehicleCore, return_alt_m: float) -> None:
        """Return to launch: over the boot point at max(current, return altitude), then land."""
        model = v.model
        if model.landed:
            return
        height = max(model.position[2], return_alt_m)
        self.rtl_height_m = height
        v.steer(0.0, 0.0, height)

    def mode_changed(self) -> None:
        """Any mode change ends an orbit, a return and ArduCopter's speed override."""
        self.orbit = None
        self.rtl_height_m = None
        self.speed_override_mps = None

    # -- each step -----------------------------------------------------------------------

    def step(self, v: VehicleCore, dt_s: float) -> None:
        """Advance the heading, the orbit's carrot and the return (before the model moves)."""
        model = v.model
        if self.orbit is not None and not model.landed:
            o = self.orbit
            x, y, z = model.position
            bearing = math.atan2(y - o.cy, x - o.cx)
            sign = 1.0 if o.clockwise else -1.0
            lead = sign * min(o.speed_mps * ORBIT_LEAD_S / o.radius_m, math.pi / 4)
            ahead = bearing + lead
            model.set_target(
                o.cx + o.radius_m * math.cos(ahead), o.cy + o.radius_m * math.sin(ahead), z
            )
            # The nose points at the centre.
            self.yaw_target_deg = wrap_deg(math.degrees(math.atan2(o.cy - y, o.cx - x)))
        if self.rtl_height_m is not None and not model.landed:
            x, y, _ = model.position
            st = model.state
            if math.hypot(x, y) <= RTL_ARRIVED_M and st.horizontal_speed_mps <= RTL_ARRIVED_MPS:
                self.rtl_height_m = None
                v.text("RTL: landing at home")
                v.steer(0.0, 0.0, 0.0)
        if self.yaw_target_deg is not None and model.armed and not model.landed:
            self.heading_deg = turn_towards(
                self.heading_deg, self.yaw_target_deg, YAW_RATE_DPS * dt_s
            )


__all__ = ["YAW_RATE_DPS", "Manoeuvres", "Orbit", "turn_towards", "wrap_deg"]
