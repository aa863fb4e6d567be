"""The project's own camera actions, shipped as action plugins (entry points ``eamos.actions``).

They go through the same door as a lab's plugin (docs/plugins.md): pyproject.toml names
these :class:`~eamos.program.plugins.ActionPlugin` objects, and each names its
implementation per adapter family: the simulator's in :mod:`eamos.hal.sim.camera`, MAVLink's
(camera and gimbal protocol commands) in ``eamos.hal.mavlink.camera``.
"""

from __future__ import annotations

from .plugins import ActionPlugin


def _impl(function: str) -> dict[str, str]:
    return {
        "sim": f"eamos.hal.sim.camera:{function}",
        "mavlink": f"eamos.hal.mavlink.camera:{function}",
    }


TAKE_PHOTO = ActionPlugin(
    "TakePhoto",
    (),
    "Take one photo with the camera (the simulator logs where it was taken).",
    _impl("take_photo"),
)
START_VIDEO = ActionPlugin(
    "StartVideo", (), "Start recording video; it records until StopVideo.", _impl("start_video")
)
STOP_VIDEO = ActionPlugin("StopVideo", (), "Stop recording video.", _impl("stop_video"))
GIMBAL = ActionPlugin(
    "Gimbal",
    ("pitch_deg",),
    "Point the camera gimbal to `pitch_deg` degrees (0 level, -90 straight down, up to 30).",
    _impl("gimbal"),
    ranges={"pitch_deg": (-90.0, 30.0)},
)

#: The camera plugins, as pyproject.toml installs them.
CAMERA_PLUGINS = (TAKE_PHOTO, START_VIDEO, STOP_VIDEO, GIMBAL)

__all__ = ["CAMERA_PLUGINS", "GIMBAL", "START_VIDEO", "STOP_VIDEO", "TAKE_PHOTO"]
