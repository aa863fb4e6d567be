"""What differs between PX4 and ArduPilot for the MAVLink adapter (and the simulated vehicle).

Both autopilots speak MAVLink, but they fly a companion computer's commands
in different ways (docs/flying-real-drones.md, "PX4 SITL" and "ArduPilot SITL"):

* PX4 follows position setpoints only in OFFBOARD mode, and only while they
  keep streaming (a second without one is a failsafe).  Taking off is just a
  setpoint above the ground; the stream must run before OFFBOARD is chosen.
* ArduPilot follows position targets in GUIDED mode; they need not stream.
  It takes off with MAV_CMD_NAV_TAKEOFF, and only in GUIDED mode.

An :class:`Autopilot` holds the mode tables and turns a flight step (prepare
to arm, take off, go to a point, hold, land) into calls on a
:class:`Controller`, which the adapter implements for one running action (so
every wait in there can be cancelled).  Nothing in this module waits or
owns a thread.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from typing import Literal, Protocol

from eamos.hal.mavlink.frames import Vector

#: HEARTBEAT.autopilot values (MAV_AUTOPILOT).
MAV_AUTOPILOT_ARDUPILOTMEGA = 3
MAV_AUTOPILOT_PX4 = 12
#: MAVLink command ids used here (MAV_CMD).
MAV_CMD_NAV_TAKEOFF = 22
MAV_CMD_NAV_LAND = 21
#: DO_SET_MODE param1 flag: "custom_mode is valid" (MAV_MODE_FLAG_CUSTOM_MODE_ENABLED).
MAV_MODE_FLAG_CUSTOM_MODE_ENABLED = 1

#: PX4 modes by name: (main mode, sub mode); custom_mode = main << 16 | sub << 24.
PX4_MODES: dict[str, tuple[int, int]] = {
    "MANUAL": (1, 0),
    "ALTCTL": (2, 0),
    "POSCTL": (3, 0),
    "ORBIT": (3, 1),  # POSCTL's Orbit sub mode: MAV_CMD_DO_ORBIT flies in it
    "AUTO.READY": (4, 1),
    "AUTO.TAKEOFF": (4, 2),
    "HOLD": (4, 3),  # AUTO.LOITER; PX4's boot mode
    "AUTO.MISSION": (4, 4),
    "AUTO.RTL": (4, 5),
    "AUTO.LAND": (4, 6),
    "ACRO": (5, 0),
    "OFFBOARD": (6, 0),
    "STABILIZED": (7, 0),
}

#: ArduCopter modes by name: custom_mode.
ARDUCOPTER_MODES: dict[str, int] = {
    "STABILIZE": 0,
    "ACRO": 1,
    "ALT_HOLD": 2,
    "AUTO": 3,
    "GUIDED": 4,
    "LOITER": 5,
    "RTL": 6,
    "CIRCLE": 7,
    "LAND": 9,
    "DRIFT": 11,
    "SPORT": 13,
    "AUTOTUNE": 15,
    "POSHOLD": 16,
    "BRAKE": 17,
    "THROW": 18,
    "GUIDED_NOGPS": 20,
    "SMART_RTL": 21,
}


def px4_custom_mode(main: int, sub: int = 0) -> int:
    """PX4's HEARTBEAT.custom_mode for a main/sub mode pair."""
    return (main << 16) | (sub << 24)


def px4_mode_of(custom_mode: int) -> tuple[int, int]:
    """The (main, sub) pair encoded in a PX4 custom_mode."""
    return (custom_mode >> 16) & 0xFF, (custom_mode >> 24) & 0xFF


_PX4_BY_CUSTOM = {px4_custom_mode(*pair): name for name, pair in PX4_MODES.items()}
_ARDU_BY_CUSTOM = {value: name for name, value in ARDUCOPTER_MODES.items()}


class CommandRejected(Exception):
    """A vehicle answered a command with something other than MAV_RESULT_ACCEPTED."""

    def __init__(self, command: str, result: str, statustext: str = "") -> None:
        self.command = command
        self.result = result
        self.statustext = statustext
        why = f": {statustext}" if statustext else ""
        super().__init__(f"{command} rejected with {result}{why}")


