"""The simulated MAVLink vehicle's core: state, simulated time, modes and parameters.

:class:`VehicleCore` is what PX4 SITL and ArduCopter SITL have in common: the
kinematic model, arming and disarming (pre-arm delay, automatic disarm before
take-off and after touchdown, forced disarm), modes, parameters
(:class:`ParamTable`), the fence it enforces
(:class:`~eamos.hal.sitl.fence.FenceWatch`) and STATUSTEXT; the messages that
act on it are decoded by :mod:`eamos.hal.sitl.inbox`.  Everything that differs
between the two is asked of its :class:`Personality` (:mod:`eamos.hal.sitl.px4`,
:mod:`eamos.hal.sitl.ardupilot`): mode names and numbers, arming rules
and texts, take-off, landing and repositioning, setpoint streams, the fence's
limits and a breach's reaction, parameters and their wire encoding.

The core owns no thread and no connection: its owner
(:class:`eamos.hal.sitl.vehicle.SimVehicle`) feeds it messages (through an
:class:`~eamos.hal.sitl.inbox.Inbox`), steps it
(:meth:`VehicleCore.step`) and gives it a ``send`` function.  The only clock
it reads is the injected ``wall`` clock (PX4's setpoint-loss check also counts
wall seconds).
"""

from __future__ import annotations

import math
import random
import time
from collections.abc import Callable, Mapping
from dataclasses import replace
from typing import TYPE_CHECKING, Any

from eamos.hal.kinematics import GeoFrame, Limits, Quadcopter
from eamos.hal.sim.core import SIM_DT_S
from eamos.hal.sitl.fence import FenceLimits, FenceWatch, Geofence
from eamos.hal.sitl.manoeuvres import Manoeuvres
from eamos.hal.sitl.missions import FENCE, MISSION, Dialect, MissionServer
from eamos.hal.sitl.params import Param, Params, ParamTable
from eamos.hal.sitl.payload import CameraGimbal
from eamos.hal.sitl.streams import Identity, Send, Status, Streams
from eamos.hal.sitl.wire import (
    BOOT_S,
    ESTIMATOR_SETTLED_FLAGS,
    ESTIMATOR_UNSETTLED_FLAGS,
    LAND_DISARM_S,
    PREARM_TEXT_PERIOD_S,
    SEV_CRITICAL,
    SEV_INFO,
    STATUSTEXT_LEN,
    UNSUPPORTED,
    AutopilotName,
    VehicleOptions,
)

if TYPE_CHECKING:
    from eamos.logs import EventLog

#: Modes in which the vehicle lands, and returns to launch (either autopilot's names).
LAND_MODES = frozenset({"AUTO.LAND", "LAND"})
RTL_MODES = frozenset({"AUTO.RTL", "RTL"})
#: LAND while moving brakes gently: ArduCopter touched down ~10 m past the point at
#: 5 m/s, PX4 ~14 m at 6 m/s (the notes); this deceleration gives 10 and 14.4 m.
LAND_DECEL_MPS2 = 1.25
#: Descent speed in LAND (ArduCopter LAND_SPEED 50 cm/s, PX4 MPC_LAND_SPEED 0.7 m/s).
LAND_SPEED_MPS = 0.7
#: GIMBAL_DEVICE_ATTITUDE_STATUS period (simulated seconds).
GIMBAL_STATUS_PERIOD_S = 0.2
#: The wandering estimate's correlation time (seconds): slow, like an EKF's drift.
WANDER_TAU_S = 2.0


def stopping_point(
    position: tuple[float, float, float], velocity: tuple[float, float, float], accel: float
) -> tuple[float, float, float]:
    """Where a vehicle braking at ``accel`` from ``velocity`` comes to rest (pure)."""
    return tuple(  # type: ignore[return-value]
        p + v * abs(v) / (2.0 * accel) for p, v in zip(position, velocity, strict=True)
    )


