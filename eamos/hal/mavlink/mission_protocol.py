"""The MAVLink mission protocol: download, upload and clear a vehicle's items of one type.

https://mavlink.io/en/services/mission.html.  The adapter uses it for geofences
(``MAV_MISSION_TYPE_FENCE``), which PX4 and ArduPilot both take this way:

* download: MISSION_REQUEST_LIST -> MISSION_COUNT, then MISSION_REQUEST_INT per item
  -> MISSION_ITEM_INT, then our MISSION_ACK;
* upload: MISSION_COUNT -> the vehicle asks for each item (MISSION_REQUEST_INT, or
  the older MISSION_REQUEST) -> MISSION_ITEM_INT, until its MISSION_ACK;
* clear: MISSION_CLEAR_ALL -> MISSION_ACK.

A request that gets no answer is sent again (``retries``), as the protocol asks.
The answers are read from the link's state
(:attr:`~eamos.hal.mavlink.state.LinkState.mission`), waiting on the link's
condition: nothing polls.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

from eamos.hal.mavlink.link import MavlinkLink

MAV_MISSION_TYPE_FENCE = 1
MAV_MISSION_ACCEPTED = 0
MAV_MISSION_RESULT_NAMES = {
    0: "MAV_MISSION_ACCEPTED",
    1: "MAV_MISSION_ERROR",
    2: "MAV_MISSION_UNSUPPORTED_FRAME",
    3: "MAV_MISSION_UNSUPPORTED",
    4: "MAV_MISSION_NO_SPACE",
    5: "MAV_MISSION_INVALID",
    13: "MAV_MISSION_DENIED",
    15: "MAV_MISSION_OPERATION_CANCELLED",
}


def mission_result_name(result: int | None) -> str:
    """``"MAV_MISSION_ACCEPTED"`` for 0 ...; ``"no MISSION_ACK"`` for None."""
    if result is None:
        return "no MISSION_ACK"
    return MAV_MISSION_RESULT_NAMES.get(result, f"MAV_MISSION_RESULT({result})")


@dataclass(frozen=True)
class MissionItem:
    """One MISSION_ITEM_INT: a command, its params, and x/y (degrees * 1e7) and z."""

    command: int
    frame: int
    params: tuple[float, float, float, float]
    x: int
    y: int
    z: float

    @classmethod
    def of(cls, msg: Any) -> MissionItem:
        """The item a MISSION_ITEM_INT carries."""
        return cls(
            int(msg.command),
            int(msg.frame),
            (float(msg.param1), float(msg.param2), float(msg.param3), float(msg.param4)),
            int(msg.x),
            int(msg.y),
            float(msg.z),
        )


class MissionError(Exception):
    """A mission exchange that did not complete (the vehicle's answer, or none)."""


def _item_of(seq: int, mission_type: int) -> Callable[[Any], bool]:
    """Matches the MISSION_ITEM_INT ``seq`` of ``mission_type``."""

    def match(m: Any) -> bool:
        return bool(
            m.get_type() == "MISSION_ITEM_INT"
            and m.seq == seq
            and getattr(m, "mission_type", 0) == mission_type
        )

    return match


class MissionProtocol:
    """Mission-protocol exchanges with one vehicle over one link (module docstring)."""

    def __init__(self, link: MavlinkLink, timeout_s: float, retries: int) -> None:
        self.link = link
        self.timeout_s = timeout_s
        self.retries = retries

    def _next(self, seen: int, match: Callable[[Any], bool], abandon: Callable[[], bool]) -> Any:
        """The first mission answer newer than ``seen`` that ``match``es, or None on timeout."""
        link = self.link

        def found() -> Any:
            return next((m for n, m in link.state.mission if n > seen and match(m)), None)

        with link.cond:
            link.cond.wait_for(
                lambda: found() is not None or abandon() or link.state.closed,
                timeout=self.timeout_s,
            )
            return found()

    def _serial(self) -> int:
        with self.link.cond:
            return self.link.state.mission_serial

    def download(
        self, mission_type: int, abandon: Callable[[], bool] = lambda: False
    ) -> list[MissionItem]:
        """Every item of ``mission_type`` on the vehicle; :class:`MissionError` if it fails."""
        link = self.link
        system, component = link.target
        count = None
        for _ in range(self.retries):
            seen = self._serial()
            link.send("mission_request_list", system, component, mission_type)
            count = self._next(
                seen,
                lambda m: (
                    m.get_type() == "MISSION_COUNT"
                    and getattr(m, "mission_type", 0) == mission_type
                ),
                abandon,
            )
            if count is not None or abandon():
                break
        if count is None:
            raise MissionError("no MISSION_COUNT for MISSION_REQUEST_LIST")
        items: list[MissionItem] = []
        for seq in range(int(count.count)):
            item = None
            for _ in range(self.retries):
                seen = self._serial()
                link.send("mission_request_int", system, component, seq, mission_type)
                item = self._next(seen, _item_of(seq, mission_type), abandon)
                if item is not None or abandon():
                    break
            if item is None:
                raise MissionError(f"no MISSION_ITEM_INT {seq} of {int(count.count)}")
            items.append(MissionItem.of(item))
        link.send("mission_ack", system, component, MAV_MISSION_ACCEPTED, mission_type)
        return items

    def upload(
        self,
        items: Sequence[MissionItem],
        mission_type: int,
        abandon: Callable[[], bool] = lambda: False,
    ) -> None:
        """Replace the vehicle's items of ``mission_type`` by ``items`` (none: clear them);
        :class:`MissionError` with the vehicle's MISSION_ACK result if it refuses."""
        if not items:
            self.clear(mission_type, abandon)
            return
        link = self.link
        system, component = link.target

        def answer(m: Any) -> bool:
            kind = m.get_type()
            if getattr(m, "mission_type", 0) != mission_type:
                return False
            return kind in ("MISSION_REQUEST_INT", "MISSION_REQUEST", "MISSION_ACK")

        seen = self._serial()
        link.send("mission_count", system, component, len(items), mission_type)
        tries = 0
        last_sent: int | None = None
        while True:
            msg = self._next(seen, answer, abandon)
            if msg is None:
                tries += 1
                if tries >= self.retries or abandon():
                    raise MissionError(
                        "no answer to MISSION_COUNT"
                        if last_sent is None
                        else f"no answer after mission item {last_sent}"
                    )
                seen = self._serial()
                if last_sent is None:
                    link.send("mission_count", system, component, len(items), mission_type)
                else:
                    self._send_item(items, last_sent, mission_type)
                continue
            seen = self._serial()
            tries = 0
            if msg.get_type() == "MISSION_ACK":
                if msg.type != MAV_MISSION_ACCEPTED:
                    raise MissionError(f"upload refused with {mission_result_name(msg.type)}")
                return
            if not 0 <= msg.seq < len(items):
                raise MissionError(f"the vehicle asked for item {msg.seq} of {len(items)}")
            last_sent = int(msg.seq)
            self._send_item(items, last_sent, mission_type)

    def _send_item(self, items: Sequence[MissionItem], seq: int, mission_type: int) -> None:
        item = items[seq]
        system, component = self.link.target
        self.link.send(
            "mission_item_int",
            system,
            component,
            seq,
            item.frame,
            item.command,
            0,  # current
            1,  # autocontinue
            *item.params,
            item.x,
            item.y,
            item.z,
            mission_type,
        )

    def clear(self, mission_type: int, abandon: Callable[[], bool] = lambda: False) -> None:
        """MISSION_CLEAR_ALL of ``mission_type``; :class:`MissionError` if refused or unanswered."""
        link = self.link
        system, component = link.target
        ack = None
        for _ in range(self.retries):
            seen = self._serial()
            link.send("mission_clear_all", system, component, mission_type)
            ack = self._next(
                seen,
                lambda m: (
                    m.get_type() == "MISSION_ACK" and getattr(m, "mission_type", 0) == mission_type
                ),
                abandon,
            )
            if ack is not None or abandon():
                break
        if ack is None:
            raise MissionError("no MISSION_ACK for MISSION_CLEAR_ALL")
        if ack.type != MAV_MISSION_ACCEPTED:
            raise MissionError(f"clear refused with {mission_result_name(ack.type)}")


__all__ = [
    "MAV_MISSION_TYPE_FENCE",
    "MissionError",
    "MissionItem",
    "MissionProtocol",
    "mission_result_name",
]
