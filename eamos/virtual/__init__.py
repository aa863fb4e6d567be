"""A whole mission in one thread, in virtual time: no sockets, no actors, no clock reads.

Public names: :func:`run_virtual` (and :class:`VirtualMission` for finer
control), its result :class:`VirtualRun` / :class:`DroneOutcome` /
:class:`Waiting`, and for vehicles :class:`Vehicle`, :data:`VehicleFactory`,
:func:`sim_vehicles`; :data:`Decide` / :func:`install_decide`, the hook
deciding conditions the simulation cannot know; :func:`load_snapshot` and
:func:`continuation` (a :class:`Continuation`, or :class:`SnapshotError`), to go
on from a mission's snapshot.  Tests of control structures
and the pre-flight checker build on it.
"""

from ..actors.continuation import Continuation, SnapshotError, continuation, load_snapshot
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
    "Continuation",
    "Decide",
    "DroneOutcome",
    "IdleVehicle",
    "QuietLog",
    "QuietVehicle",
    "SnapshotError",
    "Vehicle",
    "VehicleFactory",
    "VirtualMission",
    "VirtualRun",
    "Waiting",
    "continuation",
    "install_decide",
    "load_snapshot",
    "run_virtual",
    "sim_vehicles",
    "telemetry_values",
]
