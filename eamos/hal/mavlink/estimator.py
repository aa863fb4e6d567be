"""Is the position estimate settled?  PX4 ESTIMATOR_STATUS, ArduPilot EKF_STATUS_REPORT.

PX4 main accepts arming 2-4 s after start, long before its estimate has
settled, and flights armed that early drift the most (the notes); the pre-arm
bit of SYS_STATUS alone does not say so.  Both autopilots report their
estimator's health as flags (ESTIMATOR_STATUS_FLAGS / EKF_STATUS_FLAGS, the
same bits up to 512):

* settled: attitude, horizontal and vertical velocity, relative and absolute
  horizontal position and absolute height (``REQUIRED``);
* not settled: any of those missing, or "constant position mode" (no aiding
  yet), a GPS glitch, an accelerometer error, or ArduPilot's "uninitialised"
  (``BAD``).

:func:`verdict` and :func:`describe` are pure; the adapter's wait before
arming is :func:`eamos.hal.mavlink.arming.await_settled`.
"""

from __future__ import annotations

#: Message ids (MAVLink common / ardupilotmega).
MSG_ESTIMATOR_STATUS = 230
MSG_EKF_STATUS_REPORT = 193
#: Flag names by bit (ESTIMATOR_STATUS_FLAGS; EKF_STATUS_FLAGS differ only above 512).
FLAG_NAMES: dict[int, str] = {
    1: "ATTITUDE",
    2: "VELOCITY_HORIZ",
    4: "VELOCITY_VERT",
    8: "POS_HORIZ_REL",
    16: "POS_HORIZ_ABS",
    32: "POS_VERT_ABS",
    64: "POS_VERT_AGL",
    128: "CONST_POS_MODE",
    256: "PRED_POS_HORIZ_REL",
    512: "PRED_POS_HORIZ_ABS",
}
#: Every one of these must be set.
REQUIRED = 1 | 2 | 4 | 8 | 16 | 32
#: None of these may be set: CONST_POS_MODE, GPS_GLITCH (PX4) / UNINITIALIZED (EKF),
#: ACCEL_ERROR (PX4), GPS_GLITCHING (EKF).
BAD = 128 | 1024 | 2048 | 32768
BAD_NAMES = {128: "CONST_POS_MODE", 1024: "GPS_GLITCH/UNINITIALIZED", 2048: "ACCEL_ERROR"}
BAD_NAMES[32768] = "GPS_GLITCHING"
#: How long to wait for a first estimator report before not waiting for one (vehicle s).
REPORT_GRACE_S = 3.0


def estimator_message(autopilot: str) -> int:
    """The message that reports ``autopilot``'s estimator ("px4" or "ardupilot")."""
    return MSG_ESTIMATOR_STATUS if autopilot == "px4" else MSG_EKF_STATUS_REPORT


def verdict(flags: int | None) -> bool | None:
    """True when ``flags`` show a settled estimate, False when not, None when unreported."""
    if flags is None:
        return None
    return flags & REQUIRED == REQUIRED and not flags & BAD


def describe(flags: int) -> str:
    """What keeps ``flags`` from being settled: ``"missing POS_HORIZ_ABS; CONST_POS_MODE"``."""
    missing = [name for bit, name in FLAG_NAMES.items() if bit & REQUIRED and not flags & bit]
    bad = [name for bit, name in BAD_NAMES.items() if flags & bit]
    parts = ([f"missing {', '.join(missing)}"] if missing else []) + bad
    return "; ".join(parts) or "settled"


__all__ = [
    "BAD",
    "MSG_EKF_STATUS_REPORT",
    "MSG_ESTIMATOR_STATUS",
    "REQUIRED",
    "describe",
    "estimator_message",
    "verdict",
]
