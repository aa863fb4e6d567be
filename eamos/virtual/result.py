"""What a virtual-time run found: per-drone records, resolutions and final states."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from ..actors.messages import ActionRecord


@dataclass(frozen=True)
class Waiting:
    """A node still unfinished when the virtual-time limit was reached, and why."""

    drone: str
    node: str
    label: str
    why: str


@dataclass(frozen=True)
class DroneOutcome:
    """One participant's part of a virtual run (times are virtual seconds from start).

    ``actions`` are in start order (ties by node key), as in the run summary;
    ``resolved`` holds the statuses of its top-level nodes; ``final`` is the
    vehicle's state when the run ended and the vehicles settled (a simulated drone
    disarms by itself a moment after landing, as autopilots do; ``None`` for the
    ground station).
    """

    drone: str
    actions: tuple[ActionRecord, ...]
    resolved: Mapping[str, str] = field(hash=False)
    all_resolved: bool
    triggers_sent: int
    triggers_received: int
    final: Any = None  # eamos.hal.kinematics.VehicleState, or the vehicle's own snapshot

    @property
    def blocked(self) -> tuple[str, ...]:
        """Top-level nodes that resolved ``failed`` (blocked by a failure)."""
        return tuple(sorted(k for k, s in self.resolved.items() if s == "failed"))

    @property
    def ok(self) -> bool:
        """Resolved, no failed action, no blocked node (the summary's ``ok``)."""
        return (
            self.all_resolved
            and not self.blocked
            and all(a.result != "failed" for a in self.actions)
        )

    def action_names(self) -> list[str]:
        """The actions in start order, by name."""
        return [a.action for a in self.actions]


@dataclass(frozen=True)
class VirtualRun:
    """The outcome of :func:`eamos.virtual.run_virtual`.

    ``duration_s`` is when the last participant resolved; ``timed_out`` means the
    virtual-time limit came first; ``waiting`` then lists the nodes that were still
    waiting and for what.
    """

    mission: str
    drones: Mapping[str, DroneOutcome] = field(hash=False)
    duration_s: float
    timed_out: bool
    waiting: tuple[Waiting, ...] = ()
    steps: int = 0
    #: The actions a continuation ended at once, as its snapshot shows they had (drone, node,
    #: activation): in ``drones[...].actions`` too, with no duration.
    replayed: tuple[tuple[str, str, tuple[int, ...]], ...] = ()

    @property
    def ok(self) -> bool:
        """Every participant resolved and ok, within the time limit."""
        return not self.timed_out and all(d.ok for d in self.drones.values())

    def actions(self, drone: str) -> list[tuple[str, tuple[float, ...], str]]:
        """(action, args, result) of ``drone`` in start order."""
        return [(a.action, a.args, a.result) for a in self.drones[drone].actions]
