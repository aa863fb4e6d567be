"""Is the position estimate good enough to fly?  PX4 ESTIMATOR_STATUS, ArduPilot EKF_STATUS_REPORT.

PX4 main accepts arming 2-4 s after start, long before its estimate has
settled, and flights armed that early drift the most (the notes); the pre-arm
bit of SYS_STATUS alone does not say so.  Both autopilots report their
estimator's health as flags (ESTIMATOR_STATUS_FLAGS / EKF_STATUS_FLAGS, the
same bits up to 512), but a flag does not mean the same on both:

* every autopilot: attitude, horizontal and vertical velocity, relative and
  absolute horizontal position and absolute height must be set (``REQUIRED``);
* ArduPilot (EKF3 ``getFilterStatus``): CONST_POS_MODE is ``PV_AidingMode ==
  AID_NONE``, no position aiding at all, so it counts as bad, like
  UNINITIALIZED (1024) and GPS_GLITCHING (32768);
* PX4 main (``Ekf::get_ekf_soln_status``): CONST_POS_MODE is ``fake_pos ||
  valid_fake_pos || vehicle_at_rest``, so it is set whenever the vehicle stands
  still on the ground, with a perfect GNSS fix; older PX4 (1.13/1.14) set it as
  ``!velocity_horiz``, which ``REQUIRED`` already covers.  On the ground it is
  therefore ignored; what tells a real fix from a faked one there is
  PRED_POS_HORIZ_ABS (512: ``gnss_pos || aux_gpos`` on main, the absolute
  position flag on older versions), which is required instead.  In the air
  CONST_POS_MODE means a faked position and counts as bad.  GPS_GLITCH (1024)
  and ACCEL_ERROR (2048) are bad.

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
CONST_POS_MODE = 128
PRED_POS_HORIZ_ABS = 512
#: Every one of these must be set.
REQUIRED = 1 | 2 | 4 | 8 | 16 | 32
#: ...and on PX4 this one too (a GNSS position really fused, not a faked one).
PX4_REQUIRED = REQUIRED | PRED_POS_HORIZ_ABS
#: None of these may be set: CONST_POS_MODE, GPS_GLITCH (PX4) / UNINITIALIZED (EKF),
#: ACCEL_ERROR (PX4), GPS_GLITCHING (EKF).
BAD = CONST_POS_MODE | 1024 | 2048 | 32768
BAD_NAMES = {128: "CONST_POS_MODE", 1024: "GPS_GLITCH/UNINITIALIZED", 2048: "ACCEL_ERROR"}
BAD_NAMES[32768] = "GPS_GLITCHING"
#: How long to wait for a first estimator report before not waiting for one (vehicle s).
REPORT_GRACE_S = 3.0


def estimator_message(autopilot: str) -> int:
    """The message that reports ``autopilot``'s estimator ("px4" or "ardupilot")."""
    return MSG_ESTIMATOR_STATUS if autopilot == "px4" else MSG_EKF_STATUS_REPORT


def _rules(autopilot: str, landed: bool) -> tuple[int, int]:
    """(flags that must be set, flags that must not) for ``autopilot`` (module docstring)."""
    if autopilot == "px4":
        return PX4_REQUIRED, BAD & ~CONST_POS_MODE if landed else BAD
    return REQUIRED, BAD


def verdict(flags: int | None, autopilot: str = "ardupilot", landed: bool = True) -> bool | None:
    """True when ``flags`` show a position estimate good enough to fly on ``autopilot``
    (``landed``: the vehicle stands on the ground), False when not, None when unreported."""
    if flags is None:
        return None
    required, bad = _rules(autopilot, landed)
    return flags & required == required and not flags & bad


def describe(flags: int, autopilot: str = "ardupilot", landed: bool = True) -> str:
    """What keeps ``flags`` from being good enough: ``"missing POS_HORIZ_ABS; CONST_POS_MODE"``."""
    required, bad = _rules(autopilot, landed)
    missing = [name for bit, name in FLAG_NAMES.items() if bit & required and not flags & bit]
    wrong = [name for bit, name in BAD_NAMES.items() if bit & bad and flags & bit]
    parts = ([f"missing {', '.join(missing)}"] if missing else []) + wrong
    return "; ".join(parts) or "settled"


__all__ = [
    "BAD",
    "MSG_EKF_STATUS_REPORT",
    "MSG_ESTIMATOR_STATUS",
    "PX4_REQUIRED",
    "REQUIRED",
    "describe",
    "estimator_message",
    "verdict",
]
