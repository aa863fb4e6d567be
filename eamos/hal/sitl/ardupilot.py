"""The simulated vehicle's ArduPilot personality: how ArduCopter SITL behaves where PX4 differs.

* HEARTBEAT autopilot ArduPilotMega (3), ArduCopter mode numbers; it boots in
  STABILIZE and says "ArduPilot Ready" after about 1.4 s, which puts it back
  in STABILIZE (a mode set before that is overwritten).  It cannot arm before.
* It streams little until asked: SYS_STATUS only; REQUEST_DATA_STREAM and
  MAV_CMD_SET_MESSAGE_INTERVAL start the rest.
* GUIDED follows position targets once airborne; MAV_CMD_NAV_TAKEOFF (param7
  metres above home) works only in GUIDED, armed and on the ground, else FAILED.
  MAV_CMD_DO_REPOSITION switches to GUIDED only when its flag asks for it.
* Refused commands answer FAILED; LOCAL_POSITION_NED z is 0 on the ground.
* Speeds are its own unless told: WPNAV_SPEED 500 cm/s (the notes: GUIDED targets fly
  at ~5 m/s), WPNAV_SPEED_UP/DN, WPNAV_ACCEL 250 cm/s/s.  A position target at the
  current spot while fast overshoots by v^2 / (2 WPNAV_ACCEL) and comes back; BRAKE
  stops at BRAKE_DECEL_MPS2; LAND brakes gently.  DISARM_DELAY disarms an idle vehicle.
"""

from __future__ import annotations

import math

from eamos.hal.mavlink.autopilots import ARDUCOPTER_MODES, MAV_AUTOPILOT_ARDUPILOTMEGA
from eamos.hal.sitl.core import FenceLimits, Params, Personality, VehicleCore
from eamos.hal.sitl.manoeuvres import wrap_deg
from eamos.hal.sitl.missions import ARDUPILOT_DIALECT
from eamos.hal.sitl.wire import (
    ACCEPTED,
    ARDUPILOT_READY_S,
    DENIED,
    FAILED,
    MSG_EKF_STATUS_REPORT,
    MSG_HOME_POSITION,
    PARAM_REAL32,
    SEV_CRITICAL,
    SEV_NOTICE,
    VehicleOptions,
    param_int,
)

#: BRAKE mode's deceleration (ArduCopter's BRAKE_MODE_DECEL_RATE, 750 cm/s/s).
BRAKE_DECEL_MPS2 = 7.5
#: Measured on ArduCopter 4.7 SITL (experiment A, tests/sitl/test_sim_vehicle_vs_sitl.py):
#: GUIDED NAV_TAKEOFF leaves the ground this long after the command (spool-up, take-off ramp)...
TAKEOFF_LIFTOFF_S = 3.6
#: ...its jerk-limited position controller flies a move of d metres as a trapezoid of
#: acceleration JERK_ACCEL_FACTOR * d^(1/3) would (1 m legs: 0.72 m/s/s, 2.5 s each; 10 m
#: at 5 m/s: 1.55, about 5.3 s; the notes say about 5), never above WPNAV_ACCEL...
JERK_ACCEL_FACTOR = 0.72
#: ...its land detector reports on the ground 1.5 s after touchdown, and it disarms 0.8 s
#: later (2.3 s after touchdown).
LAND_DETECT_S = 1.5
LAND_DISARM_AFTER_DETECT_S = 0.8
#: Modes a GCS may not switch to here.
_REFUSED_MODES = frozenset({"AUTO", "ACRO", "THROW", "GUIDED_NOGPS"})
_BY_NUMBER = {value: name for name, value in ARDUCOPTER_MODES.items()}