class Controller(Protocol):
    """What an :class:`Autopilot` needs from the adapter while one action runs.

    Every method may raise the adapter's own "action ended" exceptions (the
    action was cancelled, the link was lost); :meth:`command` and
    :meth:`set_mode` raise :class:`CommandRejected` when the vehicle says no.
    """

    def mode(self) -> str:
        """The vehicle's current mode name, from its latest HEARTBEAT."""
        ...

    def set_mode(self, mode: str) -> None:
        """Request ``mode`` with MAV_CMD_DO_SET_MODE and wait until a HEARTBEAT shows it."""
        ...

    def command(self, command: int, params: tuple[float, ...], frame: int | None = None) -> None:
        """Send COMMAND_LONG (7 params; COMMAND_INT in ``frame``), wait for ACCEPTED."""
        ...

    def stream(self, target_ned: Vector | None) -> None:
        """Set the target of the continuous setpoint stream (None stops it)."""
        ...

    def wait_stream_warm(self, seconds: float) -> None:
        """Return once the setpoint stream has been running for ``seconds``."""
        ...

    def position_target(self, target_ned: Vector) -> None:
        """Send SET_POSITION_TARGET_LOCAL_NED (position only) and keep it refreshed."""
        ...

    def set_yaw(self, heading_deg: float) -> None:
        """Let every target from now on carry the compass heading ``heading_deg``."""
        ...

    def global_target(self, lat_deg: float, lon_deg: float, rel_alt_m: float) -> None:
        """Send SET_POSITION_TARGET_GLOBAL_INT (relative altitude) and keep it refreshed."""
        ...

    def amsl_m(self, height_m: float) -> float:
        """Altitude above mean sea level of a point ``height_m`` above the take-off ground."""
        ...


TakeoffMode = Literal["offboard", "auto"]


class Autopilot(ABC):
    """One autopilot family's modes and flight steps (see module docstring)."""

    #: Short name used in settings and logs ("px4", "ardupilot").
    name: str
    #: HEARTBEAT.autopilot value.
    mavlink_id: int
    #: The mode in which the vehicle follows the adapter's position targets.
    motion_mode: str
    #: The mode MAV_CMD_NAV_LAND puts the vehicle in.
    land_mode: str
    #: Completion of a long move unless the settings say otherwise: within tolerance_m (m;
    #: scaled down for short moves, completion.py), slower than settle_speed_mps (m/s) on
    #: average over settle_s (vehicle s).  Measured on the SITLs (docs/flying-real-drones.md).
    tolerance_m: float = 0.2
    settle_speed_mps: float = 0.2
    settle_s: float = 0.5
    #: A short move's tolerance never goes below this (m): the estimate's own noise.
    min_tolerance_m: float = 0.05
    #: The deceleration a brake plans with (m/s/s): the position target goes where the
    #: vehicle comes to rest at it (braking.py; ArduCopter WPNAV_ACCEL 2.5 m/s/s,
    #: PX4 MPC_ACC_HOR 3 m/s/s by default).
    brake_decel_mps2: float = 2.5

    @abstractmethod
    def mode_name(self, custom_mode: int) -> str:
        """A readable name for a HEARTBEAT custom_mode."""

    @abstractmethod
    def mode_params(self, mode: str) -> tuple[float, float, float]:
        """MAV_CMD_DO_SET_MODE param1..param3 selecting ``mode``."""

    def takeoff_modes(self) -> frozenset[str]:
        """Modes the vehicle may be in while it takes off for us."""
        return frozenset({self.motion_mode})

    @abstractmethod
    def prepare_arm(self, ctl: Controller, here_ned: Vector) -> None:
        """Whatever must happen before MAV_CMD_COMPONENT_ARM_DISARM (mode, streams)."""

    @abstractmethod
    def takeoff(self, ctl: Controller, target_ned: Vector, height_m: float) -> None:
        """Start climbing to ``target_ned`` (``height_m`` above the take-off ground)."""

    @abstractmethod
    def goto(self, ctl: Controller, target_ned: Vector) -> None:
        """Start flying to a local NED point."""

    @abstractmethod
    def goto_global(
        self, ctl: Controller, lat_deg: float, lon_deg: float, rel_alt_m: float, target_ned: Vector
    ) -> None:
        """Start flying to a WGS84 point ``rel_alt_m`` above home (``target_ned``: same point)."""

    @abstractmethod
    def hold(self, ctl: Controller, here_ned: Vector, airborne: bool) -> None:
        """Stay where the vehicle is (after a cancel, once it has come to rest)."""

    def brake(self, ctl: Controller, stop_ned: Vector) -> bool:
        """Stop at ``stop_ned`` (where the vehicle comes to rest braking at
        :attr:`brake_decel_mps2`): a position target in the motion mode.  False when the
        vehicle flies another mode (it then brakes by that mode's own rules).

        Measured on the SITLs at 2 m/s (docs/flying-real-drones.md): ArduCopter's BRAKE
        mode came to rest 3.4 m on, a zero-velocity target 1.8 m (ArduCopter) and 5.6 m
        (PX4), a target at the stopping point 0.9 m and 0.7 m.
        """
        if ctl.mode() != self.motion_mode:
            return False
        self.goto(ctl, stop_ned)
        return True

    @abstractmethod
    def speed_params(self, speed_mps: float) -> tuple[tuple[str, float], ...]:
        """The parameters (and values) that set the horizontal speed."""

    def land(self, ctl: Controller, here_ned: Vector) -> None:
        """Descend and land at the current position (MAV_CMD_NAV_LAND)."""
        nan = math.nan
        # param4 NaN: keep the current yaw; lat/lon/alt NaN: land right here.
        ctl.command(MAV_CMD_NAV_LAND, (0.0, 0.0, 0.0, nan, nan, nan, nan))


