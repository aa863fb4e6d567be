"""What the simulated MAVLink vehicle sends on its own: HEARTBEAT and the telemetry streams.

:class:`Streams` keeps each stream's rate (simulated time) and when it is next
due, answers MAV_CMD_SET_MESSAGE_INTERVAL and ArduPilot's REQUEST_DATA_STREAM,
and encodes every message from the vehicle's state.  It reads the vehicle
through a :class:`Status` snapshot taken at each send, so it holds no
reference to the vehicle core.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from eamos.hal.kinematics import GeoFrame, VehicleState
from eamos.hal.sitl.wire import (
    ACCEPTED,
    BOOT_S,
    DATA_STREAMS,
    DEFAULT_STREAM_RATES,
    FAILED,
    GEOFENCE,
    LANDED_IN_AIR,
    LANDED_LANDING,
    LANDED_ON_GROUND,
    LANDED_TAKEOFF,
    MAV_MODE_FLAG_CUSTOM_MODE_ENABLED,
    MAV_MODE_FLAG_GUIDED_ENABLED,
    MAV_MODE_FLAG_SAFETY_ARMED,
    MAV_MODE_FLAG_STABILIZE_ENABLED,
    MAV_STATE_ACTIVE,
    MAV_STATE_STANDBY,
    MAV_TYPE_QUADROTOR,
    MSG_ATTITUDE,
    MSG_AUTOPILOT_VERSION,
    MSG_BATTERY_STATUS,
    MSG_EKF_STATUS_REPORT,
    MSG_ESTIMATOR_STATUS,
    MSG_EXTENDED_SYS_STATE,
    MSG_GLOBAL_POSITION_INT,
    MSG_GPS_RAW_INT,
    MSG_HEARTBEAT,
    MSG_HOME_POSITION,
    MSG_LOCAL_POSITION_NED,
    MSG_MISSION_CURRENT,
    MSG_SYS_STATUS,
    MSG_VFR_HUD,
    PREARM_CHECK,
    SENSORS,
    STREAMABLE,
    UNSUPPORTED,
    VehicleOptions,
)

#: ``send(message, *fields)``: send one MAVLink message by its pymavlink name.
Send = Callable[..., None]

#: Modes whose HEARTBEAT carries MAV_MODE_FLAG_GUIDED_ENABLED (besides every AUTO.*).
_GUIDED_MODES = frozenset({"OFFBOARD", "GUIDED", "HOLD", "LAND", "RTL"})


@dataclass(frozen=True)
class Status:
    """The vehicle as the streams see it at one send."""

    t_s: float  # simulated seconds since start
    state: VehicleState
    mode: str
    custom_mode: int
    armed: bool
    armable: bool
    #: The position estimate's error (x y z m, vx vy vz m/s, mission frame), or None.
    wander: tuple[float, float, float, float, float, float] | None = None
    #: ESTIMATOR_STATUS / EKF_STATUS_REPORT flags (0: not reported).
    estimator_flags: int = 0
    #: Compass heading (degrees, 0 north, 90 east).
    heading_deg: float = 0.0
    #: The mission's current item and its length (MISSION_CURRENT).
    mission: tuple[int, int] = (0, 0)
    #: A fence is enforced, and the vehicle is outside it (SYS_STATUS's GEOFENCE bits).
    fence_enforced: bool = False
    fence_breached: bool = False
    #: On the ground as its land detector says (a moment after touchdown).
    on_ground: bool = True


@dataclass(frozen=True)
class Identity:
    """What the vehicle says about itself: autopilot id, capabilities, firmware version."""

    mav_autopilot: int
    capabilities: int
    version: int
    sysid: int
    #: Its estimator report: ESTIMATOR_STATUS (PX4) or EKF_STATUS_REPORT (ArduPilot).
    estimator_msg: int = MSG_ESTIMATOR_STATUS

    @property
    def foreign_msg(self) -> int:
        """The other autopilot's estimator report, which this one never sends."""
        if self.estimator_msg == MSG_ESTIMATOR_STATUS:
            return MSG_EKF_STATUS_REPORT
        return MSG_ESTIMATOR_STATUS


