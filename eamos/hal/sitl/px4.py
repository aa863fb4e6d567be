"""The simulated vehicle's PX4 personality: how PX4 SITL behaves where ArduPilot differs.

* HEARTBEAT autopilot PX4 (12), custom modes ``main << 16 | sub << 24``; it
  boots in HOLD and is ready as soon as the pre-arm delay has passed.
* Arming before that is TEMPORARILY_REJECTED with "Arming denied: Resolve
  system health failures first" and the reason; other refusals are DENIED.
* OFFBOARD follows SET_POSITION_TARGET_LOCAL_NED/GLOBAL_INT and is refused
  in the air without a setpoint stream; a second without setpoints
  (COM_OF_LOSS_T, also counted in wall seconds so a host hiccup at a high
  speed-up is no failsafe) is a failsafe into HOLD, left by itself when
  setpoints resume.  OFFBOARD without a stream is not armable.
* AUTO.TAKEOFF (MAV_CMD_NAV_TAKEOFF, param7 AMSL or MIS_TAKEOFF_ALT) climbs,
  then HOLD.  MAV_CMD_DO_REPOSITION flies to a WGS84 point in HOLD.  After a
  landing (or any disarm in AUTO.LAND/AUTO.TAKEOFF) it returns to HOLD.
* LOCAL_POSITION_NED z is offset on the ground (1.5 m), as PX4 SIH's is.
* Integer parameters travel byte-wise inside PARAM_VALUE's float.
* Speeds are its own unless told: OFFBOARD position targets fly at ~6 m/s (the notes)
  under MPC_XY_VEL_MAX (12), other modes at MPC_XY_CRUISE; MPC_Z_VEL_MAX_UP/DN;
  MPC_ACC_HOR 3 m/s/s (a position target at the current spot while fast overshoots by
  v^2 / 6 and comes back); a zero-velocity setpoint stops at MPC_ACC_HOR_MAX (5 m/s/s).
"""

from __future__ import annotations

import math
import struct

from eamos.hal.mavlink.autopilots import MAV_AUTOPILOT_PX4, PX4_MODES, px4_custom_mode
from eamos.hal.sitl.core import FenceLimits, Params, Personality, VehicleCore
from eamos.hal.sitl.manoeuvres import Orbit
from eamos.hal.sitl.missions import PX4_DIALECT
from eamos.hal.sitl.wire import (
    ACCEPTED,
    DENIED,
    LAND_DISARM_S,
    MSG_ESTIMATOR_STATUS,
    OFFBOARD_LOSS_S,
    OFFBOARD_LOSS_WALL_S,
    PARAM_INT32,
    PARAM_REAL32,
    PX4_ONBOARD_RATES,
    SEV_CRITICAL,
    SEV_NOTICE,
    TEMPORARILY_REJECTED,
    VehicleOptions,
    param_int,
)

#: The speed OFFBOARD position targets were seen to fly at (PX4 main, SIH), below
#: MPC_XY_VEL_MAX's default of 12 m/s.
OFFBOARD_CRUISE_MPS = 6.0
#: PX4 main accepts arming 2-4 s after start, but its estimate settles only later (the
#: notes: "flights armed that early drift the most"): ESTIMATOR_STATUS flags settle
#: this many simulated seconds after start (at least ESTIMATOR_AFTER_ARMABLE_S after the
#: pre-arm delay).
ESTIMATOR_SETTLE_S = 6.0
ESTIMATOR_AFTER_ARMABLE_S = 2.0
#: Measured on PX4 main SITL (SIH, experiment A): OFFBOARD or AUTO.TAKEOFF leaves the
#: ground MPC_TKO_RAMP_T plus this long after being told to climb (its smooth take-off
#: also climbs slowly at first: 0.65 m/s at most towards 1.5 m)...
LIFTOFF_AFTER_RAMP_S = 2.0
#: ...and "Landing detected" comes about this long after touchdown (three landings from
#: 1.5 m took 4.8-7.3 s from MAV_CMD_NAV_LAND to ON_GROUND).
LAND_DETECT_S = 2.2
#: Modes a GCS cannot switch to without an RC transmitter.
_RC_MODES = frozenset({"MANUAL", "ALTCTL", "POSCTL", "ACRO", "STABILIZED"})
_BY_NUMBERS = {pair: name for name, pair in PX4_MODES.items()}


