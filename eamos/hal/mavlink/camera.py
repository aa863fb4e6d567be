"""TakePhoto, StartVideo, StopVideo and Gimbal on MAVLink (the camera plugins' ``"mavlink"`` code).

Both autopilots take these on the autopilot's own component (PX4's camera
trigger and gimbal manager, ArduPilot's AP_Camera and AP_Mount):

* TakePhoto: MAV_CMD_IMAGE_START_CAPTURE (param1 0: every camera, param2 0
  interval, param3 1 image, param4 the next sequence number); done at the photo's
  report that follows: CAMERA_IMAGE_CAPTURED (PX4, MAVLink cameras) or, from
  ArduPilot, which never sends that, CAMERA_FEEDBACK (AP_Camera_Backend::log_picture
  sends it for every picture taken); logged as ``adapter.photo`` with where it was
  taken (lat, lon, alt; x, y, z in the mission frame) and the gimbal's pitch.
* StartVideo / StopVideo: MAV_CMD_VIDEO_START_CAPTURE / MAV_CMD_VIDEO_STOP_CAPTURE
  (param1 0: every stream); done at the acknowledgement.
* Gimbal(pitch_deg): gimbal protocol v2, MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW
  (param1 pitch, param2 yaw 0: ahead, rates NaN, flags 0, param7 0: the primary
  gimbal); done when GIMBAL_DEVICE_ATTITUDE_STATUS shows the pitch within
  :data:`GIMBAL_TOLERANCE_DEG`.  ArduPilot sends that message only when asked, so it is
  asked for first (MAV_CMD_SET_MESSAGE_INTERVAL, message 285, at
  :data:`GIMBAL_STATUS_HZ`; a refusal is logged and the wait goes on).

Each is a :mod:`eamos.hal.mavlink.payload` implementation: ``(ctx, command) -> ActionResult``.
"""

from __future__ import annotations

import math

from eamos.hal.api import ActionResult
from eamos.hal.mavlink.autopilots import CommandRejected
from eamos.hal.mavlink.payload import PayloadContext
from eamos.hal.mavlink.waits import Failed
from eamos.program.uniform import PluginAction

MAV_CMD_IMAGE_START_CAPTURE = 2000
MAV_CMD_VIDEO_START_CAPTURE = 2500
MAV_CMD_VIDEO_STOP_CAPTURE = 2501
MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW = 1000
MAV_CMD_SET_MESSAGE_INTERVAL = 511
MSG_GIMBAL_DEVICE_ATTITUDE_STATUS = 285
#: How often the gimbal's attitude is asked for while a Gimbal action waits (vehicle Hz).
GIMBAL_STATUS_HZ = 10.0
#: How long a photo may take to be reported, and a gimbal to turn (vehicle seconds).
PHOTO_TIMEOUT_S = 5.0
GIMBAL_TIMEOUT_S = 10.0
#: A Gimbal action is done within this many degrees of the pitch.
GIMBAL_TOLERANCE_DEG = 2.0


def take_photo(ctx: PayloadContext, command: PluginAction) -> ActionResult:
    """One photo; done when CAMERA_IMAGE_CAPTURED says where it was taken."""
    seen = ctx.read(lambda st: st.image_serial)
    ctx.command(MAV_CMD_IMAGE_START_CAPTURE, (0.0, 0.0, 1.0, float(seen + 1), 0.0, 0.0, 0.0))
    ctx.wait(
        lambda st: st.image_serial > seen,
        PHOTO_TIMEOUT_S,
        f"the camera acknowledged but reported no photo (CAMERA_IMAGE_CAPTURED or "
        f"CAMERA_FEEDBACK) within {PHOTO_TIMEOUT_S:g} s",
    )
    image = ctx.read(lambda st: st.images[-1])
    if not image.ok:
        raise Failed(f"the camera could not take image {image.index}")
    where = ctx.position()
    pitch = ctx.read(lambda st: st.gimbal_pitch_deg)
    ctx.log.info(
        "adapter.photo",
        index=image.index,
        lat_deg=round(image.lat_deg, 7),
        lon_deg=round(image.lon_deg, 7),
        alt_m=round(image.rel_alt_m, 2),
        x_m=None if where is None else round(where[0], 2),
        y_m=None if where is None else round(where[1], 2),
        z_m=None if where is None else round(where[2], 2),
        pitch_deg=None if pitch is None else round(pitch, 1),
    )
    return ActionResult("ok")


def start_video(ctx: PayloadContext, command: PluginAction) -> ActionResult:
    """Start recording (every stream)."""
    ctx.command(MAV_CMD_VIDEO_START_CAPTURE, (0.0,) * 7)
    ctx.log.info("adapter.video", recording=True)
    return ActionResult("ok")


def stop_video(ctx: PayloadContext, command: PluginAction) -> ActionResult:
    """Stop recording."""
    ctx.command(MAV_CMD_VIDEO_STOP_CAPTURE, (0.0,) * 7)
    ctx.log.info("adapter.video", recording=False)
    return ActionResult("ok")


def gimbal(ctx: PayloadContext, command: PluginAction) -> ActionResult:
    """Point the gimbal to ``pitch_deg`` (yaw ahead); done when its attitude shows it."""
    pitch = command.value("pitch_deg")
    nan = math.nan
    try:
        interval_us = 1e6 / GIMBAL_STATUS_HZ
        ctx.command(
            MAV_CMD_SET_MESSAGE_INTERVAL,
            (float(MSG_GIMBAL_DEVICE_ATTITUDE_STATUS), interval_us, 0.0, 0.0, 0.0, 0.0, 0.0),
        )
    except CommandRejected as exc:
        ctx.log.info("adapter.gimbal.status_refused", reason=str(exc))
    ctx.command(MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW, (pitch, 0.0, nan, nan, 0.0, 0.0, 0.0))
    ctx.wait(
        lambda st: (
            st.gimbal_pitch_deg is not None
            and abs(st.gimbal_pitch_deg - pitch) <= GIMBAL_TOLERANCE_DEG
        ),
        GIMBAL_TIMEOUT_S,
        f"the gimbal did not reach pitch {pitch:g} deg within {GIMBAL_TIMEOUT_S:g} s "
        "(no GIMBAL_DEVICE_ATTITUDE_STATUS?)",
    )
    ctx.log.info("adapter.gimbal", pitch_deg=pitch)
    return ActionResult("ok")


__all__ = ["gimbal", "start_video", "stop_video", "take_photo"]