class Px4(Autopilot):
    """PX4: OFFBOARD position setpoints streamed continuously (or AUTO.TAKEOFF)."""

    name = "px4"
    mavlink_id = MAV_AUTOPILOT_PX4
    motion_mode = "OFFBOARD"
    land_mode = "AUTO.LAND"
    # PX4 SIH's estimate wanders while hovering (the notes): a longer window averages it.
    tolerance_m = 0.25
    settle_speed_mps = 0.3
    settle_s = 2.0
    # Hovering, PX4 SIH's estimate wanders +-0.5 m at up to 0.8 m/s (measured on the
    # SITL at speed-up 10): a 2 s mean within 8 cm of a point is luck, within 15 cm not.
    min_tolerance_m = 0.15

    #: How long the stream must run before PX4 accepts OFFBOARD (the notes: ~1 s).
    STREAM_WARMUP_S = 1.0

    def __init__(self, takeoff_mode: TakeoffMode = "offboard") -> None:
        self.takeoff_mode: TakeoffMode = takeoff_mode

    def mode_name(self, custom_mode: int) -> str:
        name = _PX4_BY_CUSTOM.get(custom_mode)
        if name is None:
            main, sub = px4_mode_of(custom_mode)
            name = f"PX4({main}/{sub})"
        return name

    def mode_params(self, mode: str) -> tuple[float, float, float]:
        main, sub = PX4_MODES[mode]
        return (float(MAV_MODE_FLAG_CUSTOM_MODE_ENABLED), float(main), float(sub))

    def takeoff_modes(self) -> frozenset[str]:
        if self.takeoff_mode == "auto":
            # AUTO.TAKEOFF switches itself to HOLD once it reaches the altitude.
            return frozenset({"AUTO.TAKEOFF", "HOLD"})
        return frozenset({"OFFBOARD"})

    def _offboard(self, ctl: Controller, target_ned: Vector) -> None:
        # The stream must already flow when OFFBOARD is requested, or PX4
        # refuses it in the air (and never becomes armable on the ground).
        ctl.stream(target_ned)
        if ctl.mode() != "OFFBOARD":
            ctl.wait_stream_warm(self.STREAM_WARMUP_S)
            ctl.set_mode("OFFBOARD")

    def prepare_arm(self, ctl: Controller, here_ned: Vector) -> None:
        if self.takeoff_mode == "offboard":
            # Arm in OFFBOARD with a setpoint on the ground: the vehicle stays
            # put until Takeoff raises the setpoint.
            self._offboard(ctl, here_ned)

    def takeoff(self, ctl: Controller, target_ned: Vector, height_m: float) -> None:
        if self.takeoff_mode == "auto":
            nan = math.nan
            # param7 is AMSL for PX4 (GLOBAL_POSITION_INT.alt + h), per the notes.
            ctl.command(MAV_CMD_NAV_TAKEOFF, (nan, 0.0, 0.0, nan, nan, nan, ctl.amsl_m(height_m)))
            # Keep a setpoint ready at the take-off point for the later OFFBOARD moves.
            ctl.stream(target_ned)
            return
        self._offboard(ctl, target_ned)

    def goto(self, ctl: Controller, target_ned: Vector) -> None:
        self._offboard(ctl, target_ned)

    def goto_global(
        self, ctl: Controller, lat_deg: float, lon_deg: float, rel_alt_m: float, target_ned: Vector
    ) -> None:
        # Offboard setpoints are local: the adapter already converted the point.
        self._offboard(ctl, target_ned)

    def hold(self, ctl: Controller, here_ned: Vector, airborne: bool) -> None:
        ctl.stream(here_ned)
        if airborne and ctl.mode() != "OFFBOARD":
            self._offboard(ctl, here_ned)

    def speed_params(self, speed_mps: float) -> tuple[tuple[str, float], ...]:
        # MAV_CMD_DO_CHANGE_SPEED is ignored in OFFBOARD: the setpoints fly under
        # MPC_XY_VEL_MAX; MPC_XY_CRUISE is the AUTO modes' speed.
        return (("MPC_XY_VEL_MAX", speed_mps), ("MPC_XY_CRUISE", speed_mps))

    def land(self, ctl: Controller, here_ned: Vector) -> None:
        # Keep streaming "here": harmless in AUTO.LAND, and a cancel that
        # returns to OFFBOARD then holds instead of jumping to an old target.
        ctl.stream(here_ned)
        super().land(ctl, here_ned)


