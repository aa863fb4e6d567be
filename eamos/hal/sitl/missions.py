"""The simulated vehicle's mission protocol: missions and geofences uploaded, downloaded, cleared.

What MAVSDK's Mission, MissionRaw and Geofence plugins, QGroundControl and
MAVProxy's ``wp`` and ``fence`` commands speak (the MAVLink mission protocol):

* upload: MISSION_COUNT, then the vehicle asks for each item in turn
  (MISSION_REQUEST_INT, or the older MISSION_REQUEST) and the client answers
  with MISSION_ITEM_INT (or MISSION_ITEM); MISSION_ACK ends it.  A count of 0
  clears that list.  A request not answered within :data:`RETRY_WALL_S` is sent
  again, :data:`RETRIES` times, then the upload is abandoned (MAV_MISSION_OPERATION_CANCELLED);
* download: MISSION_REQUEST_LIST -> MISSION_COUNT, then MISSION_REQUEST_INT /
  MISSION_REQUEST -> MISSION_ITEM_INT / MISSION_ITEM; the client's MISSION_ACK ends it;
* MISSION_CLEAR_ALL (255: every list), MISSION_SET_CURRENT -> MISSION_CURRENT;
* three lists, by MAV_MISSION_TYPE: the mission (0), the geofence (1), rally points (2).

Where the two autopilots differ (observed on the SITL builds in ../shared/sitl,
docs/flying-real-drones.md), a :class:`Dialect` says how:

* ArduCopter asks with MISSION_REQUEST, answers a download with its home as
  item 0 of the mission, reports global frames without ``_INT`` (frame 6 comes
  back as 3, 5 as 0), and refuses an item whose latitude or longitude is out of
  range (MAV_MISSION_INVALID_PARAM5_X / _PARAM6_Y), keeping the list it had;
* both ask again with MISSION_REQUEST_INT when a client answers MISSION_REQUEST with
  MAV_MISSION_UNSUPPORTED (MAVSDK does: it speaks only the ``_INT`` messages);
* PX4 asks with MISSION_REQUEST until the client has sent a MISSION_ITEM_INT,
  keeps frames as sent, marks item 0 current, and stores out-of-range
  coordinates as they come (PX4 main accepted a latitude of -214.7 degrees).

:class:`MissionServer` is pure: it reads no clock (the caller passes wall time to
:meth:`MissionServer.tick`) and sends through the ``send`` function it is given;
replies carry the client's system and component, so the vehicle's links route
them to that client only.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace
from typing import Any

#: MAV_MISSION_TYPE.
MISSION, FENCE, RALLY, ALL_TYPES = 0, 1, 2, 255
MISSION_TYPES = (MISSION, FENCE, RALLY)
#: MAV_MISSION_RESULT.
MISSION_ACCEPTED, MISSION_ERROR, MISSION_UNSUPPORTED_FRAME, MISSION_UNSUPPORTED = 0, 1, 2, 3
MISSION_NO_SPACE, MISSION_INVALID_PARAM5_X, MISSION_INVALID_PARAM6_Y = 4, 10, 11
MISSION_INVALID_SEQUENCE, MISSION_OPERATION_CANCELLED = 13, 15
#: MAV_FRAME: the global ones, and ArduPilot's report of the ``_INT`` ones.
GLOBAL_FRAMES = frozenset({0, 3, 5, 6, 10, 11})
_NOT_INT = {5: 0, 6: 3, 11: 10}
#: MAV_CMD of geofence items: polygon vertices (inclusion, exclusion), circles, return point.
FENCE_RETURN_POINT = 5000
FENCE_POLYGON_INCLUSION, FENCE_POLYGON_EXCLUSION = 5001, 5002
FENCE_CIRCLE_INCLUSION, FENCE_CIRCLE_EXCLUSION = 5003, 5004
#: MAV_CMD of items that carry a place (NAV commands and fence items) for the range check.
_PLACED = range(16, 100)
#: Items each list holds at most (beyond: MAV_MISSION_NO_SPACE).
CAPACITY: Mapping[int, int] = {MISSION: 700, FENCE: 100, RALLY: 20}
#: A request the client does not answer is repeated after this many wall seconds...
RETRY_WALL_S = 1.0
#: ...this many times, then the upload is given up.
RETRIES = 5

#: ``send(message, *fields)``: one MAVLink message by its pymavlink name.
Send = Callable[..., None]


@dataclass(frozen=True)
class MissionItem:
    """One stored item, as MISSION_ITEM_INT carries it (x, y: degrees * 1e7 in global
    frames, metres * 1e4 in local ones)."""

    seq: int
    frame: int
    command: int
    current: int
    autocontinue: int
    param1: float
    param2: float
    param3: float
    param4: float
    x: int
    y: int
    z: float
    mission_type: int = MISSION

    @property
    def lat_deg(self) -> float:
        """Latitude (global frames)."""
        return self.x / 1e7

    @property
    def lon_deg(self) -> float:
        """Longitude (global frames)."""
        return self.y / 1e7


@dataclass(frozen=True)
class Dialect:
    """How one autopilot speaks the mission protocol (see module docstring)."""

    #: Ask with MISSION_REQUEST_INT only once the client was seen to send MISSION_ITEM_INT
    #: (PX4); False: always MISSION_REQUEST (ArduCopter 4.7 did).
    request_int_once_seen: bool
    #: Item 0 of a downloaded mission is the vehicle's home (ArduPilot).
    home_is_item_zero: bool
    #: Refuse items placed outside [-90, 90] x [-180, 180] degrees (ArduPilot).
    check_coordinates: bool
    #: Report global ``_INT`` frames without ``_INT`` (ArduPilot: 6 -> 3, 5 -> 0).
    plain_frames: bool
    #: Mark item 0 current in a download (PX4).
    first_is_current: bool


ARDUPILOT_DIALECT = Dialect(
    request_int_once_seen=False,
    home_is_item_zero=True,
    check_coordinates=True,
    plain_frames=True,
    first_is_current=False,
)
PX4_DIALECT = Dialect(
    request_int_once_seen=True,
    home_is_item_zero=False,
    check_coordinates=False,
    plain_frames=False,
    first_is_current=True,
)


@dataclass
class _Upload:
    """An upload in progress."""

    client: tuple[int, int]
    mission_type: int
    count: int
    items: list[MissionItem]
    last_wall: float
    retries: int = 0


def coordinates_problem(item: MissionItem) -> int | None:
    """MAV_MISSION_INVALID_PARAM5_X / _PARAM6_Y for a placed global item out of range (pure)."""
    if item.frame not in GLOBAL_FRAMES:
        return None
    placed = item.command in _PLACED or FENCE_RETURN_POINT <= item.command <= FENCE_CIRCLE_EXCLUSION
    if not placed:
        return None
    if not -90e7 <= item.x <= 90e7:
        return MISSION_INVALID_PARAM5_X
    if not -180e7 <= item.y <= 180e7:
        return MISSION_INVALID_PARAM6_Y
    return None


class MissionServer:
    """The vehicle's three lists and the protocol that fills and reads them (see module doc).

    ``home``: the vehicle's home (lat, lon, alt AMSL), for ArduPilot's item 0.
    ``on_change(mission_type)``: called after a list changed (upload done, cleared).
    """

    def __init__(
        self,
        dialect: Dialect,
        send: Send,
        home: Callable[[], tuple[float, float, float]],
        on_change: Callable[[int], None] | None = None,
    ) -> None:
        self.dialect = dialect
        self._send = send
        self._home = home
        self._on_change = on_change
        self.lists: dict[int, list[MissionItem]] = {t: [] for t in MISSION_TYPES}
        self.current = 0  # the mission's current item
        self._upload: _Upload | None = None
        self._int_clients: set[tuple[int, int]] = set()  # clients seen sending ITEM_INT

    # -- reading -------------------------------------------------------------------------

    def items(self, mission_type: int) -> list[MissionItem]:
        """A copy of one list."""
        return list(self.lists.get(mission_type, []))

    @property
    def uploading(self) -> bool:
        """True while an upload is in progress."""
        return self._upload is not None

    # -- messages --------------------------------------------------------------------------

    def on_count(self, client: tuple[int, int], count: int, mission_type: int, wall: float) -> None:
        """MISSION_COUNT: start an upload (0: clear the list)."""
        if mission_type not in MISSION_TYPES:
            self._ack(client, MISSION_ERROR, mission_type)
            return
        if count <= 0:
            self._replace(mission_type, [])
            self._ack(client, MISSION_ACCEPTED, mission_type)
            return
        if count > CAPACITY[mission_type]:
            self._ack(client, MISSION_NO_SPACE, mission_type)
            return
        # A new MISSION_COUNT restarts any upload in progress (as both autopilots do).
        self._upload = _Upload(client, mission_type, count, [], wall)
        self._request(0)

    def on_item(self, client: tuple[int, int], fields: Mapping[str, Any], wall: float) -> None:
        """MISSION_ITEM_INT (``fields["int"]`` true) or MISSION_ITEM: the next item of an upload."""
        up = self._upload
        item = _item_from(fields)
        if fields.get("int") and self.dialect.request_int_once_seen:
            self._int_clients.add(client)
        if up is None or up.client != client or item.mission_type != up.mission_type:
            return  # not part of an upload from this client: ignored, as PX4 and ArduPilot do
        expected = len(up.items)
        if item.seq != expected:
            if item.seq < expected:
                self._request(expected)  # a repeat: ask again for the one we need
            return
        if self.dialect.check_coordinates:
            problem = coordinates_problem(item)
            if problem is not None:
                self._upload = None  # the old list stays
                self._ack(client, problem, up.mission_type)
                return
        up.items.append(item)
        up.last_wall, up.retries = wall, 0
        if len(up.items) < up.count:
            self._request(len(up.items))
            return
        self._upload = None
        self._replace(up.mission_type, up.items)
        self._ack(client, MISSION_ACCEPTED, up.mission_type)

    def on_ack(self, client: tuple[int, int], result: int, mission_type: int) -> None:
        """MISSION_ACK from a client.  During its upload, MAV_MISSION_UNSUPPORTED answers a
        MISSION_REQUEST (MAVSDK speaks only the ``_INT`` messages): ask again with
        MISSION_REQUEST_INT, as both autopilots do (MAVSDK uploads to both SITLs).  Any
        other result from the uploading client abandons the upload."""
        up = self._upload
        if up is None or up.client != client or mission_type != up.mission_type:
            return  # the end of a download, or not ours
        if result == MISSION_UNSUPPORTED and client not in self._int_clients:
            self._int_clients.add(client)
            self._request(len(up.items))
            return
        self._upload = None

    def on_request_list(self, client: tuple[int, int], mission_type: int) -> None:
        """MISSION_REQUEST_LIST: how many items the list has."""
        if mission_type not in MISSION_TYPES:
            self._ack(client, MISSION_ERROR, mission_type)
            return
        count = len(self.lists[mission_type])
        self._send("mission_count", client[0], client[1], count, mission_type)

    def on_request(
        self, client: tuple[int, int], seq: int, mission_type: int, as_int: bool
    ) -> None:
        """MISSION_REQUEST_INT / MISSION_REQUEST during a download (or an upload's echo)."""
        items = self.lists.get(mission_type)
        if items is None or not 0 <= seq < len(items):
            self._ack(client, MISSION_INVALID_SEQUENCE, mission_type)
            return
        item = self._reported(items[seq])
        if as_int:
            self._send(
                "mission_item_int",
                client[0],
                client[1],
                *_fields(item),
                item.x,
                item.y,
                item.z,
                item.mission_type,
            )
            return
        scale = 1e7 if item.frame in GLOBAL_FRAMES else 1e4
        self._send(
            "mission_item",
            client[0],
            client[1],
            *_fields(item),
            item.x / scale,
            item.y / scale,
            item.z,
            item.mission_type,
        )

    def on_clear_all(self, client: tuple[int, int], mission_type: int) -> None:
        """MISSION_CLEAR_ALL: empty one list (255: all of them)."""
        types = MISSION_TYPES if mission_type == ALL_TYPES else (mission_type,)
        if not all(t in MISSION_TYPES for t in types):
            self._ack(client, MISSION_ERROR, mission_type)
            return
        for t in types:
            self._replace(t, [])
        self._ack(client, MISSION_ACCEPTED, mission_type)

    def on_set_current(self, seq: int) -> bool:
        """MISSION_SET_CURRENT (or MAV_CMD_DO_SET_MISSION_CURRENT): True if ``seq`` exists."""
        if not 0 <= seq < len(self.lists[MISSION]):
            return False
        self.current = seq
        self.send_current()
        return True

    def send_current(self) -> None:
        """MISSION_CURRENT: the current item and how many the mission has."""
        self._send("mission_current", self.current, len(self.lists[MISSION]))

    def tick(self, wall: float) -> None:
        """Repeat an unanswered request, or give the upload up after :data:`RETRIES`."""
        up = self._upload
        if up is None or wall - up.last_wall < RETRY_WALL_S:
            return
        if up.retries >= RETRIES:
            self._upload = None
            self._ack(up.client, MISSION_OPERATION_CANCELLED, up.mission_type)
            return
        up.retries += 1
        up.last_wall = wall
        self._request(len(up.items))

    # -- helpers ---------------------------------------------------------------------------

    def _request(self, seq: int) -> None:
        up = self._upload
        assert up is not None
        as_int = up.client in self._int_clients
        kind = "mission_request_int" if as_int else "mission_request"
        self._send(kind, up.client[0], up.client[1], seq, up.mission_type)

    def _ack(self, client: tuple[int, int], result: int, mission_type: int) -> None:
        self._send("mission_ack", client[0], client[1], result, mission_type)

    def _replace(self, mission_type: int, items: list[MissionItem]) -> None:
        self.lists[mission_type] = list(items)
        if mission_type == MISSION:
            self.current = 0
        if self._on_change is not None:
            self._on_change(mission_type)

    def _reported(self, item: MissionItem) -> MissionItem:
        """The item as this autopilot reports it in a download."""
        d = self.dialect
        if d.home_is_item_zero and item.mission_type == MISSION and item.seq == 0:
            lat, lon, alt = self._home()
            item = replace(item, frame=0, command=16, x=round(lat * 1e7), y=round(lon * 1e7), z=alt)
            item = replace(item, param1=0.0, param2=0.0, param3=0.0, param4=0.0)
        if d.plain_frames:
            item = replace(item, frame=_NOT_INT.get(item.frame, item.frame))
        if d.first_is_current:
            item = replace(item, current=int(item.seq == 0))
        else:
            item = replace(item, current=0)
        if item.mission_type == FENCE:
            item = replace(item, autocontinue=0)
        return item


def _fields(item: MissionItem) -> tuple[Any, ...]:
    return (
        item.seq,
        item.frame,
        item.command,
        item.current,
        item.autocontinue,
        item.param1,
        item.param2,
        item.param3,
        item.param4,
    )


def _item_from(fields: Mapping[str, Any]) -> MissionItem:
    """A stored item from a received MISSION_ITEM_INT / MISSION_ITEM's fields."""
    frame = int(fields["frame"])
    x, y = fields["x"], fields["y"]
    if not fields.get("int"):
        # MISSION_ITEM carries degrees (global) or metres (local) as floats.
        scale = 1e7 if frame in GLOBAL_FRAMES else 1e4
        x, y = _scaled(x, scale), _scaled(y, scale)
    return MissionItem(
        seq=int(fields["seq"]),
        frame=frame,
        command=int(fields["command"]),
        current=int(fields["current"]),
        autocontinue=int(fields["autocontinue"]),
        param1=float(fields["param1"]),
        param2=float(fields["param2"]),
        param3=float(fields["param3"]),
        param4=float(fields["param4"]),
        x=int(x),
        y=int(y),
        z=float(fields["z"]),
        mission_type=int(fields.get("mission_type", MISSION)),
    )


def _scaled(value: float, scale: float) -> int:
    if not math.isfinite(value):
        return 0
    # Clamped to int32, as the wire would carry it.
    return max(-(2**31), min(2**31 - 1, round(value * scale)))


__all__ = [
    "ALL_TYPES",
    "ARDUPILOT_DIALECT",
    "FENCE",
    "FENCE_CIRCLE_EXCLUSION",
    "FENCE_CIRCLE_INCLUSION",
    "FENCE_POLYGON_EXCLUSION",
    "FENCE_POLYGON_INCLUSION",
    "FENCE_RETURN_POINT",
    "MISSION",
    "PX4_DIALECT",
    "RALLY",
    "Dialect",
    "MissionItem",
    "MissionServer",
    "coordinates_problem",
]
