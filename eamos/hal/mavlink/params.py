"""The autopilot parameters the MAVLink adapter sets for a flight, and restores afterwards.

A vehicle flies at its own cruise speed unless told otherwise (ArduCopter's
GUIDED targets ~5 m/s, PX4's OFFBOARD targets ~6 m/s), while the mission was
planned and simulated with the drone type's speeds (``horizontal_speed_mps``,
``climb_speed_mps``, ``descent_speed_mps`` in ``hal``, the same keys as the
``sim`` adapter's).  So the adapter reads these parameters after connecting,
sets them to the drone type's speeds, and writes the values it read back
when it closes:

========== ==================== ====================== =====================
autopilot  horizontal           climb                  descent
========== ==================== ====================== =====================
ardupilot  WPNAV_SPEED (cm/s)   WPNAV_SPEED_UP (cm/s)  WPNAV_SPEED_DN (cm/s)
px4        MPC_XY_VEL_MAX and   MPC_Z_VEL_MAX_UP (m/s) MPC_Z_VEL_MAX_DN (m/s)
           MPC_XY_CRUISE (m/s)
========== ==================== ====================== =====================

(PX4 flies OFFBOARD position setpoints under MPC_XY_VEL_MAX; MPC_XY_CRUISE is
the AUTO modes' speed and may not exceed it.)  Parameters are set rather than
MAV_CMD_DO_CHANGE_SPEED because the command lasts only until the next mode
change (ArduCopter: AUTO and GUIDED only) and PX4 ignores it in OFFBOARD.

This module is pure: :func:`speed_plan` says what to set;
:class:`ParamChange` records what was there before.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

#: MAV_PARAM_TYPE values.
MAV_PARAM_TYPE_INT32, MAV_PARAM_TYPE_REAL32 = 6, 9
_INT_TYPES = frozenset(range(1, 9))  # UINT8 .. INT64


@dataclass(frozen=True)
class ParamChange:
    """One parameter the adapter set: its name, the value it found and the value it wrote."""

    name: str
    before: float
    after: float
    param_type: int = MAV_PARAM_TYPE_REAL32


def speed_plan(
    autopilot: str, horizontal_mps: float, climb_mps: float, descent_mps: float
) -> tuple[tuple[str, float], ...]:
    """(parameter, value) pairs that make ``autopilot`` fly at the drone type's speeds."""
    if autopilot == "ardupilot":
        return (
            ("WPNAV_SPEED", round(horizontal_mps * 100.0, 1)),
            ("WPNAV_SPEED_UP", round(climb_mps * 100.0, 1)),
            ("WPNAV_SPEED_DN", round(descent_mps * 100.0, 1)),
        )
    if autopilot == "px4":
        return (
            ("MPC_XY_VEL_MAX", horizontal_mps),
            ("MPC_XY_CRUISE", horizontal_mps),
            ("MPC_Z_VEL_MAX_UP", climb_mps),
            ("MPC_Z_VEL_MAX_DN", descent_mps),
        )
    raise ValueError(f"unknown autopilot {autopilot!r}")


def to_wire(value: float, param_type: int, bytewise: bool) -> float:
    """A parameter's value as PARAM_SET/PARAM_VALUE carry it.

    PX4 (``bytewise``) puts integers' bytes into the float; ArduPilot casts.
    """
    if bytewise and param_type in _INT_TYPES:
        return float(struct.unpack("<f", struct.pack("<i", int(value)))[0])
    return float(value)


def from_wire(raw: float, param_type: int, bytewise: bool) -> float:
    """The inverse of :func:`to_wire`."""
    if bytewise and param_type in _INT_TYPES:
        return float(struct.unpack("<i", struct.pack("<f", raw))[0])
    return float(raw)


__all__ = [
    "MAV_PARAM_TYPE_INT32",
    "MAV_PARAM_TYPE_REAL32",
    "ParamChange",
    "from_wire",
    "speed_plan",
    "to_wire",
]