class ArduPilotPersonality(Personality):
    """ArduCopter SITL (see module docstring); keeps whether it announced "Ready"."""

    name = "ardupilot"
    mav_autopilot = MAV_AUTOPILOT_ARDUPILOTMEGA
    # MAVLINK2, COMMAND_INT, PARAM_FLOAT..., and C-cast parameter encoding.
    capabilities = 0x2000 | 0x8 | 0x2 | 0x4 | 0x80 | 0x100 | 0x20000
    version = 4 << 24 | 7 << 16
    initial_mode = "STABILIZE"
    target_mode = "GUIDED"
    modes = ARDUCOPTER_MODES
    default_ground_offset_m = 0.0
    # On SERIAL0 ArduCopter SITL sends HEARTBEAT, STATUSTEXT and, once its origin is set,
    # HOME_POSITION and GPS_GLOBAL_ORIGIN; every stream waits to be asked.
    default_rates: dict[int, float] = {}
    mission_dialect = ARDUPILOT_DIALECT
    refused = FAILED
    # Its EKF settles when the pre-arm checks pass (they include it): the default.
    estimator_msg = MSG_EKF_STATUS_REPORT
    data_streams = True
    #: MAV_CMD_DO_REPOSITION only as COMMAND_INT (as COMMAND_LONG: UNSUPPORTED, observed).
    reposition_long = False
    land_mode = "LAND"
    text_armable = "EKF3 IMU0 is using GPS"
    text_not_ready = "PreArm: EKF3 still initialising"
    text_armed = "Arming motors"
    text_disarmed = "Disarming motors"
    text_preflight_disarm = "Disarming motors"
    text_touchdown = "Land complete"
    text_land_disarm = "Disarming motors"
    text_disarm_in_air = "Disarm: vehicle in the air"
    text_mode_not_armable = "Arm: Mode not armable"

    def __init__(self) -> None:
        self._ready_announced = False

    def custom_mode(self, mode: str) -> int:
        return ARDUCOPTER_MODES[mode]

    def initial_params(self, options: VehicleOptions) -> Params:
        return {
            "SYSID_THISMAV": (float(options.sysid), PARAM_REAL32),
            "DISARM_DELAY": (options.disarm_after_s, PARAM_REAL32),
            "PILOT_TKOFF_ALT": (0.0, PARAM_REAL32),
            # ArduCopter's defaults (cm/s, cm/s/s), not the drone type's.
            "WPNAV_SPEED": (500.0, PARAM_REAL32),
            "WPNAV_SPEED_UP": (250.0, PARAM_REAL32),
            "WPNAV_SPEED_DN": (150.0, PARAM_REAL32),
            "WPNAV_ACCEL": (250.0, PARAM_REAL32),
            "LAND_SPEED": (50.0, PARAM_REAL32),  # cm/s, below LAND_ALT_LOW
            "FS_GCS_ENABLE": (0.0, PARAM_REAL32),
            "RTL_ALT": (1500.0, PARAM_REAL32),  # cm
            "CIRCLE_RADIUS": (1000.0, PARAM_REAL32),  # cm
            "CIRCLE_RATE": (20.0, PARAM_REAL32),  # deg/s, positive clockwise
            # The fence: off until enabled; FENCE_TYPE bits 1 ceiling, 2 circle, 4 polygon;
            # FENCE_ACTION 1 RTL (else land); FENCE_RADIUS 150 from the SITL's copter.parm.
            "FENCE_ENABLE": (0.0, PARAM_REAL32),
            "FENCE_TYPE": (7.0, PARAM_REAL32),
            "FENCE_ACTION": (1.0, PARAM_REAL32),
            "FENCE_ALT_MAX": (100.0, PARAM_REAL32),
            "FENCE_RADIUS": (150.0, PARAM_REAL32),
            "FENCE_MARGIN": (2.0, PARAM_REAL32),
        }

    def speeds(self, v: VehicleCore) -> tuple[float, float, float]:
        value = v.params.value
        return (
            value("WPNAV_SPEED") / 100.0,
            value("WPNAV_SPEED_UP") / 100.0,
            value("WPNAV_SPEED_DN") / 100.0,
        )

    def accel(self, v: VehicleCore) -> float:
        limit = max(v.params.value("WPNAV_ACCEL"), 50.0) / 100.0
        if v.move_from_mps > 0.5:
            return limit  # already moving (a new target in flight): WPNAV_ACCEL, as before
        return min(limit, max(0.3, JERK_ACCEL_FACTOR * v.move_m ** (1.0 / 3.0)))

    def stop_accel(self, v: VehicleCore) -> float:
        return max(v.params.value("WPNAV_ACCEL"), 50.0) / 100.0

    land_detect_s = LAND_DETECT_S

    def land_speed(self, v: VehicleCore) -> float:
        return max(v.params.value("LAND_SPEED"), 10.0) / 100.0

    def land_disarm_s(self, v: VehicleCore) -> float:
        return LAND_DISARM_AFTER_DETECT_S

    def liftoff_delay_s(self, v: VehicleCore) -> float:
        return TAKEOFF_LIFTOFF_S

    def preflight_disarm_s(self, v: VehicleCore) -> float:
        return v.params.value("DISARM_DELAY")

    def mode_entered(self, v: VehicleCore, mode: str) -> bool:
        if mode == "BRAKE":
            v.stop_at(BRAKE_DECEL_MPS2)  # the fastest stop ArduCopter has
            return True
        if mode == "CIRCLE" and v.armed and not v.model.landed:
            radius = v.params.value("CIRCLE_RADIUS") / 100.0
            rate = v.params.value("CIRCLE_RATE")
            if radius < 0.01 or rate == 0:
                return False  # a zero circle: it just holds (and yaws)
            # The centre is CIRCLE_RADIUS ahead of the nose; the speed follows from the
            # rate, capped by WPNAV_SPEED.
            speed = min(math.radians(abs(rate)) * radius, self.speeds(v)[0])
            orbit = v.manoeuvres.orbit_ahead(v, radius, speed)
            orbit.clockwise = rate > 0
            v.manoeuvres.speed_override_mps = speed
            v.manoeuvres.start_orbit(v, orbit)
            return True
        return False

    def rtl_alt_m(self, v: VehicleCore) -> float:
        return v.params.value("RTL_ALT") / 100.0

    def setpoint_yaw(self, v: VehicleCore, heading_deg: float) -> None:
        # ArduCopter's GUIDED targets carry a yaw too (SET_POSITION_TARGET_*, yaw not ignored).
        if v.mode == "GUIDED" and v.armed:
            v.manoeuvres.yaw_to(heading_deg)

    def condition_yaw(self, v: VehicleCore, p: tuple[float, ...]) -> int:
        # param1 angle (deg), param2 rate, param3 direction (-1 ccw, 1 cw, 0 shortest),
        # param4 relative (1) or absolute (0).  GUIDED (and AUTO) only.
        angle, direction, relative = p[0], p[2], p[3]
        if v.mode != "GUIDED" or not v.armed or v.model.landed or not math.isfinite(angle):
            return FAILED
        heading = v.manoeuvres.heading_deg
        if math.isfinite(relative) and relative >= 0.5:
            sign = -1.0 if math.isfinite(direction) and direction < 0 else 1.0
            v.manoeuvres.yaw_to(wrap_deg(heading + sign * angle))
        else:
            v.manoeuvres.yaw_to(angle)
        return ACCEPTED

    def change_speed(self, v: VehicleCore, p: tuple[float, ...]) -> int:
        # param1 speed type (0 airspeed, 1 ground speed, 2 climb, 3 descent), param2 m/s;
        # it holds until the next mode change.
        kind, speed = param_int(p[0], -1), p[1]
        if kind not in (0, 1) or not math.isfinite(speed) or speed <= 0:
            return FAILED
        v.manoeuvres.speed_override_mps = speed
        return ACCEPTED

    def boot(self, v: VehicleCore) -> None:
        if not self._ready_announced and v.t >= ARDUPILOT_READY_S:
            self._ready_announced = True
            v.mode = "STABILIZE"  # the initial mode wins over anything set during boot
            v.text("ArduPilot Ready")

    def ready(self, v: VehicleCore) -> bool:
        return self._ready_announced

    def arming_refused(self, v: VehicleCore) -> int:
        v.text(f"Arm: {v.prearm_reason().removeprefix('PreArm: ')}", SEV_CRITICAL)
        return FAILED

    def set_mode(self, v: VehicleCore, p: tuple[float, ...]) -> str | int:
        mode = _BY_NUMBER.get(param_int(p[1]))
        if mode is None or mode in _REFUSED_MODES:
            return FAILED
        return mode

    def takeoff(self, v: VehicleCore, p: tuple[float, ...]) -> int:
        # GUIDED and armed, on the ground, a positive height.
        model = v.model
        if v.mode != "GUIDED" or not v.armed or not model.landed:
            return FAILED
        height = p[6]
        if not math.isfinite(height) or height <= 0:
            return FAILED
        x, y, _ = model.position
        v.steer(x, y, height)
        v.flew = True  # taking off counts: no preflight auto-disarm
        return ACCEPTED

    def reposition_mode(
        self, v: VehicleCore, p: tuple[float, ...], target: tuple[float, float, float]
    ) -> int | None:
        if v.outside_fence(target) is not None:
            return FAILED  # ModeGuided refuses a destination outside the fence
        if v.mode != "GUIDED":
            if not param_int(p[1]) & 1:  # MAV_DO_REPOSITION_FLAGS_CHANGE_MODE
                return FAILED
            v.enter_mode("GUIDED", "reposition")
        return None

    def position_target(self, v: VehicleCore, target: tuple[float, float, float]) -> None:
        if v.mode == "GUIDED" and v.armed and not v.model.landed:
            # ArduCopter ignores position targets until it has taken off, and any outside
            # its enabled fence (ModeGuided's check_destination_within_fence).
            if v.outside_fence(target) is not None:
                v.log.info("vehicle.target.outside_fence", target=[round(c, 2) for c in target])
                return
            v.steer(*target)

    # -- the fence --------------------------------------------------------------------------

    def fence_limits(self, v: VehicleCore) -> FenceLimits | None:
        value = v.params.value
        if value("FENCE_ENABLE") < 0.5:
            return None
        kinds = param_int(value("FENCE_TYPE"))
        return FenceLimits(
            ceiling_m=value("FENCE_ALT_MAX") if kinds & 1 else None,
            radius_m=value("FENCE_RADIUS") if kinds & 2 else None,
            uploaded=bool(kinds & 4),
        )

    def fence_breached(self, v: VehicleCore, kind: str) -> None:
        name = {"altitude": "Max Alt", "circle": "Circle", "polygon": "Polygon"}[kind]
        v.text(f"{name} fence breached", SEV_CRITICAL)
        # FENCE_ACTION: 0 report only, 1 RTL or land, 2 land, 3/5 SmartRTL (here RTL),
        # 4 brake, 6 guided-loiter (here brake).
        action = param_int(v.params.value("FENCE_ACTION"))
        mode = {1: "RTL", 2: "LAND", 3: "RTL", 4: "BRAKE", 5: "RTL", 6: "BRAKE"}.get(action)
        if mode is not None and v.mode != mode:
            v.enter_mode(mode, "fence breach")

    def fence_cleared(self, v: VehicleCore) -> None:
        v.text("Fence breach cleared", SEV_NOTICE)

    def armable_announced(self, v: VehicleCore) -> None:
        # Its origin and home are set: it says so once, unasked.
        v.streams.send_message(MSG_HOME_POSITION, v.status())
        lat, lon, alt = v.options.home
        v.send("gps_global_origin", round(lat * 1e7), round(lon * 1e7), round(alt * 1000), 0)

    def coordinates_refused(self, v: VehicleCore) -> int | None:
        return DENIED  # check_latlng in handle_command_int_do_reposition


__all__ = ["ArduPilotPersonality"]
