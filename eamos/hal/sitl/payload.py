"""The simulated vehicle's camera and gimbal: what TakePhoto, StartVideo, StopVideo and Gimbal use.

Both autopilots answer the camera protocol on the autopilot's own component
(PX4's camera trigger, ArduPilot's AP_Camera) and the gimbal v2 manager:

* MAV_CMD_IMAGE_START_CAPTURE (param3 = 1: one image): ACCEPTED, then
  CAMERA_IMAGE_CAPTURED with where it was taken (lat, lon, alt AMSL and above
  home), the camera's attitude (the gimbal's pitch) and a growing image index;
* MAV_CMD_VIDEO_START_CAPTURE / MAV_CMD_VIDEO_STOP_CAPTURE: ACCEPTED, recording on/off
  (stopping what is not recording is FAILED);
* MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW (param1 pitch, degrees) and the older
  MAV_CMD_DO_MOUNT_CONTROL (param1 pitch): the gimbal turns at
  :data:`GIMBAL_RATE_DPS` within [-90, 30] degrees; GIMBAL_DEVICE_ATTITUDE_STATUS
  reports it (5 Hz).

:class:`CameraGimbal` holds that state; it owns no thread and reads no clock.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any, Protocol

from eamos.hal.kinematics import GeoFrame, Quadcopter
from eamos.hal.sitl.wire import ACCEPTED, DENIED, FAILED, param_int

if TYPE_CHECKING:
    from eamos.logs import EventLog

#: How fast the gimbal turns (deg/s), and its pitch limits (degrees).
GIMBAL_RATE_DPS = 90.0
GIMBAL_MIN_DEG, GIMBAL_MAX_DEG = -90.0, 30.0


class Vehicle(Protocol):
    """What the camera needs of :class:`eamos.hal.sitl.core.VehicleCore`."""

    model: Quadcopter
    frame: GeoFrame
    t: float
    log: EventLog

    def send(self, message: str, *args: Any) -> None:
        """Send one MAVLink message."""
        ...

    def text(self, text: str, severity: int = ...) -> None:
        """STATUSTEXT."""
        ...


def pitch_quaternion(pitch_deg: float) -> list[float]:
    """The attitude quaternion (w, x, y, z) of a camera pitched by ``pitch_deg`` (pure)."""
    half = math.radians(pitch_deg) / 2.0
    return [math.cos(half), 0.0, math.sin(half), 0.0]


class CameraGimbal:
    """The camera and gimbal of one simulated vehicle (see module docstring)."""

    def __init__(self) -> None:
        self.pitch_deg = 0.0
        self.pitch_target_deg = 0.0
        self.recording = False
        self.images = 0

    def step(self, dt_s: float) -> None:
        """Turn the gimbal towards its target."""
        error = self.pitch_target_deg - self.pitch_deg
        limit = GIMBAL_RATE_DPS * dt_s
        self.pitch_deg += max(-limit, min(limit, error))

    def point(self, v: Vehicle, pitch_deg: float) -> int:
        """A gimbal command's pitch: the MAV_RESULT."""
        if not math.isfinite(pitch_deg) or not GIMBAL_MIN_DEG <= pitch_deg <= GIMBAL_MAX_DEG:
            v.text(f"Gimbal: pitch {pitch_deg:g} outside {GIMBAL_MIN_DEG:g}..{GIMBAL_MAX_DEG:g}")
            return DENIED
        self.pitch_target_deg = pitch_deg
        v.log.info("vehicle.gimbal", pitch_deg=pitch_deg, t_sim=round(v.t, 3))
        return ACCEPTED

    def capture(self, v: Vehicle, p: tuple[float, ...]) -> int:
        """MAV_CMD_IMAGE_START_CAPTURE: one image (param3 1), told in CAMERA_IMAGE_CAPTURED."""
        if param_int(p[2], 1) != 1:
            return DENIED  # only single shots are simulated
        x, y, z = v.model.position
        lat, lon, alt = v.frame.to_lla(x, y, z)
        index = self.images
        self.images += 1
        v.send(
            "camera_image_captured",
            int(v.t * 1000) & 0xFFFFFFFF,
            0,
            0,
            round(lat * 1e7),
            round(lon * 1e7),
            round(alt * 1000),
            round(z * 1000),
            pitch_quaternion(self.pitch_deg),
            index,
            1,  # capture_result: success
            b"",
        )
        v.log.info(
            "vehicle.photo",
            index=index,
            x_m=round(x, 2),
            y_m=round(y, 2),
            z_m=round(z, 2),
            pitch_deg=round(self.pitch_deg, 1),
            t_sim=round(v.t, 3),
        )
        return ACCEPTED

    def video(self, v: Vehicle, start: bool) -> int:
        """MAV_CMD_VIDEO_START_CAPTURE / _STOP_CAPTURE."""
        if not start and not self.recording:
            return FAILED
        self.recording = start
        v.log.info("vehicle.video", recording=start, t_sim=round(v.t, 3))
        return ACCEPTED

    def attitude_status(self, t_s: float) -> tuple[Any, ...]:
        """GIMBAL_DEVICE_ATTITUDE_STATUS (broadcast: target 0, 0)."""
        return (
            "gimbal_device_attitude_status",
            0,
            0,
            int(t_s * 1000) & 0xFFFFFFFF,
            0,
            pitch_quaternion(self.pitch_deg),
            0.0,
            0.0,
            0.0,
            0,
        )


__all__ = ["GIMBAL_MAX_DEG", "GIMBAL_MIN_DEG", "CameraGimbal", "pitch_quaternion"]
