"""A whole mission in one thread, in virtual time: no sockets, no actors, no clock reads.

Public names: :func:`run_virtual` (and :class:`VirtualMission` for finer
control), its result :class:`VirtualRun` / :class:`DroneOutcome` /
:class:`Waiting`, and for vehicles :class:`Vehicle`, :data:`VehicleFactory`,
:func:`sim_vehicles`; :data:`Decide` / :func:`install_decide`, the hook
deciding conditions the simulation cannot know.  Tests of control structures
and the pre-flight checker build on it.
"""

from .decisions import Decide, install_decide
from .driver import TIME_LIMIT_S, VirtualMission, run_virtual, telemetry_values
from .result import DroneOutcome, VirtualRun, Waiting
from .vehicles import (
    STEP_S,
    IdleVehicle,
    QuietLog,
    QuietVehicle,
    Vehicle,
    VehicleFactory,
    sim_vehicles,
)

__all__ = [
    "STEP_S",
    "TIME_LIMIT_S",
    "Decide",
    "DroneOutcome",
    "IdleVehicle",
    "QuietLog",
    "QuietVehicle",
    "Vehicle",
    "VehicleFactory",
    "VirtualMission",
    "VirtualRun",
    "Waiting",
    "install_decide",
    "run_virtual",
    "sim_vehicles",
    "telemetry_values",
]
