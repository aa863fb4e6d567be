"""Where home is: the mission frame's origin in the vehicle's local NED frame (and WGS84).

Home is the first LOCAL_POSITION_NED heard; before every arming its height is
taken again (PX4's local z on the ground drifts between flights).  A home taken
from an estimate the estimator did not (yet) call settled is provisional: before
the first take-off it is taken again from the settled estimate, since PX4 main
reports positions metres off in its first seconds (the notes).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Protocol

from eamos.hal.kinematics import EARTH_RADIUS_M, GeoFrame
from eamos.hal.mavlink.estimator import verdict
from eamos.hal.mavlink.frames import NedOrigin, ned_to_mission
from eamos.hal.mavlink.state import LinkState

if TYPE_CHECKING:
    from eamos.hal.mavlink.autopilots import Autopilot
    from eamos.logs import EventLog


class HomeOwner(Protocol):
    """What keeps home (:class:`~eamos.hal.mavlink.vehicle.MavlinkVehicle`)."""

    state: LinkState
    origin: NedOrigin | None
    origin_provisional: bool
    flown: bool
    geo: GeoFrame | None
    log: EventLog
    autopilot: Autopilot


def capture_home(self: HomeOwner, ground: bool = False) -> None:
    """Record home at the first (settled) fix and, with ``ground``, the ground height
    before arming (condition held)."""
    st = self.state
    if st.local is None:
        return
    settled = verdict(st.estimator_flags, self.autopilot.name, landed=not st.armed)
    again = (
        ground
        and not st.armed
        and not self.flown
        and self.origin_provisional
        and settled is not False
    )
    if self.origin is None or again:
        # The first fix, or the first settled one: an early estimate may be metres off.
        self.origin = NedOrigin(st.local[0], st.local[1], st.local[2])
        self.origin_provisional = settled is not True
        if again:
            self.geo = None  # taken again below, from the settled estimate
        self.log.info(
            "adapter.home",
            north_m=round(st.local[0], 3),
            east_m=round(st.local[1], 3),
            down_m=round(st.local[2], 3),
            estimator="settled" if settled else "unsettled" if settled is False else "unknown",
        )
    elif ground and not st.armed:
        self.origin = self.origin.with_ground(st.local[2])
    if self.geo is None and st.global_pos is not None:
        # The WGS84 point of home: the vehicle's fix shifted back by where
        # it stands in the mission frame.
        g = st.global_pos
        x, y, z = ned_to_mission(st.local[:3], self.origin)
        lat0 = g.lat_deg - math.degrees(x / EARTH_RADIUS_M)
        lon0 = g.lon_deg - math.degrees(y / (EARTH_RADIUS_M * math.cos(math.radians(g.lat_deg))))
        self.geo = GeoFrame(lat0, lon0, g.alt_amsl_m - z)


__all__ = ["HomeOwner", "capture_home"]
