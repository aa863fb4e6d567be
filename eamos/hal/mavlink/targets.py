"""What the adapter tells a vehicle to fly to: SET_POSITION_TARGET_* messages.

Three kinds, all with yaw and acceleration ignored so the vehicle keeps its
heading: a local NED position (PX4 OFFBOARD setpoints, ArduPilot GUIDED
targets), a WGS84 position at a height above home (ArduPilot FlyToLLA), and a
zero velocity (velocity only): "stop now", PX4's fastest stop in OFFBOARD
(and a documented GUIDED stop on ArduCopter).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

from eamos.hal.mavlink.frames import Vector

if TYPE_CHECKING:
    from eamos.hal.mavlink.link import MavlinkLink

MAV_FRAME_LOCAL_NED = 1
MAV_FRAME_GLOBAL_RELATIVE_ALT_INT = 6
#: SET_POSITION_TARGET_* type_mask: use the position only (ignore velocity,
#: acceleration, yaw and yaw rate), so the vehicle keeps its heading.
TYPE_MASK_POSITION = 0x0FF8
#: ...and the velocity only (ignore position, acceleration, yaw, yaw rate): a stop.
TYPE_MASK_VELOCITY = 0x0DC7
#: The "ignore yaw" bit of the type_mask.
TYPE_MASK_YAW_IGNORE = 0x0400

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


def send_global(link: MavlinkLink, point: Vector) -> None:
    """SET_POSITION_TARGET_GLOBAL_INT (lat, lon in degrees, altitude above home)."""
    system, component = link.target
    lat, lon, alt = point
    link.send(
        "set_position_target_global_int",
        link.time_boot_ms(),
        system,
        component,
        MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
        TYPE_MASK_POSITION,
        round(lat * 1e7),
        round(lon * 1e7),
        alt,
        *(0.0,) * 8,
    )


def send_stop(link: MavlinkLink) -> None:
    """SET_POSITION_TARGET_LOCAL_NED with a zero velocity (velocity only): stop now."""
    system, component = link.target
    link.send(
        "set_position_target_local_ned",
        link.time_boot_ms(),
        system,
        component,
        MAV_FRAME_LOCAL_NED,
        TYPE_MASK_VELOCITY,
        *(0.0,) * 11,
    )


__all__ = [
    "MAV_FRAME_LOCAL_NED",
    "TYPE_MASK_POSITION",
    "TYPE_MASK_VELOCITY",
    "GuidedTarget",
    "send_global",
    "send_position",
    "send_stop",
]
