"""Where home is: the mission frame's origin in the vehicle's local NED frame (and WGS84).

Home is the first LOCAL_POSITION_NED heard; before every arming its height is
taken again (PX4's local z on the ground drifts between flights).  A home taken
from an estimate the estimator did not (yet) call settled is provisional: before
the first take-off it is taken again from the settled estimate, since PX4 main
reports positions metres off in its first seconds (the notes).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING, Literal, Protocol

from eamos.hal.kinematics import EARTH_RADIUS_M, GeoFrame
from eamos.hal.mavlink.estimator import verdict
from eamos.hal.mavlink.frames import NedOrigin, ned_to_mission
from eamos.hal.mavlink.state import LinkState

if TYPE_CHECKING:
    from eamos.hal.mavlink.autopilots import Autopilot
    from eamos.hal.mavlink.link import MavlinkLink
    from eamos.hal.mavlink.settings import MavlinkSettings
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


#: A vehicle's HOME_POSITION this far (m) from the fleet's home_lla is reported.
HOME_MISMATCH_M = 5.0


def check_home(home: tuple[float, float, float], home_lla: tuple[float, ...] | None) -> str:
    """Why the vehicle's HOME_POSITION (lat, lon, alt) disagrees with the fleet's
    ``home_lla`` for it ("" when it agrees, or the fleet gives none).  The check, the
    monitor and the report place the drone at the fleet's home; the vehicle flies
    from its own."""
    if home_lla is None:
        return ""
    frame = GeoFrame(home_lla[0], home_lla[1], 0.0)
    north, east, _ = frame.from_lla(home[0], home[1], 0.0)
    off = math.hypot(north, east)
    if off <= HOME_MISMATCH_M:
        return ""
    return (
        f"the vehicle's home (HOME_POSITION {home[0]:.7f}, {home[1]:.7f}) is {off:.1f} m "
        f"from the fleet's home_lla ({home_lla[0]:.7f}, {home_lla[1]:.7f}): the check, the "
        "monitor and the report place it at the fleet's; fix home_lla in the fleet file"
    )


class VehicleHomeCheck:
    """The vehicle's HOME_POSITION, once it is known: logged (``adapter.home.vehicle``) and
    compared with the fleet's ``home_lla`` (``adapter.home.mismatch``, told to the operator)."""

    def __init__(
        self,
        link: MavlinkLink,
        settings: MavlinkSettings,
        log: EventLog,
        tell: Callable[[Literal["taken_over", "warning"], str], None],
    ) -> None:
        self.link = link
        self.settings = settings
        self.log = log
        self.tell = tell
        self.done = False

    def tick(self) -> None:
        """Look once HOME_POSITION has arrived (the link's ticker)."""
        if self.done:
            return
        with self.link.cond:
            home = self.link.state.home
        if home is None:
            return
        self.done = True
        s = self.settings
        self.log.info(
            "adapter.home.vehicle",
            lat_deg=round(home[0], 7),
            lon_deg=round(home[1], 7),
            alt_m=round(home[2], 2),
            home_m=None if s.home_m is None else list(s.home_m),
        )
        note = check_home(home, s.home_lla)
        if note:
            self.log.warning("adapter.home.mismatch", note=note)
            self.tell("warning", note)


def capture_home(self: HomeOwner, ground: bool = False) -> None:
    """Record home at the first (settled) fix and, with ``ground``, the ground height
    before arming (condition held)."""
    st = self.state
    if st.local is None:
        return
    if self.origin is None and st.armed:
        # Found armed (a node restarted mid-flight, or a vehicle armed before EAMOS
        # connected): where it stands is not home, the autopilot's home is (set where it
        # armed).  Until HOME_POSITION arrives there is no mission frame, no sample.
        if st.home_ned is None:
            return
        self.origin = NedOrigin(*st.home_ned)
        self.origin_provisional = False
        self.flown = True  # its ground height is home's, not taken again
        self.log.info(
            "adapter.home",
            north_m=round(st.home_ned[0], 3),
            east_m=round(st.home_ned[1], 3),
            down_m=round(st.home_ned[2], 3),
            estimator="found armed: the vehicle's HOME_POSITION",
        )
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


__all__ = ["HOME_MISMATCH_M", "HomeOwner", "VehicleHomeCheck", "capture_home", "check_home"]
