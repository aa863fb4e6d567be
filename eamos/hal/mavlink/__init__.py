"""The MAVLink adapter: PX4 and ArduPilot autopilots (real, SITL, or ``eamos-sim-vehicle``).

Modules: :mod:`.adapter` (the adapter the uniform API drives: a thread per action,
cancel, abort, close), :mod:`.runs` (its running actions, one ``done`` each),
:mod:`.publisher` (telemetry samples to the mission), :mod:`.flight` (which phase flies
a command) and the phases: :mod:`.arming` (Arm, Disarm, a settled estimate first),
:mod:`.takeoff`, :mod:`.moves` (FlyBy*, FlyTo*), :mod:`.landing` (Land, abort, landing at
close), :mod:`.braking` (stop now, hold), :mod:`.manoeuvres` (ReturnHome, Hold, Yaw,
SetSpeed, Orbit); :mod:`.control` (one run's hold on the vehicle: the autopilots'
controller) and :mod:`.waits` (how actions wait and end), :mod:`.completion` and
:mod:`.settling` (when a move has arrived: tolerances scaled for short moves, the settle
window); :mod:`.vehicle` (the vehicle
in mission terms), :mod:`.link`, :mod:`.ticker` and :mod:`.state` (the MAVLink
connection, its periodic jobs and the messages it reads), :mod:`.command_protocol` and
:mod:`.param_protocol` (the MAVLink exchanges), :mod:`.signing` (MAVLink 2 signing keys
and rules), :mod:`.autopilots` (what differs between PX4 and ArduPilot), :mod:`.frames`
(mission frame <-> NED), :mod:`.settings` (the ``hal`` section), :mod:`.params` and
:mod:`.keeper` (the drone type's speeds set on the vehicle and restored),
:mod:`.targets` (SET_POSITION_TARGET_* messages), :mod:`.estimator` and :mod:`.home` (a
position estimate good enough to fly, per autopilot; home from it), :mod:`.payload`
and :mod:`.camera` (plugin actions: the "mavlink" seam, the camera and gimbal).
Importing this package does not load pymavlink; connecting does.
"""

from eamos.hal.mavlink.adapter import MavlinkAdapter, mavlink_adapter_from_settings
from eamos.hal.mavlink.settings import MavlinkSettings

__all__ = ["MavlinkAdapter", "MavlinkSettings", "mavlink_adapter_from_settings"]