class Streams:
    """HEARTBEAT at 1 Hz from BOOT_S, and every stream at its rate (see module docstring)."""

    def __init__(
        self,
        identity: Identity,
        rates: Mapping[int, float],
        options: VehicleOptions,
        offset_m: float,
        send: Send,
    ) -> None:
        self._identity = identity
        self._rates: dict[int, float] = dict(rates)
        self._rates.pop(identity.foreign_msg, None)
        self._due: dict[int, float] = {}
        self._next_heartbeat = BOOT_S
        self._options = options
        self._frame = GeoFrame(*options.home)
        self._offset_m = offset_m
        self._send = send

    # -- rates ---------------------------------------------------------------------------

    def set_interval(self, msg_id: int, interval_us: float, t_s: float) -> int:
        """MAV_CMD_SET_MESSAGE_INTERVAL: the MAV_RESULT (-1 stops, 0 is the default rate)."""
        if not math.isfinite(interval_us):
            interval_us = 0.0
        if msg_id == MSG_HEARTBEAT:
            return FAILED if 0 < interval_us < 1e6 else ACCEPTED  # HEARTBEAT stays 1 Hz
        if msg_id not in STREAMABLE or msg_id == self._identity.foreign_msg:
            return UNSUPPORTED
        if interval_us < 0:
            self._rates.pop(msg_id, None)
        elif interval_us == 0:
            self._rates[msg_id] = DEFAULT_STREAM_RATES.get(msg_id, 1.0)
        else:
            self._rates[msg_id] = 1e6 / interval_us
        self._due[msg_id] = t_s
        return ACCEPTED

    def data_stream(self, stream_id: int, start: bool, rate_hz: float, t_s: float) -> None:
        """REQUEST_DATA_STREAM: start or stop a MAV_DATA_STREAM group (0: all of them)."""
        if stream_id == 0:
            groups = list(DATA_STREAMS.values())
        else:
            groups = [DATA_STREAMS.get(stream_id, ())]
        for msg_id in (m for group in groups for m in group):
            if msg_id == self._identity.foreign_msg:
                continue
            if start and rate_hz > 0:
                self._rates[msg_id] = float(rate_hz)
                self._due[msg_id] = t_s
            else:
                self._rates.pop(msg_id, None)

    # -- sending -------------------------------------------------------------------------

    def send_due(self, status: Status) -> None:
        """Send the HEARTBEAT and every stream that is due (at most once each per call)."""
        t = status.t_s
        if t >= BOOT_S and t >= self._next_heartbeat:
            self._next_heartbeat = max(self._next_heartbeat + 1.0, t)
            self.heartbeat(status)
        if t < BOOT_S:
            return
        for msg_id, hz in self._rates.items():
            due = self._due.get(msg_id, t)
            if t >= due and hz > 0:
                self.send_message(msg_id, status)
                # At most once per tick; keep the cadence without bursting.
                self._due[msg_id] = max(due + 1.0 / hz, t)

    def heartbeat(self, status: Status) -> None:
        """One HEARTBEAT: mode flags, custom mode, armed state."""
        base = MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | MAV_MODE_FLAG_STABILIZE_ENABLED
        if status.mode in _GUIDED_MODES or status.mode.startswith("AUTO"):
            base |= MAV_MODE_FLAG_GUIDED_ENABLED
        if status.armed:
            base |= MAV_MODE_FLAG_SAFETY_ARMED
        self._send(
            "heartbeat",
            MAV_TYPE_QUADROTOR,
            self._identity.mav_autopilot,
            base,
            status.custom_mode,
            MAV_STATE_ACTIVE if status.armed else MAV_STATE_STANDBY,
            3,
        )

    def send_message(self, msg_id: int, status: Status) -> None:
        """Send one message (a stream's, or one asked for with MAV_CMD_REQUEST_MESSAGE)."""
        st, t = status.state, status.t_s
        ms = int(t * 1000) & 0xFFFFFFFF
        w = status.wander or (0.0,) * 6
        lat, lon, _ = self._frame.to_lla(st.x_m, st.y_m, st.z_m)
        amsl = self._options.home[2] + st.z_m
        encoders: dict[int, Callable[[], tuple[Any, ...]]] = {
            MSG_LOCAL_POSITION_NED: lambda: (
                "local_position_ned",
                ms,
                st.x_m + w[0],
                st.y_m + w[1],
                self._offset_m - st.z_m - w[2],
                st.vx_mps + w[3],
                st.vy_mps + w[4],
                -st.vz_mps - w[5],
            ),
            MSG_GLOBAL_POSITION_INT: lambda: (
                "global_position_int",
                ms,
                round(lat * 1e7),
                round(lon * 1e7),
                round(amsl * 1000),
                round(st.z_m * 1000),
                round(st.vx_mps * 100),
                round(st.vy_mps * 100),
                round(-st.vz_mps * 100),
                0,
            ),
            MSG_SYS_STATUS: lambda: self._sys_status(status),
            MSG_EXTENDED_SYS_STATE: lambda: ("extended_sys_state", 0, _landed_state(status)),
            MSG_ATTITUDE: lambda: (
                "attitude",
                ms,
                0.0,
                0.0,
                math.remainder(math.radians(status.heading_deg), 2 * math.pi),
                0.0,
                0.0,
                0.0,
            ),
            MSG_BATTERY_STATUS: lambda: _battery_status(st),
            MSG_HOME_POSITION: lambda: self._home_position(t),
            MSG_GPS_RAW_INT: lambda: (
                "gps_raw_int",
                int(t * 1e6),
                3,
                round(lat * 1e7),
                round(lon * 1e7),
                round(amsl * 1000),
                80,
                120,
                round(st.horizontal_speed_mps * 100),
                0,
                12,
                0,
                0,
                0,
                0,
                0,
                0,
            ),
            MSG_AUTOPILOT_VERSION: self._autopilot_version,
            MSG_VFR_HUD: lambda: (
                "vfr_hud",
                st.horizontal_speed_mps,  # airspeed: no wind here
                st.horizontal_speed_mps,
                round(status.heading_deg) % 360,
                (50 if not st.landed else 0) if status.armed else 0,  # throttle %
                amsl,
                st.vz_mps,
            ),
            MSG_MISSION_CURRENT: lambda: ("mission_current", status.mission[0], status.mission[1]),
            MSG_ESTIMATOR_STATUS: lambda: (
                "estimator_status",
                int(t * 1e6),
                status.estimator_flags,
                *(0.1, 0.1, 0.1, 0.1, 0.0, 0.0),
                math.hypot(w[0], w[1]) + 0.05,
                abs(w[2]) + 0.05,
            ),
            MSG_EKF_STATUS_REPORT: lambda: (
                "ekf_status_report",
                status.estimator_flags,
                *(0.1, 0.1, 0.1, 0.1, 0.0, 0.0),
            ),
        }
        if msg_id == self._identity.foreign_msg:
            return
        encode = encoders.get(msg_id)
        if encode is not None:
            self._send(*encode())

    def _sys_status(self, status: Status) -> tuple[Any, ...]:
        report = self._options.report_prearm
        fence = GEOFENCE if status.fence_enforced else 0
        reported = SENSORS | fence | (PREARM_CHECK if report else 0)
        # As ArduPilot: the geofence is healthy unless breached (MAVProxy says "fence breach").
        health = SENSORS | (0 if status.fence_breached else GEOFENCE)
        health |= PREARM_CHECK if status.armable and report else 0
        battery = round(status.state.battery_pct)
        current = 500 if status.armed else 50
        return ("sys_status", reported, reported, health, 250, 12600, current, battery) + (0,) * 6

    def _home_position(self, t_s: float) -> tuple[Any, ...]:
        hlat, hlon, halt = self._options.home
        return (
            "home_position",
            round(hlat * 1e7),
            round(hlon * 1e7),
            round(halt * 1000),
            0.0,
            0.0,
            self._offset_m,
            [1.0, 0.0, 0.0, 0.0],
            0.0,
            0.0,
            0.0,
            int(t_s * 1e6),
        )

    def _autopilot_version(self) -> tuple[Any, ...]:
        ident = self._identity
        return (
            "autopilot_version",
            ident.capabilities,
            ident.version,
            0,
            0,
            0,
            [0] * 8,
            [0] * 8,
            [0] * 8,
            0,
            0,
            ident.sysid,
        )


def _battery_status(st: VehicleState) -> tuple[Any, ...]:
    return (
        "battery_status",
        0,
        0,
        1,
        32767,
        [12600] + [65535] * 9,
        -1,
        -1,
        -1,
        round(st.battery_pct),
        0,
        1,
        [0, 0, 0, 0],
        0,
        0,
    )


def _landed_state(status: Status) -> int:
    if status.on_ground:
        return LANDED_ON_GROUND
    if status.mode in ("AUTO.LAND", "LAND"):
        return LANDED_LANDING
    if status.mode == "AUTO.TAKEOFF":
        return LANDED_TAKEOFF
    return LANDED_IN_AIR


__all__ = ["Identity", "Send", "Status", "Streams"]
