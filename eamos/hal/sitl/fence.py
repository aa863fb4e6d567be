"""The simulated vehicle's geofence: where it may fly, from the fence items uploaded to it.

A fence is what the mission protocol's FENCE list holds (:mod:`.missions`):
inclusion and exclusion polygons (MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION /
_EXCLUSION, param1 the vertex count, consecutive items one polygon) and circles
(MAV_CMD_NAV_FENCE_CIRCLE_INCLUSION / _EXCLUSION, param1 the radius), plus a
ceiling and, for ArduCopter's FENCE_TYPE circle, a radius around home, which
the personalities take from their parameters.  The vehicle is inside when it
is inside every inclusion polygon and circle (there is at least one, or none
is given), outside every exclusion, and not above the ceiling.

The geometry (:class:`Geofence`) is pure: points in the vehicle's local frame
(x north, y east, metres from home), no clock.  :class:`FenceWatch` applies it
to the flying vehicle: it holds the uploaded fence, asks the autopilot what it
enforces now, and tells it when the vehicle leaves the fence and comes back.
What a breach does is the personality's business (ArduCopter FENCE_ACTION,
PX4 GF_ACTION).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Generic, Protocol, TypeVar

from eamos.hal.kinematics import GeoFrame, Quadcopter
from eamos.hal.sitl.missions import (
    FENCE_CIRCLE_EXCLUSION,
    FENCE_CIRCLE_INCLUSION,
    FENCE_POLYGON_EXCLUSION,
    FENCE_POLYGON_INCLUSION,
    GLOBAL_FRAMES,
    MissionItem,
)
from eamos.hal.sitl.wire import SEV_CRITICAL

if TYPE_CHECKING:
    from eamos.logs import EventLog

Point = tuple[float, float]


def inside_polygon(point: Point, polygon: Sequence[Point]) -> bool:
    """Whether ``point`` lies inside ``polygon`` (even-odd rule; pure)."""
    x, y = point
    inside = False
    n = len(polygon)
    for i in range(n):
        (x1, y1), (x2, y2) = polygon[i], polygon[(i + 1) % n]
        if (y1 > y) != (y2 > y):
            cross = x1 + (y - y1) * (x2 - x1) / (y2 - y1)
            if x < cross:
                inside = not inside
    return inside


@dataclass(frozen=True)
class Circle:
    """A circle in the local frame."""

    x: float
    y: float
    radius_m: float

    def contains(self, point: Point) -> bool:
        """Whether ``point`` is inside (or on) the circle."""
        return math.hypot(point[0] - self.x, point[1] - self.y) <= self.radius_m


@dataclass(frozen=True)
class Geofence:
    """Polygons and circles that bound where the vehicle may fly (see module docstring)."""

    inclusion: tuple[tuple[Point, ...], ...] = ()
    exclusion: tuple[tuple[Point, ...], ...] = ()
    circles_in: tuple[Circle, ...] = ()
    circles_out: tuple[Circle, ...] = ()

    @property
    def empty(self) -> bool:
        """No horizontal boundary at all."""
        return not (self.inclusion or self.exclusion or self.circles_in or self.circles_out)

    def horizontal_breach(self, point: Point) -> str | None:
        """``"polygon"`` or ``"circle"`` when ``point`` is outside what bounds it, else None."""
        if any(not inside_polygon(point, p) for p in self.inclusion):
            return "polygon"
        if any(inside_polygon(point, p) for p in self.exclusion):
            return "polygon"
        if any(not c.contains(point) for c in self.circles_in):
            return "circle"
        if any(c.contains(point) for c in self.circles_out):
            return "circle"
        return None

    @classmethod
    def from_items(cls, items: Iterable[MissionItem], frame: GeoFrame) -> Geofence:
        """The fence the FENCE list's items describe; ValueError for an inconsistent list."""
        inclusion: list[tuple[Point, ...]] = []
        exclusion: list[tuple[Point, ...]] = []
        circles_in: list[Circle] = []
        circles_out: list[Circle] = []
        polygon: list[Point] = []
        expected, kind = 0, 0
        for item in items:
            if item.frame not in GLOBAL_FRAMES:
                raise ValueError(f"fence item {item.seq}: frame {item.frame} is not global")
            north, east, _ = frame.from_lla(item.lat_deg, item.lon_deg, 0.0)
            if item.command in (FENCE_POLYGON_INCLUSION, FENCE_POLYGON_EXCLUSION):
                if not polygon:
                    expected, kind = round(item.param1), item.command
                    if expected < 3:
                        raise ValueError(f"fence item {item.seq}: a polygon needs 3 vertices")
                elif item.command != kind or round(item.param1) != expected:
                    raise ValueError(f"fence item {item.seq}: polygon {len(inclusion)} incomplete")
                polygon.append((north, east))
                if len(polygon) == expected:
                    target = inclusion if kind == FENCE_POLYGON_INCLUSION else exclusion
                    target.append(tuple(polygon))
                    polygon = []
                continue
            if polygon:
                raise ValueError(f"fence item {item.seq}: the polygon before it is incomplete")
            if item.command in (FENCE_CIRCLE_INCLUSION, FENCE_CIRCLE_EXCLUSION):
                if not item.param1 > 0:
                    raise ValueError(f"fence item {item.seq}: a circle needs a radius")
                circle = Circle(north, east, float(item.param1))
                (circles_in if item.command == FENCE_CIRCLE_INCLUSION else circles_out).append(
                    circle
                )
        if polygon:
            raise ValueError("the fence's last polygon is incomplete")
        return cls(tuple(inclusion), tuple(exclusion), tuple(circles_in), tuple(circles_out))


