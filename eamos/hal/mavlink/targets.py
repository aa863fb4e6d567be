"""What the adapter tells a vehicle to fly to: SET_POSITION_TARGET_* messages.

A local NED position (PX4 OFFBOARD setpoints, ArduPilot GUIDED targets) and a WGS84
position at a height above home (ArduPilot FlyToLLA), both with the heading the
vehicle holds once a Yaw set one (else yaw ignored, so the vehicle keeps its own);
and a point of a path with its velocity and heading (Orbit, :class:`CirclePath`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

from eamos.hal.mavlink.frames import Vector

if TYPE_CHECKING:
    from eamos.hal.mavlink.link import MavlinkLink

MAV_FRAME_LOCAL_NED = 1
MAV_FRAME_GLOBAL_RELATIVE_ALT_INT = 6
#: SET_POSITION_TARGET_* type_mask: use the position only (ignore velocity,
#: acceleration, yaw and yaw rate), so the vehicle keeps its heading.
TYPE_MASK_POSITION = 0x0FF8
#: The "ignore yaw" bit of the type_mask.
TYPE_MASK_YAW_IGNORE = 0x0400
#: Position, velocity (feed-forward) and yaw; acceleration and yaw rate ignored: a path.
TYPE_MASK_PATH = 0x09C0

#: What the vehicle is told to go to: ("local", NED point) or ("global", (lat, lon, rel alt)).
GuidedTarget = tuple[str, Vector]


def send_position(link: MavlinkLink, target: Vector, yaw_deg: float | None = None) -> None:
    """SET_POSITION_TARGET_LOCAL_NED, position only (and the compass heading ``yaw_deg``
    if given: PX4 turns to an OFFBOARD setpoint's yaw), MAV_FRAME_LOCAL_NED."""
    system, component = link.target
    mask, yaw = TYPE_MASK_POSITION, 0.0
    if yaw_deg is not None:
        mask &= ~TYPE_MASK_YAW_IGNORE
        yaw = math.remainder(math.radians(yaw_deg), 2 * math.pi)
    link.send(
        "set_position_target_local_ned",
        link.time_boot_ms(),
        system,
        component,
        MAV_FRAME_LOCAL_NED,
        mask,
        target[0],
        target[1],
        target[2],
        *(0.0,) * 6,
        yaw,
        0.0,
    )


def send_global(link: MavlinkLink, point: Vector, yaw_deg: float | None = None) -> None:
    """SET_POSITION_TARGET_GLOBAL_INT (lat, lon in degrees, altitude above home; and the
    compass heading ``yaw_deg`` if given)."""
    system, component = link.target
    lat, lon, alt = point
    mask, yaw = TYPE_MASK_POSITION, 0.0
    if yaw_deg is not None:
        mask &= ~TYPE_MASK_YAW_IGNORE
        yaw = math.remainder(math.radians(yaw_deg), 2 * math.pi)
    link.send(
        "set_position_target_global_int",
        link.time_boot_ms(),
        system,
        component,
        MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
        mask,
        round(lat * 1e7),
        round(lon * 1e7),
        alt,
        *(0.0,) * 6,
        yaw,
        0.0,
    )


def send_path(link: MavlinkLink, position: Vector, velocity: Vector, yaw_deg: float) -> None:
    """SET_POSITION_TARGET_LOCAL_NED: a point of a path, with its velocity (feed-forward)
    and heading (both autopilots follow it in GUIDED / OFFBOARD)."""
    system, component = link.target
    link.send(
        "set_position_target_local_ned",
        link.time_boot_ms(),
        system,
        component,
        MAV_FRAME_LOCAL_NED,
        TYPE_MASK_PATH,
        *position,
        *velocity,
        0.0,
        0.0,
        0.0,
        math.remainder(math.radians(yaw_deg), 2 * math.pi),
        0.0,
    )


#: How far ahead of the vehicle (round the circle) a path's target runs: at most this
#: many metres, and never more than an eighth of a turn.
PATH_LEAD_M = 1.0


@dataclass(frozen=True)
class CirclePath:
    """A target going clockwise (seen from above) round a circle just ahead of the
    vehicle, the nose to the centre, until it has gone round ``angle_rad`` (NED, metres;
    pure).

    The target leads the vehicle by :data:`PATH_LEAD_M` along the circle, from the angle
    the vehicle has flown so far, not from the clock: a vehicle slower than the path
    (PX4 SIH flew 1.0 of the 1.5 m/s asked) would otherwise be left behind and cut
    straight back to the end.  Its velocity (feed-forward) is tangent at ``speed_mps``.
    Orbit streams it on both autopilots in GUIDED / OFFBOARD: ArduCopter's CIRCLE mode
    (like LOITER) takes its climb rate from the RC throttle and descends into the ground
    without a transmitter (the notes).
    """

    centre_n: float
    centre_e: float
    down: float
    radius_m: float
    speed_mps: float
    #: Bearing (radians, from north towards east) of the start, seen from the centre.
    start_bearing: float
    #: How far round to go (radians).
    angle_rad: float

    def at(self, flown_rad: float) -> tuple[Vector, Vector, float]:
        """(position, velocity, heading in degrees) of the target once the vehicle has
        flown ``flown_rad`` round the centre."""
        lead = min(PATH_LEAD_M / self.radius_m, math.pi / 4)
        ahead = min(self.angle_rad, max(0.0, flown_rad) + lead)
        bearing = self.start_bearing + ahead
        n = self.centre_n + self.radius_m * math.cos(bearing)
        e = self.centre_e + self.radius_m * math.sin(bearing)
        speed = self.speed_mps if ahead < self.angle_rad else 0.0
        velocity = (-speed * math.sin(bearing), speed * math.cos(bearing), 0.0)
        heading = math.degrees(math.atan2(self.centre_e - e, self.centre_n - n)) % 360.0
        return (n, e, self.down), velocity, heading


__all__ = [
    "MAV_FRAME_LOCAL_NED",
    "PATH_LEAD_M",
    "TYPE_MASK_PATH",
    "TYPE_MASK_POSITION",
    "CirclePath",
    "GuidedTarget",
    "send_global",
    "send_path",
    "send_position",
]
