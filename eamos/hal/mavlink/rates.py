"""The telemetry rates a shared link delivers, asked for again when someone lowers them.

The adapter asks the vehicle for the messages it flies by (LOCAL_POSITION_NED,
GLOBAL_POSITION_INT, ATTITUDE, EXTENDED_SYS_STATE) at ``telemetry_hz`` with
MAV_CMD_SET_MESSAGE_INTERVAL.  A second ground station on the same MAVLink
channel can lower them: MAVProxy's ``set streamrate 1`` (REQUEST_DATA_STREAM, which
on ArduPilot resets every message of a stream to the new rate on that channel), or
any client's own SET_MESSAGE_INTERVAL.  Moves then complete late and brakes start
late, silently.  :class:`RateWatch` compares what arrives with what was asked for,
window by window of the vehicle's own clock (the messages' ``time_boot_ms``: a
SITL asked to run K times faster runs slower than that on a loaded machine, so
wall time times K would see rates drop that did not), and says what to do: ask
again for a message that comes too slowly, and, when it stays too slow after
being asked again, report it once.

:class:`RateWatch` is pure: counts and times are passed in.  :class:`RateKeeper`
runs it on the link's ticker: it sends the requests (without waiting for their
acknowledgement: the ticker also streams PX4's setpoints), logs
``adapter.rate.request`` and ``adapter.rate.low``, and tells the operator once.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Literal

from eamos.hal.mavlink.estimator import (
    MSG_EKF_STATUS_REPORT,
    MSG_ESTIMATOR_STATUS,
    estimator_message,
)
from eamos.hal.mavlink.state import result_name

if TYPE_CHECKING:
    from eamos.hal.mavlink.command_protocol import CommandProtocol
    from eamos.hal.mavlink.link import MavlinkLink
    from eamos.hal.mavlink.settings import MavlinkSettings
    from eamos.logs import EventLog

MAV_CMD_SET_MESSAGE_INTERVAL = 511
#: Messages requested with MAV_CMD_SET_MESSAGE_INTERVAL, and their rate in Hz
#: (None: ``telemetry_hz``).
MSG_LOCAL_POSITION_NED = 32
MSG_GLOBAL_POSITION_INT = 33
MSG_SYS_STATUS = 1
MSG_EXTENDED_SYS_STATE = 245
MSG_BATTERY_STATUS = 147
MSG_HOME_POSITION = 242
MSG_ATTITUDE = 30
#: The messages the adapter flies by, at ``telemetry_hz``: re-requested when a second
#: ground station lowers their rate (:class:`RateKeeper`).
RATE_WATCHED = {
    "LOCAL_POSITION_NED": MSG_LOCAL_POSITION_NED,
    "GLOBAL_POSITION_INT": MSG_GLOBAL_POSITION_INT,
    "ATTITUDE": MSG_ATTITUDE,
}
TELEMETRY_INTERVALS: dict[int, float | None] = {
    MSG_LOCAL_POSITION_NED: None,
    MSG_GLOBAL_POSITION_INT: None,
    MSG_EXTENDED_SYS_STATE: None,
    MSG_ATTITUDE: None,  # the heading (Yaw, Orbit)
    MSG_SYS_STATUS: 2.0,
    MSG_BATTERY_STATUS: 1.0,
    MSG_HOME_POSITION: 0.5,
    MSG_ESTIMATOR_STATUS: 2.0,  # PX4 only
    MSG_EKF_STATUS_REPORT: 2.0,  # ArduPilot only
}


def watched(telemetry_hz: float) -> dict[str, tuple[int, float]]:
    """:data:`RATE_WATCHED` with the rate each is asked for (``telemetry_hz``)."""
    return {name: (msg_id, telemetry_hz) for name, msg_id in RATE_WATCHED.items()}


def request_intervals(
    commands: CommandProtocol,
    autopilot: str,
    settings: MavlinkSettings,
    log: EventLog,
    deadline: float,
) -> None:
    """Ask for the telemetry the adapter reads (best effort; each answer is logged)."""
    s = settings
    for msg_id, hz in TELEMETRY_INTERVALS.items():
        if time.monotonic() >= deadline:
            break
        if msg_id in (MSG_ESTIMATOR_STATUS, MSG_EKF_STATUS_REPORT) and msg_id != (
            estimator_message(autopilot)
        ):
            continue  # the other autopilot's estimator report
        rate = s.telemetry_hz if hz is None else min(hz, s.telemetry_hz)
        result = commands.request(
            MAV_CMD_SET_MESSAGE_INTERVAL,
            (float(msg_id), 1e6 / rate, 0, 0, 0, 0, 0),
            timeout_s=s.command_timeout_s,
            retries=1,
        )
        log.info("adapter.interval", message=msg_id, hz=rate, result=result_name(result))


#: The window over which rates are measured (vehicle seconds).
RATE_WINDOW_S = 2.0
#: A message arriving slower than this fraction of the rate asked for is too slow.
LOW_FRACTION = 0.6
#: Windows still too slow after asking again before the rate is reported.
REPORT_AFTER = 2


@dataclass(frozen=True)
class RateFinding:
    """What a window showed for one message: ask again, or report that it stays slow."""

    action: Literal["request", "report"]
    message: str
    msg_id: int
    seen_hz: float  # vehicle time
    wanted_hz: float


class RateWatch:
    """Measures each wanted message's rate per window (see the module docstring).

    ``wanted`` maps a message name to (its id, the rate asked for in Hz of vehicle
    time).  :meth:`window` takes the messages counted so far (by name) and the
    vehicle's clock (seconds since its boot), and returns the findings of a window
    that just ended (none before it ends).
    """

    def __init__(
        self, wanted: Mapping[str, tuple[int, float]], window_s: float = RATE_WINDOW_S
    ) -> None:
        self.wanted = dict(wanted)
        self.window_s = window_s
        self._start: float | None = None
        self._counts: dict[str, int] = {}
        self._slow_since_request: dict[str, int] = {}  # windows too slow since asked again
        self.reported: set[str] = set()

    def restart(self) -> None:
        """Start a new window at the next :meth:`window` (after the link was silent)."""
        self._start = None

    def window(self, counts: Mapping[str, int], vehicle_s: float) -> list[RateFinding]:
        """Findings when a window ends at ``vehicle_s`` (the vehicle's clock); else []."""
        if self._start is None or vehicle_s < self._start:  # first, or the vehicle rebooted
            self._start, self._counts = vehicle_s, dict(counts)
            return []
        elapsed = vehicle_s - self._start
        if elapsed < self.window_s:
            return []
        out: list[RateFinding] = []
        for name, (msg_id, wanted_hz) in self.wanted.items():
            if not self._counts.get(name, 0):
                continue  # not flowing yet (ArduPilot: no LOCAL_POSITION_NED before its EKF)
            seen_hz = (counts.get(name, 0) - self._counts.get(name, 0)) / elapsed
            if seen_hz >= LOW_FRACTION * wanted_hz:
                self._slow_since_request.pop(name, None)
                continue
            slow = self._slow_since_request.get(name)
            if slow is not None and slow + 1 >= REPORT_AFTER and name not in self.reported:
                self.reported.add(name)
                out.append(RateFinding("report", name, msg_id, round(seen_hz, 2), wanted_hz))
            self._slow_since_request[name] = 0 if slow is None else slow + 1
            out.append(RateFinding("request", name, msg_id, round(seen_hz, 2), wanted_hz))
        self._start, self._counts = vehicle_s, dict(counts)
        return out


class RateKeeper:
    """Runs a :class:`RateWatch` on a link's ticker (see the module docstring).

    ``tell("warning", text)`` reaches the operator (once per message that stays slow);
    ``blocked()`` is true once the adapter may no longer command the vehicle (a
    pilot took it): no request is sent then.
    """

    def __init__(
        self,
        link: MavlinkLink,
        log: EventLog,
        tell: Callable[[Literal["taken_over", "warning"], str], None],
        blocked: Callable[[], bool],
    ) -> None:
        self.link = link
        self.log = log
        self.tell = tell
        self.blocked = blocked
        self.watch: RateWatch | None = None

    def start(self, wanted: Mapping[str, tuple[int, float]]) -> None:
        """Watch ``wanted`` (name -> (message id, Hz asked for)) from now on."""
        self.watch = RateWatch(wanted)

    def tick(self) -> None:
        """One look at the rates (the link's ticker thread)."""
        watch = self.watch
        if watch is None or self.blocked():
            return
        link = self.link
        with link.cond:
            counts, ok, boot_ms = dict(link.state.counts), link.state.link_ok, link.state.boot_ms
        if not ok or boot_ms is None:
            watch.restart()  # a silent link is not a slow one
            return
        for finding in watch.window(counts, boot_ms / 1000.0):
            if finding.action == "request":
                self._request(finding)
            else:
                self._report(finding)

    def _request(self, finding: RateFinding) -> None:
        system, component = self.link.target
        interval_us = 1e6 / finding.wanted_hz
        # Fire and forget: the ticker must not wait (its ack is logged like any other).
        self.link.send(
            "command_long",
            system,
            component,
            MAV_CMD_SET_MESSAGE_INTERVAL,
            0,
            float(finding.msg_id),
            interval_us,
            0.0,
            0.0,
            0.0,
            0.0,
            0.0,
        )
        self.log.info(
            "adapter.rate.request",
            message=finding.message,
            seen_hz=finding.seen_hz,
            hz=finding.wanted_hz,
        )

    def _report(self, finding: RateFinding) -> None:
        text = (
            f"{finding.message} arrives at {finding.seen_hz:g} Hz, below the "
            f"{finding.wanted_hz:g} Hz the adapter needs, although asked for again "
            "(another ground station on this link lowering the rates?): moves complete "
            "and brakes start later"
        )
        self.log.warning(
            "adapter.rate.low",
            message=finding.message,
            seen_hz=finding.seen_hz,
            hz=finding.wanted_hz,
            note=text,
        )
        self.tell("warning", text)


__all__ = [
    "LOW_FRACTION",
    "RATE_WATCHED",
    "RATE_WINDOW_S",
    "REPORT_AFTER",
    "TELEMETRY_INTERVALS",
    "RateFinding",
    "RateKeeper",
    "RateWatch",
    "request_intervals",
    "watched",
]
