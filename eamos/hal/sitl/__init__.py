"""A simulated vehicle that speaks MAVLink like PX4 or ArduCopter SITL (``eamos-sim-vehicle``).

The other end of the MAVLink adapter, for CI and desk tests without an autopilot
build: :mod:`.core` (vehicle state, arming, modes, steps), one personality per
autopilot (:mod:`.px4`, :mod:`.ardupilot`), :mod:`.inbox` (commands and their
acks), :mod:`.streams` (heartbeat and telemetry streams), :mod:`.wire` (MAVLink
numbers, options), :mod:`.manoeuvres` (heading, return to launch, orbits),
:mod:`.payload` (camera and gimbal), :mod:`.vehicle` (the thread and the connection).
"""

from eamos.hal.sitl.vehicle import (
    ACCEPTED,
    DENIED,
    FAILED,
    PERSONALITIES,
    RESULTS,
    TEMPORARILY_REJECTED,
    UNSUPPORTED,
    SimVehicle,
    VehicleOptions,
    parse_reject,
)

__all__ = [
    "ACCEPTED",
    "DENIED",
    "FAILED",
    "PERSONALITIES",
    "RESULTS",
    "TEMPORARILY_REJECTED",
    "UNSUPPORTED",
    "SimVehicle",
    "VehicleOptions",
    "parse_reject",
]
