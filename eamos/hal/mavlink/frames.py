"""Conversions between the mission frame and a MAVLink vehicle's local NED frame.

The mission frame of the uniform API is X north, Y east, Z up, metres from
the drone's home.  Autopilots report LOCAL_POSITION_NED: x north, y east,
z *down*, from an origin of their own choosing (ArduPilot: the EKF origin,
about home; PX4 SIH: an origin whose z is not 0 on the ground).  The adapter
therefore records where home is in NED (:class:`NedOrigin`) and converts
every position and setpoint through the two pure functions below, so the
vehicle's own origin never leaks into a mission.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

Vector = tuple[float, float, float]


@dataclass(frozen=True)
class NedOrigin:
    """Where the mission frame's home is, in the vehicle's local NED frame (metres)."""

    north_m: float = 0.0
    east_m: float = 0.0
    down_m: float = 0.0

    def with_ground(self, down_m: float) -> NedOrigin:
        """The same horizontal home with a new ground height (NED down of the ground).

        Heights are measured from the ground where the vehicle stood before
        take-off: PX4's local z on the ground drifts between flights.
        """
        return replace(self, down_m=float(down_m))


def mission_to_ned(point: Vector, origin: NedOrigin) -> Vector:
    """Mission (x north, y east, z up from home) -> local NED (north, east, down)."""
    x, y, z = point
    return (origin.north_m + x, origin.east_m + y, origin.down_m - z)


def ned_to_mission(point: Vector, origin: NedOrigin) -> Vector:
    """Local NED (north, east, down) -> mission (x north, y east, z up from home)."""
    n, e, d = point
    # "+ 0.0" turns a negative zero into 0.0 for tidy telemetry.
    return (n - origin.north_m + 0.0, e - origin.east_m + 0.0, origin.down_m - d + 0.0)


def ned_velocity_to_mission(velocity: Vector) -> Vector:
    """NED velocity (vn, ve, vd) -> mission velocity (vx north, vy east, vz up)."""
    vn, ve, vd = velocity
    return (vn, ve, -vd + 0.0)


__all__ = [
    "NedOrigin",
    "Vector",
    "mission_to_ned",
    "ned_to_mission",
    "ned_velocity_to_mission",
]
