"""The simulated MAVLink vehicle's inbox: every message it understands, and its answers.

:class:`Inbox` decodes what a GCS sends (HEARTBEAT, COMMAND_LONG/COMMAND_INT,
SET_POSITION_TARGET_*, REQUEST_DATA_STREAM, PARAM_*) and acts on the
:class:`~eamos.hal.sitl.core.VehicleCore`; every command gets exactly
one COMMAND_ACK (ACCEPTED, a refusal, UNSUPPORTED, or a ``reject`` test fault).
Where PX4 and ArduPilot differ it asks the vehicle's personality.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

from eamos.hal.sitl.core import VehicleCore
from eamos.hal.sitl.wire import (
    ACCEPTED,
    CMD_COMPONENT_ARM_DISARM,
    CMD_CONDITION_YAW,
    CMD_DO_CHANGE_SPEED,
    CMD_DO_FENCE_ENABLE,
    CMD_DO_GIMBAL_MANAGER_PITCHYAW,
    CMD_DO_MOUNT_CONTROL,
    CMD_DO_ORBIT,
    CMD_DO_REPOSITION,
    CMD_DO_SET_MISSION_CURRENT,
    CMD_DO_SET_MODE,
    CMD_GET_HOME_POSITION,
    CMD_IMAGE_START_CAPTURE,
    CMD_NAV_LAND,
    CMD_NAV_RETURN_TO_LAUNCH,
    CMD_NAV_TAKEOFF,
    CMD_REQUEST_AUTOPILOT_CAPABILITIES,
    CMD_REQUEST_MESSAGE,
    CMD_SET_MESSAGE_INTERVAL,
    CMD_VIDEO_START_CAPTURE,
    CMD_VIDEO_STOP_CAPTURE,
    DENIED,
    FAILED,
    FORCE_MAGIC,
    FRAME_GLOBAL,
    FRAME_GLOBAL_INT,
    FRAME_GLOBAL_RELATIVE_ALT,
    FRAME_GLOBAL_RELATIVE_ALT_INT,
    FRAME_LOCAL_NED,
    IGNORE_POSITION,
    IGNORE_VELOCITY,
    IGNORE_YAW,
    MAV_MODE_FLAG_CUSTOM_MODE_ENABLED,
    MSG_AUTOPILOT_VERSION,
    MSG_HOME_POSITION,
    SEV_CRITICAL,
    SEV_WARNING,
    STREAMABLE,
    UNSUPPORTED,
    json_number,
    param_int,
)

#: Modes from which a vehicle refuses to arm.
_NOT_ARMABLE_MODES = frozenset({"AUTO.LAND", "AUTO.RTL", "LAND", "RTL", "AUTO"})


class Inbox:
    """Handles the messages one vehicle receives (see module docstring)."""

    def __init__(self, vehicle: VehicleCore) -> None:
        self.v = vehicle
        self._gcs: tuple[int, int] | None = None  # last GCS heard (sysid, compid)
        self.commands: list[tuple[int, int]] = []  # (MAV_CMD, MAV_RESULT) answered

    def handle(self, msg: Any) -> None:
        """Handle one received MAVLink message (unknown types are ignored)."""
        handler = getattr(self, f"_on_{msg.get_type().lower()}", None)
        if handler is not None:
            handler(msg)

    def _for_us(self, msg: Any) -> bool:
        return msg.target_system in (0, self.v.options.sysid) and msg.target_component in (0, 1)

    def _on_heartbeat(self, msg: Any) -> None:
        if self._gcs is None:
            self.v.log.info("vehicle.gcs", sysid=msg.get_srcSystem(), compid=msg.get_srcComponent())
        self._gcs = (msg.get_srcSystem(), msg.get_srcComponent())

    def _on_command_long(self, msg: Any) -> None:
        if self._for_us(msg):
            params = (
                msg.param1,
                msg.param2,
                msg.param3,
                msg.param4,
                msg.param5,
                msg.param6,
                msg.param7,
            )
            self._command(msg, msg.command, params, None)

    def _on_command_int(self, msg: Any) -> None:
        if self._for_us(msg):
            params = (
                msg.param1,
                msg.param2,
                msg.param3,
                msg.param4,
                float(msg.x),
                float(msg.y),
                msg.z,
            )
            self._command(msg, msg.command, params, msg.frame)

    def _command(self, msg: Any, command: int, p: tuple[float, ...], frame: int | None) -> None:
        handlers: dict[int, Callable[[tuple[float, ...], int | None], int]] = {
            CMD_COMPONENT_ARM_DISARM: self._cmd_arm_disarm,
            CMD_DO_SET_MODE: self._cmd_set_mode,
            CMD_NAV_TAKEOFF: lambda p, f: self.v.p.takeoff(self.v, p),
            CMD_NAV_LAND: self._cmd_land,
            CMD_DO_REPOSITION: self._cmd_reposition,
            CMD_NAV_RETURN_TO_LAUNCH: self._cmd_return_to_launch,
            CMD_CONDITION_YAW: lambda p, f: self.v.p.condition_yaw(self.v, p),
            CMD_DO_ORBIT: lambda p, f: self.v.p.orbit(self.v, p, f),
            CMD_DO_CHANGE_SPEED: lambda p, f: self.v.p.change_speed(self.v, p),
            CMD_IMAGE_START_CAPTURE: lambda p, f: self.v.camera.capture(self.v, p),
            CMD_VIDEO_START_CAPTURE: lambda p, f: self.v.camera.video(self.v, True),
            CMD_VIDEO_STOP_CAPTURE: lambda p, f: self.v.camera.video(self.v, False),
            CMD_DO_GIMBAL_MANAGER_PITCHYAW: lambda p, f: self.v.camera.point(self.v, p[0]),
            CMD_DO_MOUNT_CONTROL: lambda p, f: self.v.camera.point(self.v, p[0]),
            CMD_SET_MESSAGE_INTERVAL: lambda p, f: self.v.streams.set_interval(
                param_int(p[0], -1), p[1], self.v.t
            ),
            CMD_REQUEST_MESSAGE: self._cmd_request_message,
            CMD_GET_HOME_POSITION: lambda p, f: self._send_now(MSG_HOME_POSITION),
            CMD_REQUEST_AUTOPILOT_CAPABILITIES: lambda p, f: self._send_now(MSG_AUTOPILOT_VERSION),
            CMD_DO_SET_MISSION_CURRENT: self._cmd_set_mission_current,
            CMD_DO_FENCE_ENABLE: self._cmd_fence_enable,
        }
        if command in self.v.options.reject:
            result = self.v.options.reject[command]
            self.v.text(f"Command {command} rejected (test fault)", SEV_WARNING)
        else:
            handler = handlers.get(command)
            result = UNSUPPORTED if handler is None else handler(p, frame)
        self.commands.append((command, result))
        self.v.log.info(
            "vehicle.command",
            command=command,
            params=[json_number(v) for v in p],
            result=result,
            t_sim=round(self.v.t, 3),
        )
        self.v.send(
            "command_ack", command, result, 0, 0, msg.get_srcSystem(), msg.get_srcComponent()
        )

    def _cmd_arm_disarm(self, p: tuple[float, ...], frame: int | None) -> int:
        force = param_int(p[1]) == FORCE_MAGIC
        if p[0] >= 0.5:
            if self.v.armed:
                return ACCEPTED
            if not force and not self.v.armable():
                return self.v.p.arming_refused(self.v)
            if self.v.mode in _NOT_ARMABLE_MODES:
                self.v.text(self.v.p.text_mode_not_armable, SEV_CRITICAL)
                return self.v.p.refused
            self.v.arm()
            return ACCEPTED
        if not self.v.armed:
            return ACCEPTED
        if not self.v.model.landed and not force:
            self.v.text(self.v.p.text_disarm_in_air, SEV_CRITICAL)
            return self.v.p.refused
        self.v.disarm(self.v.p.text_disarmed, force=force)
        return ACCEPTED

    def _cmd_set_mode(self, p: tuple[float, ...], frame: int | None) -> int:
        if not param_int(p[0]) & MAV_MODE_FLAG_CUSTOM_MODE_ENABLED:
            return DENIED
        mode = self.v.p.set_mode(self.v, p)
        if isinstance(mode, int):
            return mode
        if mode != self.v.mode:
            self.v.enter_mode(mode, "command")
        return ACCEPTED

    def _cmd_land(self, p: tuple[float, ...], frame: int | None) -> int:
        if not self.v.armed:
            return self.v.p.refused
        self.v.enter_mode(self.v.p.land_mode, "land command")
        self.v.p.landing(self.v)
        return ACCEPTED

    def _cmd_return_to_launch(self, p: tuple[float, ...], frame: int | None) -> int:
        if not self.v.armed or self.v.model.landed:
            return self.v.p.refused
        rtl = "AUTO.RTL" if "AUTO.RTL" in self.v.p.modes else "RTL"
        if self.v.mode != rtl:
            self.v.enter_mode(rtl, "return to launch command")
        return ACCEPTED

    def _cmd_reposition(self, p: tuple[float, ...], frame: int | None) -> int:
        model = self.v.model
        if frame is None and not self.v.p.reposition_long:
            return UNSUPPORTED
        if not self.v.armed or model.landed:
            return self.v.p.refused
        x, y, z = model.position
        lat, lon, alt = p[4], p[5], p[6]
        if frame is not None:  # COMMAND_INT: degrees * 1e7
            lat, lon = lat / 1e7, lon / 1e7
        relative = frame in (FRAME_GLOBAL_RELATIVE_ALT, FRAME_GLOBAL_RELATIVE_ALT_INT)
        placed = math.isfinite(lat) and math.isfinite(lon) and bool(lat or lon)
        if placed and not (-90.0 <= lat <= 90.0 and -180.0 <= lon <= 180.0):
            # Out of range (MAVSDK once sent -214.7 degrees): ArduCopter refuses it; PX4
            # main accepts it, and here the vehicle then stays where it is.
            self.v.log.warning("vehicle.reposition.out_of_range", lat=lat, lon=lon)
            refused = self.v.p.coordinates_refused(self.v)
            return ACCEPTED if refused is None else refused
        tx, ty = (x, y) if not placed else self.v.frame.from_lla(lat, lon, 0.0)[:2]
        tz = z if not math.isfinite(alt) else (alt if relative else alt - self.v.options.home[2])
        target = (tx, ty, max(tz, 0.5))
        refused = self.v.p.reposition_mode(self.v, p, target)
        if refused is not None:
            return refused
        self.v.steer(*target)
        return ACCEPTED

    def _cmd_set_mission_current(self, p: tuple[float, ...], frame: int | None) -> int:
        return ACCEPTED if self.v.missions.on_set_current(param_int(p[0], -1)) else FAILED

    def _cmd_fence_enable(self, p: tuple[float, ...], frame: int | None) -> int:
        # ArduPilot: param1 0 off, 1 on (FENCE_ENABLE); PX4 main does not know it.
        if "FENCE_ENABLE" not in self.v.params.snapshot():
            return UNSUPPORTED
        enable = param_int(p[0], -1)
        if enable not in (0, 1):
            return FAILED
        self.v.params.set("FENCE_ENABLE", float(enable))
        return ACCEPTED

    def _cmd_request_message(self, p: tuple[float, ...], frame: int | None) -> int:
        msg_id = param_int(p[0], -1)
        if msg_id not in STREAMABLE and msg_id != MSG_AUTOPILOT_VERSION:
            return UNSUPPORTED
        return self._send_now(msg_id)

    def _send_now(self, msg_id: int) -> int:
        self.v.streams.send_message(msg_id, self.v.status())
        return ACCEPTED

    def _on_set_position_target_local_ned(self, msg: Any) -> None:
        if not self._for_us(msg):
            return
        self.v.p.setpoint(self.v)
        if msg.coordinate_frame != FRAME_LOCAL_NED:
            return
        yaw = getattr(msg, "yaw", math.nan)
        if not msg.type_mask & IGNORE_YAW and math.isfinite(yaw):
            self.v.p.setpoint_yaw(self.v, math.degrees(yaw))
        if msg.type_mask & IGNORE_POSITION:
            if not msg.type_mask & IGNORE_VELOCITY:
                # NED velocity -> model frame (z up); only a stop is simulated.
                self.v.p.velocity_target(self.v, (msg.vx, msg.vy, -msg.vz))
            return  # acceleration setpoints only keep the stream alive here
        self.v.p.position_target(self.v, (msg.x, msg.y, -(msg.z - self.v.offset_m)))

    def _on_set_position_target_global_int(self, msg: Any) -> None:
        if not self._for_us(msg):
            return
        self.v.p.setpoint(self.v)
        if msg.type_mask & IGNORE_POSITION:
            return
        lat, lon = msg.lat_int / 1e7, msg.lon_int / 1e7
        if not (-90.0 <= lat <= 90.0 and -180.0 <= lon <= 180.0):
            # ArduCopter ignores a target out of range (check_latlng), and so does this vehicle.
            self.v.log.warning("vehicle.target.out_of_range", lat=lat, lon=lon)
            return
        x, y, _ = self.v.frame.from_lla(lat, lon, 0.0)
        if msg.coordinate_frame in (FRAME_GLOBAL_RELATIVE_ALT, FRAME_GLOBAL_RELATIVE_ALT_INT):
            z = msg.alt
        elif msg.coordinate_frame in (FRAME_GLOBAL, FRAME_GLOBAL_INT):
            z = msg.alt - self.v.options.home[2]
        else:
            return
        self.v.p.position_target(self.v, (x, y, z))

    def _on_request_data_stream(self, msg: Any) -> None:
        """ArduPilot's older way to ask for telemetry (PX4 ignores it)."""
        if self.v.p.data_streams and self._for_us(msg):
            self.v.streams.data_stream(
                msg.req_stream_id, bool(msg.start_stop), msg.req_message_rate, self.v.t
            )

    # -- the mission protocol (eamos.hal.sitl.missions) ----------------------------------------

    @staticmethod
    def _client(msg: Any) -> tuple[int, int]:
        return (msg.get_srcSystem(), msg.get_srcComponent())

    def _on_mission_count(self, msg: Any) -> None:
        if self._for_us(msg):
            self.v.missions.on_count(
                self._client(msg), msg.count, _mission_type(msg), self.v.wall()
            )

    def _on_mission_item_int(self, msg: Any) -> None:
        if self._for_us(msg):
            self.v.missions.on_item(self._client(msg), _item_fields(msg, True), self.v.wall())

    def _on_mission_item(self, msg: Any) -> None:
        if self._for_us(msg):
            self.v.missions.on_item(self._client(msg), _item_fields(msg, False), self.v.wall())

    def _on_mission_ack(self, msg: Any) -> None:
        if self._for_us(msg):
            self.v.missions.on_ack(self._client(msg), msg.type, _mission_type(msg))

    def _on_mission_request_list(self, msg: Any) -> None:
        if self._for_us(msg):
            self.v.missions.on_request_list(self._client(msg), _mission_type(msg))

    def _on_mission_request_int(self, msg: Any) -> None:
        if self._for_us(msg):
            self.v.missions.on_request(self._client(msg), msg.seq, _mission_type(msg), True)

    def _on_mission_request(self, msg: Any) -> None:
        if self._for_us(msg):
            self.v.missions.on_request(self._client(msg), msg.seq, _mission_type(msg), False)

    def _on_mission_clear_all(self, msg: Any) -> None:
        if self._for_us(msg):
            self.v.missions.on_clear_all(self._client(msg), _mission_type(msg))

    def _on_mission_set_current(self, msg: Any) -> None:
        if self._for_us(msg):
            self.v.missions.on_set_current(msg.seq)

    # -- parameters --------------------------------------------------------------------------

    def _on_param_request_list(self, msg: Any) -> None:
        if self._for_us(msg):
            self.v.params.send_all()

    def _on_param_request_read(self, msg: Any) -> None:
        if self._for_us(msg):
            self.v.params.read(_param_name(msg.param_id), msg.param_index)

    def _on_param_set(self, msg: Any) -> None:
        if self._for_us(msg):
            self.v.params.set(_param_name(msg.param_id), msg.param_value)


def _mission_type(msg: Any) -> int:
    return int(getattr(msg, "mission_type", 0) or 0)


_ITEM_FIELDS = (
    "seq",
    "frame",
    "command",
    "current",
    "autocontinue",
    "param1",
    "param2",
    "param3",
    "param4",
    "x",
    "y",
    "z",
)


def _item_fields(msg: Any, as_int: bool) -> dict[str, Any]:
    fields = {name: getattr(msg, name) for name in _ITEM_FIELDS}
    fields["mission_type"] = _mission_type(msg)
    fields["int"] = as_int
    return fields


def _param_name(raw: str | bytes) -> str:
    name = raw.decode() if isinstance(raw, bytes) else raw
    return name.rstrip("\x00")


__all__ = ["Inbox"]
