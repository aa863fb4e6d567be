"""The vehicle's side of a pilot's takeover: the watch fed under the link's condition.

:class:`~eamos.hal.mavlink.takeover.TakeoverWatch` decides whose each mode change
is; :class:`PilotHand` feeds it (the link's ``observe`` hook, with the condition
held, so a mode change is classified before any waiting action wakes to it),
settles mode changes still waiting for a failsafe's STATUSTEXT on the ticker, and
acts on a pilot's: from that moment the vehicle's steering stops
(:attr:`MavlinkVehicle.taken_over` is set; nothing but heartbeats is sent any
more), ``adapter.taken_over`` is logged at error level with where the vehicle
was, and the adapter is told (``on_taken_over``: its running actions fail with
"taken over by the pilot (MODE)").
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, Protocol

from eamos.hal.api import TakenOver
from eamos.hal.mavlink.frames import Vector
from eamos.hal.mavlink.state import Events, LinkState
from eamos.hal.mavlink.takeover import (
    FAILSAFE_GRACE_S,
    FAILSAFE_WINDOW_S,
    ModeChange,
    TakeoverWatch,
)

if TYPE_CHECKING:
    from eamos.hal.mavlink.settings import MavlinkSettings
    from eamos.logs import EventLog


#: The least wall time a mode change nobody asked for waits for a failsafe's STATUSTEXT.
FAILSAFE_GRACE_MIN_S = 1.0


def takeover_watch(settings: MavlinkSettings) -> TakeoverWatch:
    """A vehicle's watch, its windows in vehicle seconds (``speedup``); PX4 until the
    HEARTBEAT names the autopilot (``set_autopilot``)."""
    return TakeoverWatch(
        "px4",
        # At least FAILSAFE_GRACE_MIN_S of wall time: a SITL at a speed-up of 10 on a loaded
        # machine sent the failsafe's STATUSTEXT later than 0.15 s after its HEARTBEAT (a
        # fence breach then read as a pilot's HOLD).  Nothing is commanded meanwhile.
        grace_s=max(settings.scaled(FAILSAFE_GRACE_S), FAILSAFE_GRACE_MIN_S),
        window_s=settings.scaled(FAILSAFE_WINDOW_S),
        link_grace_s=settings.heartbeat_timeout_s,
    )


class PilotOwner(Protocol):
    """What :class:`PilotHand` needs of the vehicle (a :class:`.vehicle.MavlinkVehicle`)."""

    takeover: TakeoverWatch
    taken_over: TakenOver | None
    on_taken_over: Callable[[TakenOver], None] | None
    autopilot: Any  # an autopilots.Autopilot: its ``mode_name``
    state: LinkState
    cond: threading.Condition
    log: EventLog

    def mission_position(self, st: LinkState | None = None) -> Vector: ...

    def stop_steering(self) -> None: ...


class PilotHand:
    """Feeds one vehicle's takeover watch and acts on its verdicts (module docstring)."""

    def __init__(self, vehicle: PilotOwner) -> None:
        self.v = vehicle

    def observe(self, events: Events, now: float) -> None:
        """The link's hook (condition held): mode changes, failsafe texts, link gaps and
        disarms reach the watch before any waiter wakes to them."""
        v = self.v
        watch = v.takeover
        for name, fields in list(events):
            change: ModeChange | None = None
            if name == "vehicle.mode":
                change = watch.mode_seen(
                    v.autopilot.mode_name(fields["previous"]),
                    v.autopilot.mode_name(fields["custom_mode"]),
                    v.state.armed,
                    now,
                )
            elif name == "vehicle.statustext":
                change = watch.statustext(str(fields["text"]), now)
            elif name == "link.gap":
                watch.link_gap(now)
            elif name == "vehicle.armed" and not fields["armed"]:
                watch.disarmed()
            if change is not None:
                self._classified(change, events)

    def tick(self) -> None:
        """A mode change whose grace ended without a failsafe: the pilot's (ticker)."""
        v = self.v
        events: Events = []
        with v.cond:
            change = v.takeover.tick(time.monotonic())
            if change is not None:
                self._classified(change, events)
                v.cond.notify_all()
        for name, fields in events:
            if not self.event(name, fields):
                v.log.info(f"adapter.{name}", **fields)

    def _classified(self, change: ModeChange, events: Events) -> None:
        """A mode change classified (condition held): a pilot's ends all steering now."""
        v = self.v
        fields = {"mode": change.mode, "previous": change.previous}
        if change.verdict == "pilot" and v.taken_over is None:
            taken = TakenOver(change.mode)
            if v.state.local is not None:
                x, y, z = v.mission_position()
                taken = TakenOver(change.mode, round(x, 2), round(y, 2), round(z, 2))
            v.taken_over = taken
            v.stop_steering()
            events.append(("vehicle.taken_over", fields))
        elif change.verdict == "failsafe":
            events.append(("vehicle.failsafe", {**fields, "statustext": change.why}))
        elif change.verdict == "pending":
            events.append(("vehicle.mode_unexplained", fields))

    def event(self, name: str, fields: dict[str, Any]) -> bool:
        """Log a takeover or a failsafe (outside the condition) and tell the adapter of a
        takeover; False for any other event."""
        v = self.v
        if name == "vehicle.taken_over":
            taken = v.taken_over
            assert taken is not None
            v.log.error(
                "adapter.taken_over",
                mode=taken.mode,
                previous=fields["previous"],
                x_m=taken.x_m,
                y_m=taken.y_m,
                z_m=taken.z_m,
                note="a pilot has the vehicle: EAMOS never commands it again in this run",
            )
            if v.on_taken_over is not None:
                v.on_taken_over(taken)
            return True
        if name == "vehicle.failsafe":
            v.log.warning("adapter.failsafe", **fields)
            return True
        return False


__all__ = ["PilotHand", "PilotOwner", "takeover_watch"]
