"""The simulated MAVLink vehicle's wire: MAVLink numbers, build options, ``--reject`` parsing.

Shared by the vehicle core (:mod:`eamos.hal.sitl.core`), its PX4 and
ArduPilot personalities and the threaded vehicle (:mod:`eamos.hal.sitl.vehicle`).
The numbers are kept here, not read from pymavlink, so the simulator reads
(and imports) without pymavlink loaded.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

from eamos.hal.kinematics import Limits
from eamos.hal.mavlink.link import load_mavutil

AutopilotName = Literal["px4", "ardupilot"]

# -- MAVLink numbers (kept local so the module reads without pymavlink open) --
MAV_TYPE_QUADROTOR = 2
MAV_STATE_STANDBY, MAV_STATE_ACTIVE = 3, 4
MAV_MODE_FLAG_CUSTOM_MODE_ENABLED = 1
MAV_MODE_FLAG_GUIDED_ENABLED = 8
MAV_MODE_FLAG_STABILIZE_ENABLED = 16
MAV_MODE_FLAG_SAFETY_ARMED = 128
ACCEPTED, TEMPORARILY_REJECTED, DENIED, UNSUPPORTED, FAILED = 0, 1, 2, 3, 4
RESULTS = {
    "ACCEPTED": ACCEPTED,
    "TEMPORARILY_REJECTED": TEMPORARILY_REJECTED,
    "DENIED": DENIED,
    "UNSUPPORTED": UNSUPPORTED,
    "FAILED": FAILED,
}
SEV_CRITICAL, SEV_WARNING, SEV_NOTICE, SEV_INFO = 2, 4, 5, 6
LANDED_ON_GROUND, LANDED_IN_AIR, LANDED_TAKEOFF, LANDED_LANDING = 1, 2, 3, 4
FORCE_MAGIC = 21196  # MAV_CMD_COMPONENT_ARM_DISARM param2: force (disarm in the air)

CMD_NAV_LAND, CMD_NAV_TAKEOFF = 21, 22
CMD_DO_SET_MODE, CMD_DO_REPOSITION = 176, 192
CMD_COMPONENT_ARM_DISARM = 400
CMD_NAV_RETURN_TO_LAUNCH, CMD_DO_ORBIT, CMD_CONDITION_YAW = 20, 34, 115
CMD_DO_CHANGE_SPEED = 178
CMD_DO_FENCE_ENABLE, CMD_DO_SET_MISSION_CURRENT = 207, 224
CMD_DO_MOUNT_CONTROL, CMD_DO_GIMBAL_MANAGER_PITCHYAW = 205, 1000
CMD_IMAGE_START_CAPTURE, CMD_VIDEO_START_CAPTURE, CMD_VIDEO_STOP_CAPTURE = 2000, 2500, 2501
CMD_GET_HOME_POSITION = 410
CMD_SET_MESSAGE_INTERVAL, CMD_REQUEST_MESSAGE = 511, 512
CMD_REQUEST_AUTOPILOT_CAPABILITIES = 520

MSG_HEARTBEAT, MSG_SYS_STATUS, MSG_GPS_RAW_INT, MSG_ATTITUDE = 0, 1, 24, 30
MSG_LOCAL_POSITION_NED, MSG_GLOBAL_POSITION_INT = 32, 33
MSG_MISSION_CURRENT, MSG_VFR_HUD = 42, 74
MSG_BATTERY_STATUS, MSG_AUTOPILOT_VERSION = 147, 148
MSG_HOME_POSITION, MSG_EXTENDED_SYS_STATE = 242, 245
#: The estimator's health: PX4's ESTIMATOR_STATUS, ArduPilot's EKF_STATUS_REPORT.
MSG_ESTIMATOR_STATUS, MSG_EKF_STATUS_REPORT = 230, 193
#: ESTIMATOR_STATUS_FLAGS / EKF_STATUS_FLAGS (the same bits up to 512): a settled
#: estimate has attitude, velocity, relative and absolute position, height, predictions.
ESTIMATOR_SETTLED_FLAGS = 1 | 2 | 4 | 8 | 16 | 32 | 256 | 512
#: ...an unsettled one: attitude, velocity, height, and "constant position mode".
ESTIMATOR_UNSETTLED_FLAGS = 1 | 2 | 4 | 32 | 128
STREAMABLE = frozenset(
    {
        MSG_SYS_STATUS,
        MSG_GPS_RAW_INT,
        MSG_ATTITUDE,
        MSG_LOCAL_POSITION_NED,
        MSG_GLOBAL_POSITION_INT,
        MSG_BATTERY_STATUS,
        MSG_HOME_POSITION,
        MSG_EXTENDED_SYS_STATE,
        MSG_ESTIMATOR_STATUS,
        MSG_EKF_STATUS_REPORT,
        MSG_MISSION_CURRENT,
        MSG_VFR_HUD,
    }
)
#: The rate (Hz, simulated time) a stream returns to when MAV_CMD_SET_MESSAGE_INTERVAL
#: asks for "the default" (interval 0): PX4's defaults, which both personalities use.
DEFAULT_STREAM_RATES: Mapping[int, float] = {
    MSG_SYS_STATUS: 1.0,
    MSG_EXTENDED_SYS_STATE: 1.0,
    MSG_LOCAL_POSITION_NED: 10.0,
    MSG_GLOBAL_POSITION_INT: 10.0,
    MSG_ATTITUDE: 10.0,
    MSG_HOME_POSITION: 0.5,
    MSG_GPS_RAW_INT: 1.0,
    MSG_BATTERY_STATUS: 0.5,
    MSG_ESTIMATOR_STATUS: 1.0,
    MSG_EKF_STATUS_REPORT: 1.0,
    MSG_MISSION_CURRENT: 1.0,
    MSG_VFR_HUD: 4.0,
}
#: What PX4's onboard link (MAVLINK_MODE_ONBOARD, the 14540+N link) streams unasked (Hz,
#: simulated time), for the messages simulated here; PX4 main's SITL measured the same.
#: The vehicle sends each stream at most once per tick (at a speed-up of 10: 10 Hz).
PX4_ONBOARD_RATES: Mapping[int, float] = {
    MSG_SYS_STATUS: 5.0,
    MSG_EXTENDED_SYS_STATE: 5.0,
    MSG_LOCAL_POSITION_NED: 30.0,
    MSG_GLOBAL_POSITION_INT: 50.0,
    MSG_ATTITUDE: 100.0,
    MSG_HOME_POSITION: 0.5,
    MSG_GPS_RAW_INT: 5.0,
    MSG_BATTERY_STATUS: 0.5,
    MSG_ESTIMATOR_STATUS: 1.0,
    MSG_MISSION_CURRENT: 1.0,
    MSG_VFR_HUD: 10.0,
}
#: ArduPilot's REQUEST_DATA_STREAM groups (MAV_DATA_STREAM) of the messages simulated here.
DATA_STREAMS: dict[int, tuple[int, ...]] = {
    2: (MSG_SYS_STATUS, MSG_GPS_RAW_INT, MSG_MISSION_CURRENT),  # EXTENDED_STATUS
    6: (MSG_GLOBAL_POSITION_INT, MSG_LOCAL_POSITION_NED),  # POSITION
    10: (MSG_ATTITUDE,),  # EXTRA1
    11: (MSG_VFR_HUD,),  # EXTRA2
    # EXTRA3
    12: (MSG_BATTERY_STATUS, MSG_EXTENDED_SYS_STATE, MSG_HOME_POSITION, MSG_EKF_STATUS_REPORT),
}

FRAME_GLOBAL, FRAME_LOCAL_NED, FRAME_GLOBAL_RELATIVE_ALT = 0, 1, 3
FRAME_GLOBAL_INT, FRAME_GLOBAL_RELATIVE_ALT_INT = 5, 6
#: SET_POSITION_TARGET type_mask bits meaning "ignore x, y, z" and "ignore vx, vy, vz".
IGNORE_POSITION = 0x7
IGNORE_VELOCITY = 0x38
#: ...and "ignore yaw".
IGNORE_YAW = 0x400

PARAM_INT32, PARAM_REAL32 = 6, 9
#: MAV_SYS_STATUS sensors every simulated vehicle has and reports healthy.
SENSORS = (
    0x1
    | 0x2
    | 0x4
    | 0x8
    | 0x20  # gyro, accel, mag, baro, GPS
    | 0x400
    | 0x800
    | 0x1000
    | 0x2000
    | 0x4000
    | 0x8000  # rate, attitude, yaw, z, xy, motors
    | 0x200000
    | 0x2000000  # AHRS, battery
)
PREARM_CHECK = 0x10000000
GEOFENCE = 0x100000  # MAV_SYS_STATUS_GEOFENCE

#: Simulated seconds from start to the first HEARTBEAT (both SITLs take ~1 s).
BOOT_S = 1.0
#: ArduPilot: the initial mode replaces anything set before this (the notes: ~1.4 s).
ARDUPILOT_READY_S = 1.4
#: PX4 COM_OF_LOSS_T: simulated seconds without a setpoint before the failsafe...
OFFBOARD_LOSS_S = 1.0
#: ...and, so a host hiccup at a high speed-up is not a failsafe, wall seconds too.
OFFBOARD_LOSS_WALL_S = 0.5
#: Touchdown to automatic disarm (PX4 COM_DISARM_LAND; ArduPilot likewise ~2 s).
LAND_DISARM_S = 2.0
#: How often an unready vehicle repeats why it cannot arm (simulated seconds).
PREARM_TEXT_PERIOD_S = 10.0
#: STATUSTEXT payload length; longer texts go out in chunks sharing an id.
STATUSTEXT_LEN = 50


@dataclass(frozen=True)
class VehicleOptions:
    """How to build one :class:`SimVehicle` (the command line maps onto this)."""

    autopilot: AutopilotName
    connection: str
    sysid: int = 1
    speedup: float = 1.0
    prearm_delay_s: float = 3.0
    home: tuple[float, float, float] = (46.6103, 14.2640, 450.0)  # lat, lon, alt AMSL
    reject: Mapping[int, int] = field(default_factory=dict)  # MAV_CMD -> MAV_RESULT
    disarm_after_s: float = 10.0
    ground_offset_m: float | None = None  # PX4 LOCAL z on the ground; None: 1.5 PX4, 0 ArduPilot
    report_prearm: bool = True  # False: SYS_STATUS without the PREARM_CHECK bit (older firmware)
    limits: Limits = field(default_factory=Limits)
    log: Path | None = None
    #: Standard deviation (m) of a wandering position estimate (PX4 SIH hovers at ~0.28 m);
    #: 0: LOCAL_POSITION_NED is the truth.  ``seed`` makes the wander repeatable.
    wander_m: float = 0.0
    seed: int = 0
    #: MAVLink 2 signing key (32 bytes): sign everything, refuse unsigned (but RADIO_STATUS).
    #: None: unsigned until a SETUP_SIGNING provisions a key.
    signing_key: bytes | None = field(default=None, repr=False)
    #: Sudden death: this many simulated seconds after leaving the ground the vehicle
    #: stops dead (no message, no goodbye), like a crashed autopilot process.
    die_after_s: float | None = None
    #: Simulated seconds from start until the estimator settles (ESTIMATOR_STATUS /
    #: EKF_STATUS_REPORT flags); None: the personality's (PX4 6 s, after it already
    #: accepts arming at ``prearm_delay_s``, as PX4 main does; ArduPilot: armable).
    estimator_settle_s: float | None = None
    #: The unsettled estimate's horizontal error at start (m, north-east), shrinking to 0
    #: when it settles: whatever is anchored to an early estimate (home) is off by it.
    estimator_bias_m: float = 0.0

    def __post_init__(self) -> None:
        if self.autopilot not in ("px4", "ardupilot"):
            raise ValueError(f"autopilot must be px4 or ardupilot, got {self.autopilot!r}")
        if not self.connection.startswith(("udpout:", "udpin:", "tcpin:")):
            raise ValueError(
                f"connection must be udpout:, udpin: or tcpin:HOST:PORT, got {self.connection!r}"
            )
        if not 1 <= self.sysid <= 255:
            raise ValueError(f"sysid must be 1..255, got {self.sysid}")
        if not self.speedup > 0:
            raise ValueError("speedup must be > 0")
        if not self.prearm_delay_s >= 0 or not self.disarm_after_s > 0:
            raise ValueError("prearm delay must be >= 0 and disarm-after > 0")
        if not self.wander_m >= 0:
            raise ValueError("wander must be >= 0")
        if self.estimator_settle_s is not None and not self.estimator_settle_s >= 0:
            raise ValueError("estimator settle time must be >= 0")
        if not self.estimator_bias_m >= 0:
            raise ValueError("estimator bias must be >= 0")


def parse_reject(specs: Iterable[str]) -> dict[int, int]:
    """``["MAV_CMD_NAV_TAKEOFF", "400=FAILED"]`` -> {22: DENIED, 400: FAILED}.

    A command is a MAV_CMD name (with or without ``MAV_CMD_``) or number; the
    result (default DENIED) a MAV_RESULT name (with or without ``MAV_RESULT_``).
    """
    mavutil = load_mavutil()
    by_name = {entry.name: value for value, entry in mavutil.mavlink.enums["MAV_CMD"].items()}
    out: dict[int, int] = {}
    for spec in specs:
        cmd_text, _, result_text = spec.partition("=")
        cmd_text = cmd_text.strip().upper()
        if cmd_text.isdigit():
            command = int(cmd_text)
        else:
            name = cmd_text if cmd_text.startswith("MAV_CMD_") else f"MAV_CMD_{cmd_text}"
            if name not in by_name:
                raise ValueError(f"unknown MAVLink command {spec!r}")
            command = by_name[name]
        result_key = (result_text.strip().upper() or "DENIED").removeprefix("MAV_RESULT_")
        if result_key not in RESULTS or result_key == "ACCEPTED":
            raise ValueError(
                f"--reject {spec!r}: result must be one of "
                f"{', '.join(k for k in RESULTS if k != 'ACCEPTED')}"
            )
        out[command] = RESULTS[result_key]
    return out


def param_int(value: float, default: int = 0) -> int:
    """A command parameter as an integer; NaN ("unused", as MAVSDK sends) gives ``default``."""
    return round(value) if math.isfinite(value) else default


def json_number(value: float) -> float | None:
    """A JSON-friendly number (NaN becomes null)."""
    return None if not math.isfinite(value) else round(value, 7)