class Personality:
    """What one autopilot does differently; subclasses answer for PX4 and ArduPilot.

    One instance per vehicle: a personality may keep state of its own (PX4's
    setpoint stream, ArduPilot's boot announcement).  Methods receive the
    :class:`VehicleCore` they act on.
    """

    name: AutopilotName
    #: HEARTBEAT.autopilot (MAV_AUTOPILOT).
    mav_autopilot: int
    #: AUTOPILOT_VERSION capabilities and flight software version.
    capabilities: int
    version: int
    #: The mode it boots in, and the mode names it knows.
    initial_mode: str
    modes: Mapping[str, Any]
    #: LOCAL_POSITION_NED z of the ground unless the options say otherwise.
    default_ground_offset_m: float = 0.0
    #: What it streams unasked (message id -> Hz, simulated time).
    default_rates: Mapping[int, float]
    #: Its estimator report (ESTIMATOR_STATUS or EKF_STATUS_REPORT).
    estimator_msg: int
    #: The MAV_RESULT of a refused command (PX4 DENIED, ArduPilot FAILED).
    refused: int
    #: Whether REQUEST_DATA_STREAM is understood.
    data_streams: bool = False
    #: Whether MAV_CMD_DO_REPOSITION is understood as COMMAND_LONG too (not only COMMAND_INT).
    reposition_long: bool = True
    #: The mode MAV_CMD_NAV_LAND switches to.
    land_mode: str
    #: How it speaks the mission protocol (:mod:`eamos.hal.sitl.missions`).
    mission_dialect: Dialect
    #: STATUSTEXT narration.
    text_armable: str
    text_not_ready: str
    text_armed: str
    text_disarmed: str
    text_preflight_disarm: str
    text_touchdown: str
    text_land_disarm: str
    text_disarm_in_air: str
    text_mode_not_armable: str

    def custom_mode(self, mode: str) -> int:
        """HEARTBEAT.custom_mode of ``mode``."""
        raise NotImplementedError

    def speeds(self, v: VehicleCore) -> tuple[float, float, float]:
        """Horizontal, climb and descent speed limits now (from its parameters)."""
        raise NotImplementedError

    def accel(self, v: VehicleCore) -> float:
        """The horizontal acceleration its position controller uses (from its parameters)."""
        raise NotImplementedError

    def stop_accel(self, v: VehicleCore) -> float:
        """The deceleration of a zero-velocity target (its fastest documented stop)."""
        return self.accel(v)

    def preflight_disarm_s(self, v: VehicleCore) -> float:
        """Armed on the ground without a take-off, disarm after this (<= 0: never)."""
        raise NotImplementedError

    #: Seconds from touchdown until it reports being on the ground (its land detector).
    land_detect_s: float = 1.5

    def land_speed(self, v: VehicleCore) -> float:
        """The descent speed in its land mode (from its parameters)."""
        return LAND_SPEED_MPS

    def land_disarm_s(self, v: VehicleCore) -> float:
        """Seconds from reporting on the ground until it disarms by itself."""
        return LAND_DISARM_S

    def liftoff_delay_s(self, v: VehicleCore) -> float:
        """Seconds from being told to climb (armed, on the ground) until it leaves it."""
        return 0.0

    def estimator_settle_s(self, options: VehicleOptions) -> float:
        """When its estimator settles unless the options say (simulated seconds from start)."""
        return options.prearm_delay_s

    #: The mode in which it follows a companion's position and velocity targets.
    target_mode: str

    def velocity_target(self, v: VehicleCore, velocity: tuple[float, float, float]) -> None:
        """A velocity target (model frame).  Only "stop" (all zero) is simulated: the vehicle
        brakes at :meth:`stop_accel` to where that stops it; other velocities are ignored."""
        if (
            v.armed
            and not v.model.landed
            and v.mode == self.target_mode
            and max(abs(c) for c in velocity) < 0.05
        ):
            v.stop_at(self.stop_accel(v))

    def initial_params(self, options: VehicleOptions) -> Params:
        """The parameters it answers PARAM_REQUEST_LIST with."""
        raise NotImplementedError

    def param_to_wire(self, value: float, ptype: int) -> float:
        """A parameter's value as PARAM_VALUE carries it."""
        return float(value)

    def param_from_wire(self, raw: float, ptype: int) -> float:
        """A PARAM_SET value as the parameter's value."""
        return float(raw)

    def ready(self, v: VehicleCore) -> bool:
        """Booted far enough to arm (besides the pre-arm delay)."""
        return True

    def armable(self, v: VehicleCore) -> bool:
        """Mode-dependent arming condition (PX4: OFFBOARD needs a setpoint stream)."""
        return True

    def boot(self, v: VehicleCore) -> None:
        """Its boot sequence, first thing each simulated step (ArduPilot: "Ready")."""

    def on_step(self, v: VehicleCore) -> None:
        """Its own behaviour each step, after the pre-arm narration, before the model moves."""

    def arming_refused(self, v: VehicleCore) -> int:
        """Narrate why an unready vehicle cannot arm; the MAV_RESULT."""
        raise NotImplementedError

    def set_mode(self, v: VehicleCore, p: tuple[float, ...]) -> str | int:
        """MAV_CMD_DO_SET_MODE: the mode to enter, or the MAV_RESULT refusing it."""
        raise NotImplementedError

    def mode_entered(self, v: VehicleCore, mode: str) -> bool:
        """A mode was entered; True if this personality set the vehicle's target for it."""
        return False

    def apply_mode_target(self, v: VehicleCore) -> None:
        """Armed (or re-entering a mode): steer to the current mode's own target, if any."""

    def after_disarm(self, v: VehicleCore) -> None:
        """Bookkeeping after disarming."""

    def takeoff(self, v: VehicleCore, p: tuple[float, ...]) -> int:
        """MAV_CMD_NAV_TAKEOFF: the MAV_RESULT."""
        raise NotImplementedError

    def landing(self, v: VehicleCore) -> None:
        """MAV_CMD_NAV_LAND accepted: narrate it."""

    def reposition_mode(
        self, v: VehicleCore, p: tuple[float, ...], target: tuple[float, float, float]
    ) -> int | None:
        """Enter the mode a reposition to ``target`` flies in; a MAV_RESULT if it is refused."""
        raise NotImplementedError

    def setpoint(self, v: VehicleCore) -> None:
        """A SET_POSITION_TARGET_* arrived (setpoint streams count them)."""

    def position_target(self, v: VehicleCore, target: tuple[float, float, float]) -> None:
        """A position target in the model frame: fly there if the mode follows targets."""
        raise NotImplementedError

    # -- manoeuvres (eamos.hal.sitl.manoeuvres); UNSUPPORTED unless the autopilot has them --

    def rtl_alt_m(self, v: VehicleCore) -> float:
        """The return altitude (m above home) from its parameters."""
        raise NotImplementedError

    def setpoint_yaw(self, v: VehicleCore, heading_deg: float) -> None:
        """A setpoint carried a yaw (PX4 OFFBOARD follows it)."""

    def condition_yaw(self, v: VehicleCore, p: tuple[float, ...]) -> int:
        """MAV_CMD_CONDITION_YAW: the MAV_RESULT."""
        return UNSUPPORTED

    def orbit(self, v: VehicleCore, p: tuple[float, ...], frame: int | None) -> int:
        """MAV_CMD_DO_ORBIT: the MAV_RESULT."""
        return UNSUPPORTED

    def change_speed(self, v: VehicleCore, p: tuple[float, ...]) -> int:
        """MAV_CMD_DO_CHANGE_SPEED: the MAV_RESULT."""
        return UNSUPPORTED

    # -- geofence (eamos.hal.sitl.fence: its FencePolicy) --------------------------------------

    def fence_limits(self, v: VehicleCore) -> FenceLimits | None:
        """What its fence parameters enable now; None: no fence is enforced."""
        return None

    def fence_breached(self, v: VehicleCore, kind: str) -> None:
        """The vehicle just left its fence (``kind``: altitude, circle, polygon): react."""

    def fence_cleared(self, v: VehicleCore) -> None:
        """The vehicle is back inside its fence."""

    def armable_announced(self, v: VehicleCore) -> None:
        """The pre-arm checks just passed (ArduPilot: home and origin are set then)."""

    def coordinates_refused(self, v: VehicleCore) -> int | None:
        """MAV_CMD_DO_REPOSITION to a latitude or longitude out of range: the MAV_RESULT,
        or None if it accepts it (and the vehicle then holds where it is)."""
        return None


