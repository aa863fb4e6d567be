"""What the MAVLink link knows about its vehicle, and how each received message updates it.

:class:`LinkState` is the vehicle as last heard (HEARTBEAT, positions, battery,
acks, STATUSTEXT...).  :class:`StateTracker` folds each received message into
it: it locks onto the first autopilot heard, ignores other systems, notes
gaps and heartbeat loss, reassembles chunked STATUSTEXTs, and reports what
changed as events.  It holds no lock, thread or clock of its own: the link's
reader thread calls it with the condition held and the receive time.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

#: MAVLink numbers the tracker reads (kept local: no pymavlink needed).
MAV_TYPE_GCS = 6
MAV_AUTOPILOT_INVALID = 8
MAV_MODE_FLAG_SAFETY_ARMED = 128
MAV_RESULT_NAMES = {
    0: "MAV_RESULT_ACCEPTED",
    1: "MAV_RESULT_TEMPORARILY_REJECTED",
    2: "MAV_RESULT_DENIED",
    3: "MAV_RESULT_UNSUPPORTED",
    4: "MAV_RESULT_FAILED",
    5: "MAV_RESULT_IN_PROGRESS",
    6: "MAV_RESULT_CANCELLED",
    7: "MAV_RESULT_COMMAND_LONG_ONLY",
    8: "MAV_RESULT_COMMAND_INT_ONLY",
    9: "MAV_RESULT_COMMAND_UNSUPPORTED_MAV_FRAME",
}

#: Silence on the link (any message) that counts as a gap when it ends.
GAP_S = 1.0
#: STATUSTEXT payload size: a chunk this long is continued by the next one.
STATUSTEXT_CHUNK = 50
#: LOCAL_POSITION_NED samples kept for settle windows (a few seconds at 10-50 Hz).
RECENT_SAMPLES = 200


def result_name(result: int | None) -> str:
    """``"MAV_RESULT_DENIED"`` for 2, etc.; ``"no COMMAND_ACK"`` for None."""
    if result is None:
        return "no COMMAND_ACK"
    return MAV_RESULT_NAMES.get(result, f"MAV_RESULT({result})")


@dataclass
class GlobalPosition:
    """GLOBAL_POSITION_INT in SI units."""

    lat_deg: float
    lon_deg: float
    alt_amsl_m: float
    rel_alt_m: float
    vn_mps: float
    ve_mps: float
    vd_mps: float


@dataclass(frozen=True)
class CapturedImage:
    """CAMERA_IMAGE_CAPTURED in SI units: where a photo was taken."""

    index: int
    lat_deg: float
    lon_deg: float
    alt_amsl_m: float
    rel_alt_m: float
    ok: bool  # capture_result == 1


@dataclass
class LinkState:
    """What the reader knows about the vehicle; read and written under ``MavlinkLink.cond``."""

    system_id: int | None = None
    component_id: int = 1
    autopilot: int | None = None
    base_mode: int = 0
    custom_mode: int = 0
    armed: bool = False
    heartbeats: int = 0
    last_heartbeat: float = -math.inf  # time.monotonic()
    link_ok: bool = False  # heartbeats arrive (none missing for > heartbeat_timeout_s)
    last_rx: float = -math.inf
    gap_ended_at: float = -math.inf  # first message after a silence of GAP_S or more
    failsafe_at: float = -math.inf  # last STATUSTEXT mentioning a failsafe
    local: tuple[float, float, float, float, float, float] | None = None  # NED x y z vx vy vz
    local_since: float | None = None  # when the first LOCAL_POSITION_NED came (monotonic)
    #: Recent LOCAL_POSITION_NED (receive time, NED x y z vx vy vz): the settle window.
    recent: deque[tuple[float, tuple[float, ...]]] = field(
        default_factory=lambda: deque(maxlen=RECENT_SAMPLES)
    )
    #: PARAM_VALUE by name: (raw wire value, MAV_PARAM_TYPE, param_serial when heard).
    params: dict[str, tuple[float, int, int]] = field(default_factory=dict)
    param_serial: int = 0
    global_pos: GlobalPosition | None = None
    home: tuple[float, float, float] | None = None  # HOME_POSITION lat, lon, alt AMSL
    home_ned: tuple[float, float, float] | None = None  # HOME_POSITION x, y, z (local NED)
    sensors_present: int | None = None
    sensors_health: int | None = None
    battery_pct: float | None = None
    landed_state: int | None = None  # EXTENDED_SYS_STATE (MAV_LANDED_STATE)
    #: ESTIMATOR_STATUS (PX4) / EKF_STATUS_REPORT (ArduPilot) flags; None: not heard.
    estimator_flags: int | None = None
    #: Compass heading from ATTITUDE.yaw (degrees, 0 north, 90 east); None: not heard.
    heading_deg: float | None = None
    #: CAMERA_IMAGE_CAPTURED or ArduPilot's CAMERA_FEEDBACK (latest last), and how many.
    images: deque[CapturedImage] = field(default_factory=lambda: deque(maxlen=20))
    image_serial: int = 0
    #: The gimbal's pitch from GIMBAL_DEVICE_ATTITUDE_STATUS (degrees); None: not heard.
    gimbal_pitch_deg: float | None = None
    acks: dict[int, tuple[int, int]] = field(default_factory=dict)  # command -> (result, serial)
    ack_serial: int = 0
    statustexts: deque[str] = field(default_factory=lambda: deque(maxlen=20))
    statustext_serial: int = 0
    severities: deque[int] = field(default_factory=lambda: deque(maxlen=20))  # of each text
    #: Vehicle HEARTBEATs the link refused for their signature (signing.refused_frame):
    #: how many, whether the latest was signed (with another key) and by which autopilot.
    refused_heartbeats: int = 0
    refused_signed: bool = False
    refused_autopilot: int | None = None
    refused_at: float = -math.inf
    #: Messages heard from the vehicle so far, by type (rates.py measures their rates).
    counts: dict[str, int] = field(default_factory=dict)
    #: The vehicle's clock: the latest ``time_boot_ms`` it sent (ms since its boot).
    boot_ms: int | None = None
    #: The mission protocol's answers addressed to us (MISSION_COUNT, MISSION_REQUEST(_INT),
    #: MISSION_ITEM_INT, MISSION_ACK), each with its serial number (mission_protocol.py).
    mission: deque[tuple[int, Any]] = field(default_factory=lambda: deque(maxlen=64))
    mission_serial: int = 0
    closed: bool = False

    def window(self, now: float, span_s: float) -> tuple[tuple[float, float, float], float] | None:
        """Mean NED position and speed of LOCAL_POSITION_NED over ``span_s`` before ``now``.

        None until samples cover the whole span; ``span_s`` 0: the latest sample.
        """
        if self.local is None:
            return None
        samples: list[tuple[float, ...]] = [self.local]
        if span_s > 0:
            if not self.recent or self.recent[0][0] > now - span_s:
                return None
            samples = [x for t, x in self.recent if t >= now - span_s] or samples
        n = len(samples)
        m = [sum(x[i] for x in samples) / n for i in range(6)]
        return (m[0], m[1], m[2]), math.sqrt(m[3] ** 2 + m[4] ** 2 + m[5] ** 2)

    @property
    def last_statustext(self) -> str:
        """The latest STATUSTEXT (reassembled), or ``""``."""
        return self.statustexts[-1] if self.statustexts else ""

    def ack_since(self, command: int, serial: int) -> int | None:
        """The result of the latest COMMAND_ACK for ``command`` newer than ``serial``."""
        entry = self.acks.get(command)
        return entry[0] if entry is not None and entry[1] > serial else None


#: Events collected under the condition, reported after releasing it.
Events = list[tuple[str, dict[str, Any]]]


class StateTracker:
    """Folds received messages into a :class:`LinkState` (see module docstring)."""

    def __init__(
        self,
        state: LinkState,
        *,
        source_system: int,
        component_id: int,
        heartbeat_timeout_s: float,
        notify: Callable[[], None],
    ) -> None:
        self.state = state
        self._source_system = source_system
        self._component_id = component_id
        self._heartbeat_timeout_s = heartbeat_timeout_s
        self._notify = notify  # wakes every waiter on the link's condition
        self._chunks: dict[int, list[str]] = {}  # STATUSTEXT parts by id

    def check_heartbeat(self, now: float, events: Events) -> None:
        """Heartbeats stopped for longer than the timeout: the link is lost (once)."""
        st = self.state
        if st.link_ok and now - st.last_heartbeat > self._heartbeat_timeout_s:
            st.link_ok = False
            events.append(
                (
                    "link.lost",
                    {
                        "silent_s": round(now - st.last_heartbeat, 3),
                        "heartbeat_timeout_s": self._heartbeat_timeout_s,
                    },
                )
            )
            self._notify()

    def handle(self, msg: Any, now: float, events: Events) -> None:
        """Fold one message received at ``now`` into the state; append what changed."""
        st = self.state
        kind = msg.get_type()
        src, comp = msg.get_srcSystem(), msg.get_srcComponent()
        if kind == "HEARTBEAT":
            if not self._is_vehicle_heartbeat(msg, src, comp):
                return
        elif st.system_id is None or src != st.system_id:
            return  # another system on a shared port, or before we know the vehicle
        if now - st.last_rx >= GAP_S and st.last_rx > -math.inf:
            st.gap_ended_at = now
            events.append(("link.gap", {"silent_s": round(now - st.last_rx, 3)}))
        st.last_rx = now
        st.counts[kind] = st.counts.get(kind, 0) + 1
        boot_ms = getattr(msg, "time_boot_ms", None)
        if isinstance(boot_ms, int) and boot_ms > 0:
            st.boot_ms = boot_ms
        handler = getattr(self, f"_on_{kind.lower()}", None)
        if handler is not None:
            handler(msg, now, events)
            self._notify()

    def refused(self, frame: Any, now: float, events: Events) -> None:
        """A frame the link refused for its signature (a :class:`~.signing.RefusedFrame`):
        counted when it is the vehicle's HEARTBEAT (who it is, as for a good one)."""
        st = self.state
        if not frame.vehicle_heartbeat:
            return
        if frame.component_id != self._component_id and not (
            self._component_id == 0 and frame.component_id == 1
        ):
            return
        if st.system_id is not None and frame.system_id != st.system_id:
            return
        st.refused_heartbeats += 1
        st.refused_signed = frame.signed
        st.refused_autopilot = frame.autopilot
        st.refused_at = now
        if st.refused_heartbeats == 1:
            events.append(
                (
                    "link.refused",
                    {"system_id": frame.system_id, "signed": frame.signed},
                )
            )
        self._notify()

    def _is_vehicle_heartbeat(self, msg: Any, src: int, comp: int) -> bool:
        st = self.state
        if comp != self._component_id and not (self._component_id == 0 and comp == 1):
            return False
        if st.system_id is None:
            # Lock onto the first autopilot heard; ignore ground stations and
            # other companions sharing the port.
            if msg.autopilot == MAV_AUTOPILOT_INVALID or msg.type == MAV_TYPE_GCS:
                return False
            st.system_id = src
            return True
        return src == st.system_id

    def _on_heartbeat(self, msg: Any, now: float, events: Events) -> None:
        st = self.state
        armed = bool(msg.base_mode & MAV_MODE_FLAG_SAFETY_ARMED)
        if st.heartbeats == 0:
            events.append(
                (
                    "link.vehicle",
                    {"system_id": st.system_id, "autopilot": msg.autopilot, "type": msg.type},
                )
            )
        else:
            if msg.custom_mode != st.custom_mode:
                events.append(
                    ("vehicle.mode", {"custom_mode": msg.custom_mode, "previous": st.custom_mode})
                )
            if armed != st.armed:
                events.append(("vehicle.armed", {"armed": armed}))
        if not st.link_ok:
            if st.heartbeats:
                events.append(("link.restored", {"silent_s": round(now - st.last_heartbeat, 3)}))
            st.link_ok = True
        st.autopilot = msg.autopilot
        st.base_mode, st.custom_mode, st.armed = msg.base_mode, msg.custom_mode, armed
        st.heartbeats += 1
        st.last_heartbeat = now

    def _on_command_ack(self, msg: Any, now: float, events: Events) -> None:
        target = getattr(msg, "target_system", 0)
        if target not in (0, self._source_system):
            return  # an ack meant for another ground station
        st = self.state
        st.ack_serial += 1
        st.acks[msg.command] = (msg.result, st.ack_serial)
        events.append(("vehicle.ack", {"command": msg.command, "result": result_name(msg.result)}))

    def _on_local_position_ned(self, msg: Any, now: float, events: Events) -> None:
        self.state.local = (msg.x, msg.y, msg.z, msg.vx, msg.vy, msg.vz)
        if self.state.local_since is None:
            self.state.local_since = now
        self.state.recent.append((now, self.state.local))

    def _mission(self, msg: Any, now: float, events: Events) -> None:
        if getattr(msg, "target_system", 0) not in (0, self._source_system):
            return  # another ground station's mission exchange on a shared port
        st = self.state
        st.mission_serial += 1
        st.mission.append((st.mission_serial, msg))

    _on_mission_count = _on_mission_request = _on_mission_request_int = _mission
    _on_mission_item_int = _on_mission_ack = _mission

    def _on_param_value(self, msg: Any, now: float, events: Events) -> None:
        raw = msg.param_id
        name = (raw.decode("utf-8", "replace") if isinstance(raw, bytes) else raw).rstrip("\x00")
        st = self.state
        st.param_serial += 1
        st.params[name] = (float(msg.param_value), int(msg.param_type), st.param_serial)

    def _on_global_position_int(self, msg: Any, now: float, events: Events) -> None:
        self.state.global_pos = GlobalPosition(
            msg.lat / 1e7,
            msg.lon / 1e7,
            msg.alt / 1000.0,
            msg.relative_alt / 1000.0,
            msg.vx / 100.0,
            msg.vy / 100.0,
            msg.vz / 100.0,
        )

    def _on_home_position(self, msg: Any, now: float, events: Events) -> None:
        self.state.home = (msg.latitude / 1e7, msg.longitude / 1e7, msg.altitude / 1000.0)
        self.state.home_ned = (float(msg.x), float(msg.y), float(msg.z))

    def _on_sys_status(self, msg: Any, now: float, events: Events) -> None:
        st = self.state
        st.sensors_present = msg.onboard_control_sensors_present
        st.sensors_health = msg.onboard_control_sensors_health
        if msg.battery_remaining >= 0:
            st.battery_pct = float(msg.battery_remaining)

    def _on_battery_status(self, msg: Any, now: float, events: Events) -> None:
        if msg.battery_remaining >= 0:
            self.state.battery_pct = float(msg.battery_remaining)

    def _on_extended_sys_state(self, msg: Any, now: float, events: Events) -> None:
        self.state.landed_state = msg.landed_state

    def _on_camera_image_captured(self, msg: Any, now: float, events: Events) -> None:
        st = self.state
        image = CapturedImage(
            int(msg.image_index),
            msg.lat / 1e7,
            msg.lon / 1e7,
            msg.alt / 1000.0,
            msg.relative_alt / 1000.0,
            msg.capture_result == 1,
        )
        st.images.append(image)
        st.image_serial += 1
        events.append(("vehicle.image", {"index": image.index, "ok": image.ok}))

    def _on_camera_feedback(self, msg: Any, now: float, events: Events) -> None:
        # ArduPilot's report of a photo (AP_Camera_Backend::log_picture): it never sends
        # CAMERA_IMAGE_CAPTURED.  alt_msl / alt_rel are metres already.
        st = self.state
        image = CapturedImage(
            int(msg.img_idx), msg.lat / 1e7, msg.lng / 1e7, msg.alt_msl, msg.alt_rel, True
        )
        st.images.append(image)
        st.image_serial += 1
        events.append(
            ("vehicle.image", {"index": image.index, "ok": True, "via": "CAMERA_FEEDBACK"})
        )

    def _on_gimbal_device_attitude_status(self, msg: Any, now: float, events: Events) -> None:
        w, x, y, z = msg.q
        self.state.gimbal_pitch_deg = math.degrees(
            math.asin(max(-1.0, min(1.0, 2 * (w * y - z * x))))
        )

    def _on_attitude(self, msg: Any, now: float, events: Events) -> None:
        self.state.heading_deg = math.degrees(msg.yaw) % 360.0

    def _on_estimator_status(self, msg: Any, now: float, events: Events) -> None:
        self._estimator(int(msg.flags), events)

    def _on_ekf_status_report(self, msg: Any, now: float, events: Events) -> None:
        self._estimator(int(msg.flags), events)

    def _estimator(self, flags: int, events: Events) -> None:
        st = self.state
        if flags != st.estimator_flags:
            events.append(("vehicle.estimator", {"flags": flags, "previous": st.estimator_flags}))
        st.estimator_flags = flags

    def _on_statustext(self, msg: Any, now: float, events: Events) -> None:
        text = msg.text.decode("utf-8", "replace") if isinstance(msg.text, bytes) else msg.text
        text = text.rstrip("\x00")
        chunk_id = getattr(msg, "id", 0)
        if chunk_id:
            # MAVLink 2 splits long texts into chunks sharing an id (PX4 does).
            parts = self._chunks.setdefault(chunk_id, [])
            parts.append(text)
            if len(text) >= STATUSTEXT_CHUNK and len(parts) < 8:
                return
            text = "".join(self._chunks.pop(chunk_id))
        st = self.state
        st.statustexts.append(text)
        st.severities.append(int(msg.severity))
        st.statustext_serial += 1
        if "failsafe" in text.lower():
            st.failsafe_at = now
        events.append(("vehicle.statustext", {"severity": msg.severity, "text": text}))


__all__ = [
    "MAV_RESULT_NAMES",
    "CapturedImage",
    "Events",
    "GlobalPosition",
    "LinkState",
    "StateTracker",
    "result_name",
]
