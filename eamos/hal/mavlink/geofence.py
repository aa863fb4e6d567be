"""The fleet's geofence on the vehicle itself: set before the first arming, put back at close.

``eamos check`` keeps every planned track inside the fleet's ``[safety]``
``geofence_m`` polygon and below ``max_altitude_m``; nothing in the plan keeps a
drone inside them when its node dies or a command goes wrong.  The autopilots
can: so before its first arming the adapter gives each MAVLink vehicle the
fleet's polygon (in WGS84, placed from the vehicle's home and the drone's
``home_m`` in the fleet frame) and ceiling, and the autopilot's own breach
action stops a vehicle that crosses them:

=========== =========================================== ================================
autopilot   polygon (mission protocol, MAV_MISSION_      ceiling and action (parameters)
            TYPE_FENCE, MAV_CMD_NAV_FENCE_POLYGON_
            VERTEX_INCLUSION items)
=========== =========================================== ================================
ardupilot   uploaded; FENCE_TYPE gets its polygon bit    FENCE_ALT_MAX (m above home),
            (4)                                          FENCE_TYPE bit 1, FENCE_ACTION 4
                                                         (Brake, else Land), FENCE_ENABLE 1
px4         uploaded (PX4 enforces it while armed)       GF_MAX_VER_DIST (m above home),
                                                         GF_ACTION 2 (Hold)
=========== =========================================== ================================

The fence the vehicle had before (downloaded first) is uploaded again at close,
or the fence cleared when it had none; the parameters go back to their old
values with the drone type's speeds (:class:`~eamos.hal.mavlink.keeper.ParamKeeper`).
A vehicle a pilot took over keeps the fence (and the adapter says so).

:func:`fence_plan` is pure (what to upload and set); :class:`GeofenceKeeper` does it
over the vehicle's link.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Protocol

from eamos.hal.kinematics import GeoFrame
from eamos.hal.mavlink.mission_protocol import (
    MAV_MISSION_TYPE_FENCE,
    MissionError,
    MissionItem,
    MissionProtocol,
)

if TYPE_CHECKING:
    from eamos.hal.mavlink.keeper import ParamKeeper
    from eamos.hal.mavlink.link import MavlinkLink
    from eamos.hal.mavlink.settings import MavlinkSettings
    from eamos.logs import EventLog

MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION = 5001
MAV_FRAME_GLOBAL = 0
#: ArduPilot's FENCE_TYPE bits and FENCE_ACTION "Brake, or Land when Brake is unavailable".
FENCE_TYPE_ALT_MAX = 1
FENCE_TYPE_POLYGON = 4
FENCE_ACTION_BRAKE_OR_LAND = 4
#: PX4's GF_ACTION "Hold mode".
GF_ACTION_HOLD = 2


@dataclass(frozen=True)
class FencePlan:
    """What goes on one vehicle: the polygon's items and the parameters, in order."""

    items: tuple[MissionItem, ...]
    params: tuple[tuple[str, float], ...]

    def to_json(self) -> dict[str, object]:
        """For the adapter log: the vertices (lat, lon) and the parameters."""
        return {
            "vertices": [[i.x / 1e7, i.y / 1e7] for i in self.items],
            "params": dict(self.params),
        }


def fence_plan(
    autopilot: str,
    polygon_m: Sequence[tuple[float, float]],
    ceiling_m: float | None,
    home_m: tuple[float, float],
    geo: GeoFrame,
) -> FencePlan:
    """The fence of the fleet's ``polygon_m`` (fleet frame, north/east m) and ``ceiling_m``
    for a vehicle whose home is ``home_m`` in the fleet frame and ``geo`` in WGS84."""
    items = tuple(
        MissionItem(
            MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION,
            MAV_FRAME_GLOBAL,
            (float(len(polygon_m)), 0.0, 0.0, 0.0),
            round(lat * 1e7),
            round(lon * 1e7),
            0.0,
        )
        for lat, lon, _ in (
            geo.to_lla(north - home_m[0], east - home_m[1], 0.0) for north, east in polygon_m
        )
    )
    params: list[tuple[str, float]] = []
    if autopilot == "ardupilot":
        kinds = (FENCE_TYPE_POLYGON if items else 0) | (
            FENCE_TYPE_ALT_MAX if ceiling_m is not None else 0
        )
        if ceiling_m is not None:
            params.append(("FENCE_ALT_MAX", round(ceiling_m, 2)))
        params += [
            ("FENCE_TYPE", float(kinds)),
            ("FENCE_ACTION", float(FENCE_ACTION_BRAKE_OR_LAND)),
            ("FENCE_ENABLE", 1.0),  # last: every part is there when it turns on
        ]
    elif autopilot == "px4":
        if ceiling_m is not None:
            params.append(("GF_MAX_VER_DIST", round(ceiling_m, 2)))
        params.append(("GF_ACTION", float(GF_ACTION_HOLD)))
    else:
        raise ValueError(f"unknown autopilot {autopilot!r}")
    return FencePlan(items, tuple(params))