class VehicleCore:
    """One simulated MAVLink vehicle without thread or connection (see module docstring)."""

    def __init__(
        self,
        options: VehicleOptions,
        personality: Personality,
        log: EventLog,
        send: Send,
        wall: Callable[[], float] = time.monotonic,
    ) -> None:
        o = options
        self.options = options
        self.p = personality
        self.log = log
        self.wall = wall
        self.frame = GeoFrame(*o.home)
        self.model = Quadcopter(o.limits)
        # Set by a brake (BRAKE mode, a zero-velocity target) until the next target.
        self.braking_accel: float | None = None
        self.manoeuvres = Manoeuvres()  # heading, return to launch, orbits
        self.camera = CameraGimbal()  # photos, video, the gimbal
        self._next_gimbal_status = BOOT_S
        self._rng = random.Random(o.seed)
        self.wander: list[float] = [0.0] * 6  # estimate error: x y z (m), vx vy vz (m/s)
        self.offset_m = (
            o.ground_offset_m
            if o.ground_offset_m is not None
            else personality.default_ground_offset_m
        )
        self._send = send
        self.t = 0.0  # simulated seconds since start
        self.armed = False
        self.armed_at = 0.0
        self.flew = False  # left the ground (or was told to) since arming
        self.touchdown_at: float | None = None
        self._climb_asked_at: float | None = None  # told to climb while on the ground
        self._touchdown_told = True
        self.move_m = 0.0  # the length of the current move (from where it was steered)
        self.move_from_mps = 0.0  # the speed it had when that move began
        self._was_landed = True
        self.mode = personality.initial_mode
        self._armable_announced = False
        self._next_prearm_text = BOOT_S
        self._text_id = 0
        self.params = ParamTable(personality, personality.initial_params(o), log, send)
        self._next_position_log = 0.0
        self._last_position_key: tuple[float | bool | str, ...] | None = None
        identity = Identity(
            personality.mav_autopilot,
            personality.capabilities,
            personality.version,
            o.sysid,
            personality.estimator_msg,
        )
        self.settle_s = (
            o.estimator_settle_s
            if o.estimator_settle_s is not None
            else personality.estimator_settle_s(o)
        )
        self.streams = Streams(identity, personality.default_rates, o, self.offset_m, send)
        self.missions = MissionServer(
            personality.mission_dialect, send, lambda: o.home, self._missions_changed
        )
        self.fence = FenceWatch(self, personality)

    # -- sending -------------------------------------------------------------------------

    def send(self, message: str, *args: Any) -> None:
        """Send one MAVLink message (by its pymavlink name)."""
        self._send(message, *args)

    def text(self, text: str, severity: int = SEV_INFO) -> None:
        """STATUSTEXT (in chunks sharing an id when longer than one message)."""
        self.log.info("vehicle.statustext", text=text, t_sim=round(self.t, 3))
        if len(text) <= STATUSTEXT_LEN:
            self.send("statustext", severity, text.encode(), 0, 0)
            return
        self._text_id = self._text_id % 65535 + 1
        chunks = [text[i : i + STATUSTEXT_LEN] for i in range(0, len(text), STATUSTEXT_LEN)]
        for seq, chunk in enumerate(chunks):
            self.send("statustext", severity, chunk.encode(), self._text_id, seq)

    def status(self) -> Status:
        """The vehicle as its streams see it now."""
        error = list(self.wander)
        bias = self.estimator_bias()
        error[0] += bias
        error[1] += bias
        erring = self.options.wander_m > 0 or bias != 0.0
        return Status(
            self.t,
            self.model.state,
            self.mode,
            self.p.custom_mode(self.mode),
            self.armed,
            self.armable(),
            (tuple(error) if erring else None),  # type: ignore[arg-type]
            ESTIMATOR_SETTLED_FLAGS if self.estimator_settled() else ESTIMATOR_UNSETTLED_FLAGS,
            self.manoeuvres.heading_deg,
            (self.missions.current, len(self.missions.lists[MISSION])),
            self.p.fence_limits(self) is not None,
            self.fence.breach is not None,
            self.on_ground,
        )

    def estimator_settled(self) -> bool:
        """The estimator's flags are all good (``settle_s`` after start)."""
        return self.t >= self.settle_s

    def estimator_bias(self) -> float:
        """The unsettled estimate's north and east error (m): ``estimator_bias_m`` at start,
        shrinking linearly to 0 when the estimator settles."""
        bias = self.options.estimator_bias_m
        if bias <= 0 or self.estimator_settled() or not math.isfinite(self.settle_s):
            return 0.0
        return bias * (1.0 - self.t / self.settle_s) / math.sqrt(2.0)

    def send_due(self) -> None:
        """Send the HEARTBEAT and the streams that are due."""
        self.streams.send_due(self.status())
        if self.t >= self._next_gimbal_status:
            # A gimbal device broadcasts its attitude by itself (GIMBAL_STATUS_PERIOD_S).
            self._next_gimbal_status = self.t + GIMBAL_STATUS_PERIOD_S
            self.send(*self.camera.attitude_status(self.t))

    # -- simulated time ------------------------------------------------------------------

    def step(self) -> None:
        """Advance one SIM_DT_S step: boot, pre-arm narration, personality, auto-disarm, model."""
        p, model = self.p, self.model
        self.t += SIM_DT_S
        t = self.t
        p.boot(self)
        if self.armable() and not self._armable_announced:
            self._armable_announced = True
            self.text(p.text_armable)
            p.armable_announced(self)
        if not self.armable() and t >= self._next_prearm_text and t >= BOOT_S:
            self._next_prearm_text = t + PREARM_TEXT_PERIOD_S
            self.text(self.prearm_reason(), SEV_CRITICAL)
        p.on_step(self)
        delay = p.preflight_disarm_s(self)
        if self.armed and model.landed and not self.flew and 0 < delay <= t - self.armed_at:
            self.disarm(p.text_preflight_disarm)
        self.manoeuvres.step(self, SIM_DT_S)
        self.camera.step(SIM_DT_S)
        model.limits = self.flight_limits()
        held = self._spooling_up()
        model.step(SIM_DT_S)
        if held is not None:
            model.set_target(*held)
        self._wander()
        if not model.landed:
            self.flew = True
        if model.landed and not self._was_landed:
            self.touchdown_at = t
            self._touchdown_told = False
            if not self.armed and model.armed:
                model.disarm()  # a force-disarmed vehicle has now hit the ground
        if not self._touchdown_told and self.touchdown_at is not None and self.on_ground:
            self._touchdown_told = True  # when its land detector says so
            self.text(p.text_touchdown, SEV_INFO)
        self._was_landed = model.landed
        self.fence.check()
        self.missions.tick(self.wall())
        if (
            self.touchdown_at is not None
            and self.armed
            and model.landed
            and t - self.touchdown_at >= p.land_detect_s + p.land_disarm_s(self)
        ):
            self.disarm(p.text_land_disarm)
        self._log_position()

    # -- geofence (FenceWatch) --------------------------------------------------------------

    def _missions_changed(self, mission_type: int) -> None:
        if mission_type == FENCE:
            self.fence.load(self.missions.items(FENCE))

    @property
    def geofence(self) -> Geofence:
        """The fence uploaded to the vehicle (empty: none)."""
        return self.fence.geofence

    def outside_fence(self, point: tuple[float, float, float]) -> str | None:
        """What of the enforced fence ``point`` is outside of (altitude, circle, polygon)."""
        return self.fence.outside(point)

    def _spooling_up(self) -> tuple[float, float, float] | None:
        """Told to climb from the ground: the target, withheld for this step while the motors
        spool up (the personality's lift-off delay); None when the model may move."""
        model = self.model
        target = model.target
        if not (self.armed and model.landed and target is not None and target[2] > 0):
            self._climb_asked_at = None
            return None
        if self._climb_asked_at is None:
            self._climb_asked_at = self.t
            self.flew = True  # taking off: no preflight auto-disarm while the motors spool up
        if self.t - self._climb_asked_at >= self.p.liftoff_delay_s(self):
            return None
        model.hold()
        return target

    @property
    def on_ground(self) -> bool:
        """Landed as its land detector says: on the ground for ``land_detect_s`` (or since boot)."""
        if not self.model.landed:
            return False
        return self.touchdown_at is None or self.t - self.touchdown_at >= self.p.land_detect_s

    def flight_limits(self) -> Limits:
        """The model's limits now: the autopilot's speed parameters, the mode's deceleration."""
        horizontal, climb, descent = self.p.speeds(self)
        if self.manoeuvres.speed_override_mps is not None:
            horizontal = self.manoeuvres.speed_override_mps
        accel = self.braking_accel or self.p.accel(self)
        if self.mode in LAND_MODES:
            accel, descent = LAND_DECEL_MPS2, self.p.land_speed(self)
        return replace(
            self.options.limits,
            horizontal_speed_mps=max(horizontal, 0.05),
            climb_speed_mps=max(climb, 0.05),
            descent_speed_mps=max(descent, 0.05),
            accel_mps2=accel,
        )

    def stop_at(self, accel: float, ground: bool = False) -> None:
        """Brake at ``accel`` to where that stops the vehicle (``ground``: then descend)."""
        st = self.model.state
        if self.model.landed:
            return
        x, y, z = stopping_point((st.x_m, st.y_m, st.z_m), (st.vx_mps, st.vy_mps, st.vz_mps), accel)
        self.model.set_target(x, y, 0.0 if ground else z)
        self.braking_accel = accel

    def steer(self, x: float, y: float, z: float) -> None:
        """A new position target: the autopilot's own acceleration applies again."""
        self.braking_accel = None
        new = (x, y, max(z, 0.0))
        old = self.model.target
        if old is None or math.dist(old, new) > 0.01:
            # A new move (a target re-sent every second, as the adapter does, is not).
            self.move_m = math.dist(self.model.position, new)
            self.move_from_mps = self.model.state.speed_mps
        self.model.set_target(x, y, z)

    def _wander(self) -> None:
        """Advance the estimate's error: an Ornstein-Uhlenbeck walk of ``wander_m`` spread."""
        sigma = self.options.wander_m
        if sigma <= 0:
            return
        k = SIM_DT_S / WANDER_TAU_S
        scale = math.sqrt(2.0 * k)
        for i in range(6):
            spread = sigma if i < 3 else sigma * 0.6
            if i in (2, 5):
                spread *= 0.3  # the height wanders less than the horizontal position
            self.wander[i] += -self.wander[i] * k + spread * scale * self._rng.gauss(0.0, 1.0)

    def armable(self) -> bool:
        """Pre-arm checks pass: booted, past the pre-arm delay, the personality agrees."""
        if self.t < max(BOOT_S, self.options.prearm_delay_s) or not self.p.ready(self):
            return False
        return self.p.armable(self)

    def prearm_reason(self) -> str:
        """Why the vehicle cannot arm yet (its STATUSTEXT)."""
        if self.t < self.options.prearm_delay_s:
            return self.p.text_not_ready
        return "Preflight Fail: no offboard setpoints"

    # -- state changes ---------------------------------------------------------------------

    def arm(self) -> None:
        """Arm the motors."""
        self.armed = True
        self.armed_at = self.t
        self.flew = False
        self.touchdown_at = None
        self.model.arm()
        self.log.info("vehicle.armed", armed=True, t_sim=round(self.t, 3))
        self.text(self.p.text_armed)
        self.p.apply_mode_target(self)

    def disarm(self, text: str, force: bool = False) -> None:
        """Disarm; in the air the vehicle falls (the model descends) to the ground."""
        self.armed = False
        self.touchdown_at = None
        if self.model.landed:
            self.model.disarm()
        else:
            self.model.land()
        self.log.info("vehicle.armed", armed=False, forced=force, t_sim=round(self.t, 3))
        self.text(text)
        self.p.after_disarm(self)

    def enter_mode(self, mode: str, by: str) -> None:
        """Switch to ``mode`` (by a command, the pilot, a failsafe) and steer accordingly."""
        self.mode = mode
        self.log.info("vehicle.mode", mode=mode, by=by, t_sim=round(self.t, 3))
        model = self.model
        self.manoeuvres.mode_changed()
        if self.p.mode_entered(self, mode):
            return
        self.braking_accel = None
        if mode in LAND_MODES:
            # LAND brakes gently from wherever the vehicle flies, descending meanwhile.
            self.stop_at(LAND_DECEL_MPS2, ground=True)
            if model.landed and self.armed:
                self.touchdown_at = self.t  # already down: disarm soon
        elif mode in RTL_MODES:
            # Over the boot point at max(current height, return altitude), then land there.
            self.manoeuvres.start_rtl(self, self.p.rtl_alt_m(self))
        else:
            model.hold()  # HOLD, LOITER, BRAKE, GUIDED, POSCTL...: stop where it is

    # -- log -----------------------------------------------------------------------------------

    def _log_position(self) -> None:
        if self.t < self._next_position_log:
            return
        self._next_position_log = self.t + 1.0
        st = self.model.state
        key = (round(st.x_m, 2), round(st.y_m, 2), round(st.z_m, 2), self.armed, self.mode)
        if key != self._last_position_key:
            self._last_position_key = key
            self.log.info(
                "vehicle.position",
                x_m=key[0],
                y_m=key[1],
                z_m=key[2],
                armed=self.armed,
                mode=self.mode,
                t_sim=round(self.t, 3),
            )


__all__ = [
    "LAND_DECEL_MPS2",
    "LAND_MODES",
    "RTL_MODES",
    "FenceLimits",
    "Param",
    "ParamTable",
    "Params",
    "Personality",
    "VehicleCore",
    "stopping_point",
]
