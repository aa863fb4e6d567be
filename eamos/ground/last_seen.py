"""Where the ground station last saw a drone: what a drone that sent no report was doing.

Kept apart from :mod:`.station` (which runs a runtime) and :mod:`.summary` (which
reads files): both use it, and reading a summary must load no sockets.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

__all__ = ["LastSeen"]


@dataclass(frozen=True)
class LastSeen:
    """Where the ground station last saw a drone: its latest telemetry (JSON ``last_seen``).

    What a drone whose node died without a report (``kill -9``, a crash) was last
    known to be doing: a MAVLink vehicle may still hover there until something
    lands it.
    """

    x: float
    y: float
    z: float
    armed: bool
    landed: bool | None  # None: the telemetry did not say
    t: float  # wall-clock time the sample arrived

    def describe(self) -> str:
        """``last seen in the air, armed, at (x, y, z) m from its home``."""
        arming = "armed" if self.armed else "disarmed"
        if self.landed is False:
            how = f"in the air, {arming},"
        elif self.landed:
            how = f"on the ground, {arming},"
        else:
            how = arming
        return f"last seen {how} at ({self.x:.2f}, {self.y:.2f}, {self.z:.2f}) m from its home"

    def to_json(self) -> dict[str, Any]:
        """The ``last_seen`` object."""
        return {
            "x": self.x,
            "y": self.y,
            "z": self.z,
            "armed": self.armed,
            "landed": self.landed,
            "t": self.t,
        }

    @classmethod
    def from_json(cls, data: Any) -> LastSeen | None:
        """Read a ``last_seen`` object (None when absent or not one)."""
        if not isinstance(data, Mapping):
            return None
        try:
            landed = data.get("landed")
            return cls(
                float(data["x"]),
                float(data["y"]),
                float(data["z"]),
                bool(data["armed"]),
                None if landed is None else bool(landed),
                float(data["t"]),
            )
        except (KeyError, TypeError, ValueError):
            return None