@dataclass(frozen=True)
class FenceLimits:
    """What an autopilot's fence parameters enable: a ceiling (m above home), a radius
    around home (m), and the uploaded polygons and circles."""

    ceiling_m: float | None = None
    radius_m: float | None = None
    uploaded: bool = True


class FencedVehicle(Protocol):
    """What a :class:`FenceWatch` reads of the vehicle it watches (a ``VehicleCore``)."""

    t: float
    armed: bool
    model: Quadcopter
    frame: GeoFrame
    log: EventLog

    def text(self, text: str, severity: int = ...) -> None:
        """Narrate ``text`` (STATUSTEXT)."""
        ...


VehicleT = TypeVar("VehicleT", bound=FencedVehicle)
VehicleT_contra = TypeVar("VehicleT_contra", bound=FencedVehicle, contravariant=True)


class FencePolicy(Protocol[VehicleT_contra]):
    """The autopilot's side of the fence (its ``Personality``): what is enforced, the reaction."""

    def fence_limits(self, v: VehicleT_contra) -> FenceLimits | None:
        """What its fence parameters enable now; None: no fence is enforced."""
        ...

    def fence_breached(self, v: VehicleT_contra, kind: str) -> None:
        """The vehicle just left its fence (``kind``: altitude, circle, polygon): react."""
        ...

    def fence_cleared(self, v: VehicleT_contra) -> None:
        """The vehicle is back inside its fence."""
        ...


class FenceWatch(Generic[VehicleT]):
    """Whether one flying vehicle is inside the fence its autopilot enforces.

    Holds the :class:`Geofence` made of the uploaded FENCE list (:meth:`load`)
    and the breach the vehicle is in, if any (:attr:`breach`).  What is
    enforced is asked of ``policy`` each time, because a PARAM_SET may change
    it between two steps.  A breach begins when the armed vehicle, off the
    ground, is outside, and is told to ``policy`` once; so is its end.
    """

    def __init__(self, vehicle: VehicleT, policy: FencePolicy[VehicleT]) -> None:
        self.v = vehicle
        self.policy = policy
        self.geofence = Geofence()
        self.breach: str | None = None  # what the vehicle is outside of, if anything

    def load(self, items: Iterable[MissionItem]) -> None:
        """The FENCE list changed: enforce what ``items`` describe (an inconsistent list:
        no fence, and the vehicle says why)."""
        v = self.v
        try:
            self.geofence = Geofence.from_items(items, v.frame)
        except ValueError as exc:
            self.geofence = Geofence()
            v.text(f"Fence: {exc}", SEV_CRITICAL)
            return
        v.log.info(
            "vehicle.fence",
            inclusion=len(self.geofence.inclusion),
            exclusion=len(self.geofence.exclusion),
            circles=len(self.geofence.circles_in) + len(self.geofence.circles_out),
            t_sim=round(v.t, 3),
        )

    def outside(self, point: tuple[float, float, float]) -> str | None:
        """What of the enforced fence ``point`` is outside of (altitude, circle, polygon)."""
        limits = self.policy.fence_limits(self.v)
        if limits is None:
            return None
        x, y, z = point
        if limits.ceiling_m is not None and z > limits.ceiling_m:
            return "altitude"
        if limits.radius_m is not None and math.hypot(x, y) > limits.radius_m:
            return "circle"
        if limits.uploaded:
            return self.geofence.horizontal_breach((x, y))
        return None

    def check(self) -> None:
        """A breach (leaving the fence while flying) is told to the policy once."""
        v = self.v
        if not v.armed or v.model.landed:
            self.breach = None
            return
        kind = self.outside(v.model.position)
        if kind is not None and self.breach is None:
            self.breach = kind
            st = v.model.state
            v.log.warning(
                "vehicle.fence.breach",
                kind=kind,
                x_m=round(st.x_m, 2),
                y_m=round(st.y_m, 2),
                z_m=round(st.z_m, 2),
                t_sim=round(v.t, 3),
            )
            self.policy.fence_breached(v, kind)
        elif kind is None and self.breach is not None:
            self.breach = None
            v.log.info("vehicle.fence.cleared", t_sim=round(v.t, 3))
            self.policy.fence_cleared(v)


__all__ = [
    "Circle",
    "FenceLimits",
    "FencePolicy",
    "FenceWatch",
    "FencedVehicle",
    "Geofence",
    "inside_polygon",
]