class ArduPilot(Autopilot):
    """ArduCopter: GUIDED mode, MAV_CMD_NAV_TAKEOFF, position targets (no stream needed)."""

    name = "ardupilot"
    mavlink_id = MAV_AUTOPILOT_ARDUPILOTMEGA
    motion_mode = "GUIDED"
    land_mode = "LAND"

    def mode_name(self, custom_mode: int) -> str:
        return _ARDU_BY_CUSTOM.get(custom_mode, f"ArduCopter({custom_mode})")

    def mode_params(self, mode: str) -> tuple[float, float, float]:
        return (float(MAV_MODE_FLAG_CUSTOM_MODE_ENABLED), float(ARDUCOPTER_MODES[mode]), 0.0)

    def _guided(self, ctl: Controller) -> None:
        if ctl.mode() != "GUIDED":
            ctl.set_mode("GUIDED")

    def prepare_arm(self, ctl: Controller, here_ned: Vector) -> None:
        # Chosen only now that the vehicle is armable: a mode set during boot is
        # overwritten by the initial mode (the notes).
        self._guided(ctl)

    def takeoff(self, ctl: Controller, target_ned: Vector, height_m: float) -> None:
        self._guided(ctl)
        # param7: altitude in metres above home (the take-off point).
        ctl.command(MAV_CMD_NAV_TAKEOFF, (0.0, 0.0, 0.0, math.nan, 0.0, 0.0, height_m))

    def goto(self, ctl: Controller, target_ned: Vector) -> None:
        self._guided(ctl)
        ctl.position_target(target_ned)

    def goto_global(
        self, ctl: Controller, lat_deg: float, lon_deg: float, rel_alt_m: float, target_ned: Vector
    ) -> None:
        self._guided(ctl)
        ctl.global_target(lat_deg, lon_deg, rel_alt_m)

    def hold(self, ctl: Controller, here_ned: Vector, airborne: bool) -> None:
        if not airborne:
            return
        self._guided(ctl)
        ctl.position_target(here_ned)

    def speed_params(self, speed_mps: float) -> tuple[tuple[str, float], ...]:
        # MAV_CMD_DO_CHANGE_SPEED holds only until the next mode change: WPNAV_SPEED too.
        return (("WPNAV_SPEED", round(speed_mps * 100.0, 1)),)

    def brake(self, ctl: Controller, stop_ned: Vector) -> bool:
        if ctl.mode() != self.motion_mode:
            # Not ours to steer in GUIDED (RTL, LAND...): BRAKE mode at least stops it.
            ctl.set_mode("BRAKE")
            return True
        return super().brake(ctl, stop_ned)


def autopilot_named(name: str, takeoff_mode: TakeoffMode = "offboard") -> Autopilot:
    """The :class:`Autopilot` for ``"px4"`` or ``"ardupilot"``."""
    if name == "px4":
        return Px4(takeoff_mode)
    if name == "ardupilot":
        return ArduPilot()
    raise ValueError(f"unknown autopilot {name!r}")


def autopilot_from_heartbeat(mavlink_id: int, takeoff_mode: TakeoffMode = "offboard") -> Autopilot:
    """The :class:`Autopilot` announced by HEARTBEAT.autopilot; ValueError for others."""
    if mavlink_id == MAV_AUTOPILOT_PX4:
        return Px4(takeoff_mode)
    if mavlink_id == MAV_AUTOPILOT_ARDUPILOTMEGA:
        return ArduPilot()
    raise ValueError(
        f"HEARTBEAT.autopilot is {mavlink_id}; only PX4 (12) and ArduPilot (3) are supported"
    )


__all__ = [
    "ARDUCOPTER_MODES",
    "MAV_AUTOPILOT_ARDUPILOTMEGA",
    "MAV_AUTOPILOT_PX4",
    "PX4_MODES",
    "ArduPilot",
    "Autopilot",
    "CommandRejected",
    "Controller",
    "Px4",
    "TakeoffMode",
    "autopilot_from_heartbeat",
    "autopilot_named",
    "px4_custom_mode",
    "px4_mode_of",
]
