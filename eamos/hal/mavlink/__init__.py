"""The MAVLink adapter: PX4 and ArduPilot autopilots (real, SITL, or ``eamos-sim-vehicle``).

Modules: :mod:`.adapter` (the adapter the uniform API drives), :mod:`.flight` (one
action at a time: arm, take off, move, land, cancel), :mod:`.vehicle` (the vehicle's
state from telemetry), :mod:`.link` and :mod:`.state` (the MAVLink connection and the
messages it reads), :mod:`.autopilots` (what differs between PX4 and ArduPilot),
:mod:`.frames` (mission frame <-> NED), :mod:`.settings` (the ``hal`` section),
:mod:`.braking` (stop now, wait until at rest), :mod:`.params` and :mod:`.keeper`
(the drone type's speeds set on the vehicle and restored), :mod:`.targets`
(SET_POSITION_TARGET_* messages), :mod:`.signing` (MAVLink 2 signing keys and rules),
:mod:`.waits` (how actions wait and end), :mod:`.estimator`, :mod:`.arming` and
:mod:`.home` (a settled estimate before arming, home from it), :mod:`.manoeuvres`
(ReturnHome, Hold, Yaw, SetSpeed, Orbit), :mod:`.payload` and :mod:`.camera` (plugin
actions: the "mavlink" seam, the camera and gimbal).
Importing this package does not load pymavlink; connecting does.
"""

from eamos.hal.mavlink.adapter import MavlinkAdapter, mavlink_adapter_from_settings
from eamos.hal.mavlink.settings import MavlinkSettings

__all__ = ["MavlinkAdapter", "MavlinkSettings", "mavlink_adapter_from_settings"]