def inside(point: tuple[float, float], polygon: Sequence[tuple[float, float]]) -> bool:
    """Whether ``point`` is inside (or on) ``polygon`` (even-odd rule; pure)."""
    x, y = point
    hit = False
    n = len(polygon)
    for i in range(n):
        (x1, y1), (x2, y2) = polygon[i], polygon[(i + 1) % n]
        if (y1 > y) != (y2 > y):
            cross = x1 + (y - y1) * (x2 - x1) / (y2 - y1)
            if x == cross:
                return True
            if x < cross:
                hit = not hit
    return hit


class GeofenceError(Exception):
    """The fence cannot go on the vehicle, or a move would leave it: the action fails."""


class FenceOwner(Protocol):
    """What :class:`GeofenceKeeper` needs of the vehicle (a :class:`.vehicle.MavlinkVehicle`)."""

    settings: MavlinkSettings
    link: MavlinkLink
    cond: threading.Condition
    geo: GeoFrame | None
    autopilot: Any  # an autopilots.Autopilot: its ``name``
    log: EventLog
    keeper: ParamKeeper


class GeofenceKeeper:
    """Puts the fleet's fence on one vehicle before its first arming, and back at close."""

    def __init__(self, vehicle: FenceOwner) -> None:
        self.v = vehicle
        s = vehicle.settings
        self.wanted = s.fence and (bool(s.geofence_m) or s.max_altitude_m is not None)
        self.protocol = MissionProtocol(
            vehicle.link, s.command_timeout_s * 2, max(3, s.command_retries)
        )
        self.plan: FencePlan | None = None  # on the vehicle, once uploaded
        self.uploaded = False  # the fleet's fence went on the vehicle (this run)
        self._before: list[MissionItem] | None = None  # the vehicle's own fence

    def before_arming(self, abandon: Callable[[], bool]) -> None:
        """Upload the fence and set its parameters, once; :class:`GeofenceError` when the
        vehicle refuses (an Arm then fails: never fly without the fence the fleet asked for)."""
        if not self.wanted or self.plan is not None:
            return
        v, s = self.v, self.v.settings
        with v.cond:
            geo, autopilot = v.geo, v.autopilot.name
        if geo is None:
            raise GeofenceError(
                "cannot place the geofence: no GLOBAL_POSITION_INT from the vehicle"
            )
        plan = fence_plan(autopilot, s.geofence_m, s.max_altitude_m, s.home_m or (0.0, 0.0), geo)
        try:
            if plan.items:
                self._before = self.protocol.download(MAV_MISSION_TYPE_FENCE, abandon)
                self.protocol.upload(plan.items, MAV_MISSION_TYPE_FENCE, abandon)
        except MissionError as exc:
            v.log.error("adapter.fence.failed", error=str(exc))
            raise GeofenceError(
                f"geofence upload failed: {exc} (the fleet's [safety] fence goes on every "
                "MAVLink vehicle; hal.fence = false flies this one without it)"
            ) from exc
        self.plan = plan
        for name, value in plan.params:
            if not v.keeper.set_param(name, value):
                v.log.error("adapter.fence.failed", error=f"parameter {name} not set")
                raise GeofenceError(f"geofence: the vehicle did not take {name} = {value:g}")
        self.uploaded = True
        v.log.info("adapter.fence", autopilot=autopilot, **plan.to_json())

    def check_target(self, target: tuple[float, float, float]) -> None:
        """:class:`GeofenceError` when a move's ``target`` (mission frame) is outside the fleet's
        fence or above its ceiling: the autopilot would refuse it (ArduCopter ignores a
        GUIDED target outside its fence) or stop the vehicle at the fence."""
        s = self.v.settings
        if not self.wanted:
            return
        home = s.home_m or (0.0, 0.0)
        north, east = target[0] + home[0], target[1] + home[1]
        where = f"({target[0]:.2f}, {target[1]:.2f}, {target[2]:.2f})"
        if s.max_altitude_m is not None and target[2] > s.max_altitude_m:
            raise GeofenceError(
                f"target {where} is above the fleet's ceiling {s.max_altitude_m:g} m"
            )
        if s.geofence_m and not inside((north, east), s.geofence_m):
            raise GeofenceError(
                f"target {where} is outside the fleet's geofence (at {north:.2f}, {east:.2f} "
                "in the fleet frame): the autopilot would refuse or stop it"
            )

    def restore(self) -> None:
        """Put the vehicle's own fence back (or clear ours); its parameters are restored
        with the others (keeper.restore).  Logged; never raises."""
        plan, self.plan = self.plan, None
        if plan is None or not plan.items:
            return
        before = self._before or []
        try:
            self.protocol.upload(before, MAV_MISSION_TYPE_FENCE)
        except MissionError as exc:
            self.v.log.error("adapter.fence.restore_failed", error=str(exc))
            return
        self.v.log.info("adapter.fence.restore", vertices=len(before))


__all__ = ["FenceOwner", "FencePlan", "GeofenceError", "GeofenceKeeper", "fence_plan", "inside"]
