"""Per-drone tracks in the fleet frame, recorded from the vehicles in virtual time.

:class:`TrackRecorder` wraps a vehicle of the virtual driver and records its
state after every step.  The simulator integrates at fixed steps, so between two
steps a drone moves on a straight line: the track is exactly piecewise linear.
Points where the velocity does not change are dropped as they come, so a drone
hovering for a minute costs two points, not three thousand.
"""

from __future__ import annotations

import bisect
from dataclasses import dataclass
from typing import Any

from ..hal.api import ActionHandle, DoneCallback, Telemetry
from ..hal.sim import SimCore
from ..program.plugins import EMPTY_PLUGINS, PluginRegistry
from ..program.uniform import Command
from ..virtual import IdleVehicle, QuietVehicle, Vehicle
from ..virtual.vehicles import Clock, Finished, settles

#: (t_s, north_m, east_m, up_m, airborne, armed, battery_pct), as recorded.
_Raw = tuple[float, float, float, float, bool, bool, float]
#: Two velocities closer than this (m per step) count as the same (a straight piece).
_STRAIGHT_M = 1e-9


@dataclass(frozen=True)
class TrackPoint:
    """A drone at a virtual time: fleet-frame position, flags, battery."""

    t_s: float
    north_m: float
    east_m: float
    up_m: float
    airborne: bool
    armed: bool
    battery_pct: float

    @property
    def position(self) -> tuple[float, float, float]:
        """(north, east, up) in metres."""
        return (self.north_m, self.east_m, self.up_m)


@dataclass(frozen=True)
class Track:
    """A drone's piecewise-linear track: its points in time order."""

    drone: str
    points: tuple[TrackPoint, ...]

    def at(self, t_s: float) -> tuple[float, float, float]:
        """The position at ``t_s`` (linear between points, held outside them)."""
        pts = self.points
        i = bisect.bisect_right([p.t_s for p in pts], t_s)
        if i == 0:
            return pts[0].position
        if i >= len(pts):
            return pts[-1].position
        a, b = pts[i - 1], pts[i]
        f = (t_s - a.t_s) / (b.t_s - a.t_s) if b.t_s > a.t_s else 0.0
        return (
            a.north_m + f * (b.north_m - a.north_m),
            a.east_m + f * (b.east_m - a.east_m),
            a.up_m + f * (b.up_m - a.up_m),
        )


class TrackRecorder:
    """A :class:`~eamos.virtual.Vehicle` that records the track of the one it wraps."""

    def __init__(self, drone: str, inner: Vehicle, clock: Clock, home: tuple[float, float]) -> None:
        self.drone = drone
        self._inner = inner
        self._clock = clock
        self._home = home
        self._idle = inner if isinstance(inner, IdleVehicle) else None  # checked once: slow
        self._quiet = inner if isinstance(inner, QuietVehicle) else None
        self._settles = settles(inner)
        # A simulator core tells where it is without building a whole state (every step).
        self._where = inner.where if isinstance(inner, SimCore) else None
        # Plain tuples while recording (one per step): TrackPoints only when asked.
        self._raw: list[_Raw] = []

    @property
    def plugins(self) -> PluginRegistry:
        """The plugin actions the wrapped vehicle runs (none if it does not say)."""
        plugins: PluginRegistry = getattr(self._inner, "plugins", EMPTY_PLUGINS)
        return plugins

    def start(self) -> Telemetry:
        """Start the vehicle and record where it stands."""
        first = self._inner.start()
        self._record()
        return first

    def run(self, command: Command, done: DoneCallback) -> ActionHandle:
        """As the wrapped vehicle."""
        return self._inner.run(command, done)

    def cancel(self, handle: ActionHandle) -> None:
        """As the wrapped vehicle."""
        self._inner.cancel(handle)

    def abort(self) -> None:
        """As the wrapped vehicle."""
        self._inner.abort()

    def step(self) -> tuple[list[Finished], list[Telemetry]]:
        """One step of the wrapped vehicle, then record its state."""
        out = self._inner.step()
        self._record()
        return out

    def state(self) -> Any:
        """As the wrapped vehicle."""
        return self._inner.state()

    @property
    def settling(self) -> bool:
        """As the wrapped vehicle (False if it cannot tell)."""
        return self._settles is not None and self._settles.settling

    def idle_steps(self, limit: int) -> int:
        """As the wrapped vehicle (0 if it cannot tell)."""
        return self._idle.idle_steps(limit) if self._idle is not None else 0

    def quiet_steps(self, limit: int) -> int:
        """As the wrapped vehicle (its idle steps if it cannot tell)."""
        if self._quiet is not None:
            return self._quiet.quiet_steps(limit)
        return self.idle_steps(limit)

    def unsent(self) -> Telemetry | None:
        """As the wrapped vehicle (None if it cannot tell)."""
        return self._quiet.unsent() if self._quiet is not None else None

    def skip(self, steps: int) -> None:
        """Skip idle steps of the wrapped vehicle; the track stays a point at rest."""
        if self._idle is None:
            raise RuntimeError(f"{self.drone}: the vehicle cannot skip steps")
        self._idle.skip(steps)
        self._record()

    def _record(self) -> None:
        if self._where is not None:
            x, y, z, landed, armed, battery = self._where()
        else:
            st = self._inner.state()
            x, y, z, landed, armed, battery = (
                st.x_m, st.y_m, st.z_m, st.landed, st.armed, st.battery_pct
            )  # fmt: skip
        raw = (self._clock(), self._home[0] + x, self._home[1] + y, z, not landed, armed, battery)
        pts = self._raw
        if len(pts) >= 2 and _straight(pts[-2], pts[-1], raw):
            pts[-1] = raw  # the middle point adds nothing to a straight piece
        else:
            pts.append(raw)

    def track(self) -> Track:
        """The track recorded so far."""
        return Track(self.drone, tuple(TrackPoint(*raw) for raw in self._raw))


def _straight(a: _Raw, b: _Raw, c: _Raw) -> bool:
    """True when b lies on the straight, constant-speed piece from a to c (same flags)."""
    if a[4:6] != b[4:6] or b[4:6] != c[4:6]:
        return False
    if a[1:4] == b[1:4] == c[1:4]:
        return True  # at rest: the common case, decided without arithmetic
    dt1, dt2 = b[0] - a[0], c[0] - b[0]
    if dt1 <= 0 or dt2 <= 0:
        return False
    span = max(dt1, dt2)
    for k in (1, 2, 3):
        if abs((b[k] - a[k]) / dt1 - (c[k] - b[k]) / dt2) * span > _STRAIGHT_M:
            return False
    return True


__all__ = ["Track", "TrackPoint", "TrackRecorder"]