class Px4Personality(Personality):
    """PX4 SITL (see module docstring); keeps the setpoint stream and take-off height."""

    name = "px4"
    mav_autopilot = MAV_AUTOPILOT_PX4
    # MAVLINK2, COMMAND_INT, PARAM_FLOAT..., and byte-wise parameter encoding.
    capabilities = 0x2000 | 0x8 | 0x2 | 0x4 | 0x80 | 0x100 | 0x10
    version = 1 << 24 | 15 << 16 | 0 << 8 | 255
    initial_mode = "HOLD"
    target_mode = "OFFBOARD"
    modes = PX4_MODES
    default_ground_offset_m = 1.5
    default_rates = PX4_ONBOARD_RATES  # PX4's onboard link streams a lot by default
    mission_dialect = PX4_DIALECT
    refused = DENIED
    estimator_msg = MSG_ESTIMATOR_STATUS
    #: MAV_CMD_DO_REPOSITION as COMMAND_LONG or COMMAND_INT.
    reposition_long = True
    land_mode = "AUTO.LAND"
    text_armable = "Ready for takeoff!"
    text_not_ready = "Preflight Fail: ekf2 missing data"
    text_armed = "Armed by external command"
    text_disarmed = "Disarmed by external command"
    text_preflight_disarm = "Disarmed by auto preflight disarming"
    text_touchdown = "Landing detected"
    text_land_disarm = "Disarmed by landing"
    text_disarm_in_air = "Disarming denied: not landed"
    text_mode_not_armable = "Arming denied: not in a mode that can arm"

    def __init__(self) -> None:
        self._last_sp_t = -math.inf  # last setpoint, simulated and wall seconds
        self._last_sp_wall = -math.inf
        self._offboard_target: tuple[float, float, float] | None = None  # model frame
        self._failsafe = False
        self._takeoff_z: float | None = None  # AUTO.TAKEOFF target height

    # -- identity and parameters ------------------------------------------------------

    def custom_mode(self, mode: str) -> int:
        return px4_custom_mode(*PX4_MODES[mode])

    def initial_params(self, options: VehicleOptions) -> Params:
        return {
            "MAV_SYS_ID": (float(options.sysid), PARAM_INT32),
            "MIS_TAKEOFF_ALT": (2.5, PARAM_REAL32),
            "COM_DISARM_PRFLT": (options.disarm_after_s, PARAM_REAL32),
            "COM_DISARM_LAND": (LAND_DISARM_S, PARAM_REAL32),
            "MPC_LAND_SPEED": (0.7, PARAM_REAL32),
            "MPC_LAND_ALT3": (1.0, PARAM_REAL32),
            "MPC_LAND_CRWL": (0.3, PARAM_REAL32),
            "MPC_TKO_RAMP_T": (3.0, PARAM_REAL32),
            "COM_OF_LOSS_T": (OFFBOARD_LOSS_S, PARAM_REAL32),
            "COM_OBL_RC_ACT": (5.0, PARAM_INT32),
            # PX4's defaults, not the drone type's.
            "MPC_XY_CRUISE": (5.0, PARAM_REAL32),
            "MPC_XY_VEL_MAX": (12.0, PARAM_REAL32),
            "MPC_Z_VEL_MAX_UP": (3.0, PARAM_REAL32),
            "MPC_Z_VEL_MAX_DN": (1.5, PARAM_REAL32),
            "MPC_ACC_HOR": (3.0, PARAM_REAL32),
            "MPC_ACC_HOR_MAX": (5.0, PARAM_REAL32),
            "MPC_XY_P": (0.95, PARAM_REAL32),
            "MPC_Z_P": (1.0, PARAM_REAL32),
            "RTL_RETURN_ALT": (30.0, PARAM_REAL32),  # PX4 main's default (read on its SITL)
            # The geofence: GF_ACTION 2 holds on a breach (PX4 main's default); a ceiling
            # and a radius around home when set above 0; uploaded polygons always.
            "GF_ACTION": (2.0, PARAM_INT32),
            "GF_MAX_HOR_DIST": (0.0, PARAM_REAL32),
            "GF_MAX_VER_DIST": (0.0, PARAM_REAL32),
        }

    def speeds(self, v: VehicleCore) -> tuple[float, float, float]:
        value = v.params.value
        limit = value("MPC_XY_VEL_MAX")
        cruise = OFFBOARD_CRUISE_MPS if v.mode == "OFFBOARD" else value("MPC_XY_CRUISE")
        horizontal = min(cruise, limit)
        up, down = value("MPC_Z_VEL_MAX_UP"), value("MPC_Z_VEL_MAX_DN")
        target = v.model.target
        if v.mode == "OFFBOARD" and target is not None:
            # OFFBOARD position setpoints go straight to the position controller, whose
            # velocity is MPC_XY_P (MPC_Z_P) times the distance left: it slows down as it
            # nears the setpoint (1 m legs peaked at 0.7-0.8 m/s on the SITL).
            x, y, z = v.model.position
            horizontal = min(horizontal, value("MPC_XY_P") * math.dist((x, y), target[:2]))
            vertical = value("MPC_Z_P") * abs(target[2] - z)
            up, down = min(up, vertical), min(down, vertical)
        return (horizontal, up, down)

    def accel(self, v: VehicleCore) -> float:
        return max(v.params.value("MPC_ACC_HOR"), 0.5)

    def stop_accel(self, v: VehicleCore) -> float:
        return max(v.params.value("MPC_ACC_HOR_MAX"), 0.5)

    def preflight_disarm_s(self, v: VehicleCore) -> float:
        return v.params.value("COM_DISARM_PRFLT")

    land_detect_s = LAND_DETECT_S

    def land_speed(self, v: VehicleCore) -> float:
        # Below MPC_LAND_ALT3 (SIH has a distance sensor) it crawls at MPC_LAND_CRWL.
        value = v.params.value
        if v.model.position[2] < value("MPC_LAND_ALT3"):
            return max(value("MPC_LAND_CRWL"), 0.1)
        return max(value("MPC_LAND_SPEED"), 0.1)

    def land_disarm_s(self, v: VehicleCore) -> float:
        return max(v.params.value("COM_DISARM_LAND"), 0.0)

    def liftoff_delay_s(self, v: VehicleCore) -> float:
        return max(v.params.value("MPC_TKO_RAMP_T"), 0.0) + LIFTOFF_AFTER_RAMP_S

    def estimator_settle_s(self, options: VehicleOptions) -> float:
        return max(ESTIMATOR_SETTLE_S, options.prearm_delay_s + ESTIMATOR_AFTER_ARMABLE_S)

    def velocity_target(self, v: VehicleCore, velocity: tuple[float, float, float]) -> None:
        super().velocity_target(v, velocity)
        if v.mode == "OFFBOARD" and v.braking_accel is not None:
            # Re-entering OFFBOARD (after a failsafe) keeps the stop, not an old target.
            self._offboard_target = v.model.target

    def param_to_wire(self, value: float, ptype: int) -> float:
        if ptype == PARAM_INT32:
            return float(struct.unpack("<f", struct.pack("<i", int(value)))[0])
        return float(value)

    def param_from_wire(self, raw: float, ptype: int) -> float:
        if ptype == PARAM_INT32:
            return float(struct.unpack("<i", struct.pack("<f", raw))[0])
        return float(raw)

    # -- arming and time --------------------------------------------------------------

    def streaming(self, v: VehicleCore) -> bool:
        """Setpoints keep coming (within COM_OF_LOSS_T, see OFFBOARD_LOSS_*)."""
        return (
            v.t - self._last_sp_t <= OFFBOARD_LOSS_S
            or v.wall() - self._last_sp_wall <= OFFBOARD_LOSS_WALL_S
        )

    def armable(self, v: VehicleCore) -> bool:
        # OFFBOARD without a stream is not "armable in the current mode".
        return not (v.mode == "OFFBOARD" and not self.streaming(v))

    def arming_refused(self, v: VehicleCore) -> int:
        v.text("Arming denied: Resolve system health failures first", SEV_CRITICAL)
        v.text(v.prearm_reason(), SEV_CRITICAL)
        return TEMPORARILY_REJECTED

    def on_step(self, v: VehicleCore) -> None:
        model = v.model
        if v.mode == "OFFBOARD" and v.armed and not self.streaming(v):
            # COM_OF_LOSS_T passed: failsafe (COM_OBL_RC_ACT = 5: hold).
            self._failsafe = True
            v.mode = "HOLD"
            model.hold()
            v.log.info("vehicle.mode", mode="HOLD", by="failsafe", t_sim=round(v.t, 3))
            v.text("Failsafe activated: no offboard signal, holding", SEV_CRITICAL)
        if v.mode == "AUTO.TAKEOFF" and v.armed and self._takeoff_z is not None:
            x, y, z = model.position
            if model.target is None or model.landed:
                v.steer(x, y, self._takeoff_z)
            if abs(z - self._takeoff_z) < 0.1 and model.state.speed_mps < 0.2:
                self._takeoff_z = None
                v.enter_mode("HOLD", "takeoff complete")

    def after_disarm(self, v: VehicleCore) -> None:
        if v.mode in ("AUTO.LAND", "AUTO.TAKEOFF"):
            v.mode = "HOLD"  # PX4 returns to HOLD after a landing
        self._takeoff_z = None

    # -- modes ------------------------------------------------------------------------

    def set_mode(self, v: VehicleCore, p: tuple[float, ...]) -> str | int:
        main, sub = param_int(p[1]), param_int(p[2])
        if main == 4 and sub == 0:
            sub = 3  # AUTO without a sub mode: PX4 takes LOITER
        mode = _BY_NUMBERS.get((main, sub))
        if mode is None:
            return DENIED
        if mode == v.mode:
            return mode
        if mode == "OFFBOARD" and (v.armed or not v.model.landed) and not self.streaming(v):
            v.text("Switching to Offboard is currently not available", SEV_CRITICAL)
            return TEMPORARILY_REJECTED
        if mode in _RC_MODES:
            v.text("Switching to mode not possible: no RC", SEV_CRITICAL)
            return TEMPORARILY_REJECTED
        if mode == "AUTO.MISSION":
            v.text("Mission rejected: no mission", SEV_CRITICAL)
            return DENIED
        if mode == "AUTO.TAKEOFF":
            self._takeoff_z = v.params.value("MIS_TAKEOFF_ALT")
        return mode

    def mode_entered(self, v: VehicleCore, mode: str) -> bool:
        self._failsafe = False
        if mode in ("OFFBOARD", "AUTO.TAKEOFF"):
            self.apply_mode_target(v)
            return True
        return False

    def apply_mode_target(self, v: VehicleCore) -> None:
        if not v.armed:
            return
        if v.mode == "OFFBOARD" and self._offboard_target is not None:
            v.steer(*self._offboard_target)
        elif v.mode == "AUTO.TAKEOFF" and self._takeoff_z is not None:
            x, y, _ = v.model.position
            v.steer(x, y, self._takeoff_z)

    # -- commands and targets -----------------------------------------------------------

    def takeoff(self, v: VehicleCore, p: tuple[float, ...]) -> int:
        alt = p[6]
        height = (
            alt - v.options.home[2] if math.isfinite(alt) else v.params.value("MIS_TAKEOFF_ALT")
        )
        if height < 0.5:
            return DENIED
        self._takeoff_z = height
        v.enter_mode("AUTO.TAKEOFF", "takeoff command")
        v.text(f"Takeoff to {height:.1f} meters above home started")
        return ACCEPTED

    def landing(self, v: VehicleCore) -> None:
        v.text("Landing at current position")

    def reposition_mode(
        self, v: VehicleCore, p: tuple[float, ...], target: tuple[float, float, float]
    ) -> int | None:
        if v.mode != "HOLD":
            v.enter_mode("HOLD", "reposition")
        return None

    def setpoint(self, v: VehicleCore) -> None:
        self._last_sp_t, self._last_sp_wall = v.t, v.wall()

    # -- manoeuvres ------------------------------------------------------------------------

    def rtl_alt_m(self, v: VehicleCore) -> float:
        return v.params.value("RTL_RETURN_ALT")

    def setpoint_yaw(self, v: VehicleCore, heading_deg: float) -> None:
        if v.mode == "OFFBOARD" and v.armed:
            v.manoeuvres.yaw_to(heading_deg)

    def orbit(self, v: VehicleCore, p: tuple[float, ...], frame: int | None) -> int:
        # param1 radius (positive: clockwise), param2 tangential speed (NaN: MPC_XY_CRUISE),
        # x/y the centre (COMMAND_INT: degrees * 1e7).
        radius, speed, lat, lon = p[0], p[1], p[4], p[5]
        if not v.armed or v.model.landed or not math.isfinite(radius) or abs(radius) < 1.0:
            return DENIED
        if frame is not None:
            lat, lon = lat / 1e7, lon / 1e7
        if not (math.isfinite(lat) and math.isfinite(lon)):
            return DENIED
        if not math.isfinite(speed) or speed <= 0:
            speed = v.params.value("MPC_XY_CRUISE")
        cx, cy, _ = v.frame.from_lla(lat, lon, 0.0)
        v.enter_mode("ORBIT", "orbit command")
        v.manoeuvres.speed_override_mps = min(speed, v.params.value("MPC_XY_VEL_MAX"))
        v.manoeuvres.start_orbit(v, Orbit(cx, cy, abs(radius), speed, clockwise=radius > 0))
        return ACCEPTED

    # -- the geofence ---------------------------------------------------------------------------

    def fence_limits(self, v: VehicleCore) -> FenceLimits | None:
        value = v.params.value
        if param_int(value("GF_ACTION")) == 0:
            return None
        ceiling, radius = value("GF_MAX_VER_DIST"), value("GF_MAX_HOR_DIST")
        return FenceLimits(
            ceiling_m=ceiling if ceiling > 0 else None,
            radius_m=radius if radius > 0 else None,
        )

    def fence_breached(self, v: VehicleCore, kind: str) -> None:
        if kind == "altitude":
            v.text("Geofence violation: exceeding maximum altitude above Home", SEV_CRITICAL)
        else:
            v.text("Geofence violation: approaching or outside geofence", SEV_CRITICAL)
        # GF_ACTION: 1 warning, 2 hold, 3 return, 4 terminate, 5 land.
        action = param_int(v.params.value("GF_ACTION"))
        if action < 2:
            return
        v.text("Failsafe activated", SEV_CRITICAL)
        if action == 2:
            # PX4 main held about 1 m past the fence it crossed at 6 m/s (its SITL):
            # it brakes, then comes back to about where it crossed.
            here = v.model.position
            v.enter_mode("HOLD", "geofence")
            v.steer(*here)
        elif action == 3:
            v.enter_mode("AUTO.RTL", "geofence")
        elif action == 4:
            v.disarm("Flight termination active", force=True)
        else:
            v.enter_mode("AUTO.LAND", "geofence")

    def position_target(self, v: VehicleCore, target: tuple[float, float, float]) -> None:
        self._offboard_target = target
        if self._failsafe and v.mode == "HOLD":
            # PX4 returns to OFFBOARD by itself once setpoints resume.
            v.enter_mode("OFFBOARD", "setpoints resumed")
            v.text("Failsafe deactivated: offboard signal regained", SEV_NOTICE)
        elif v.mode == "OFFBOARD" and v.armed:
            v.steer(*target)


__all__ = ["Px4Personality"]
