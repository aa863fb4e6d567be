"""The camera plugins' simulator implementations (specs: :mod:`eamos.program.camera`).

Pure functions of :mod:`eamos.hal.sim.plugin_api`: a photo is logged with where it was
taken; video recording and the gimbal's pitch are kept in the payload state
(``video``: 1 while recording, ``gimbal_pitch_deg``), shown in ``adapter.action.end``.
"""

from __future__ import annotations

from eamos.hal.sim.plugin_api import SimOutcome, SimView
from eamos.program.uniform import PluginAction

#: How long the simulated gimbal takes per degree of pitch change (s/deg).
GIMBAL_S_PER_DEG = 0.01


def take_photo(view: SimView, command: PluginAction) -> SimOutcome:
    """One photo: logged with the vehicle's position, heading and gimbal pitch; counted."""
    count = view.payload.get("photos", 0.0) + 1.0
    return SimOutcome(
        payload={"photos": count},
        log={
            "photo": int(count),
            "x_m": round(view.x_m, 3),
            "y_m": round(view.y_m, 3),
            "z_m": round(view.z_m, 3),
            "heading_deg": round(view.heading_deg, 1),
            "gimbal_pitch_deg": view.payload.get("gimbal_pitch_deg", 0.0),
        },
    )


def start_video(view: SimView, command: PluginAction) -> SimOutcome:
    """Start recording (fails if already recording)."""
    if view.payload.get("video", 0.0):
        return SimOutcome(failed="already recording")
    return SimOutcome(payload={"video": 1.0}, log={"video": "start"})


def stop_video(view: SimView, command: PluginAction) -> SimOutcome:
    """Stop recording (fails if not recording)."""
    if not view.payload.get("video", 0.0):
        return SimOutcome(failed="not recording")
    return SimOutcome(payload={"video": 0.0}, log={"video": "stop"})


def gimbal(view: SimView, command: PluginAction) -> SimOutcome:
    """Pitch the gimbal; takes :data:`GIMBAL_S_PER_DEG` per degree of change."""
    pitch = command.value("pitch_deg")
    if not -90.0 <= pitch <= 30.0:
        return SimOutcome(failed=f"pitch_deg {pitch:g} outside -90 to 30")
    change = abs(pitch - view.payload.get("gimbal_pitch_deg", 0.0))
    return SimOutcome(
        duration_s=max(0.2, change * GIMBAL_S_PER_DEG),
        payload={"gimbal_pitch_deg": pitch},
        log={"gimbal_pitch_deg": pitch},
    )


__all__ = ["GIMBAL_S_PER_DEG", "gimbal", "start_video", "stop_video", "take_photo"]
