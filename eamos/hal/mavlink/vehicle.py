"""One MAVLink autopilot in mission terms: home, frames, modes, and what it is being told.

:class:`MavlinkVehicle` sits between the raw link (:mod:`eamos.hal.mavlink.link`)
and the flight procedures (:mod:`eamos.hal.mavlink.flight`).  It connects
(waits for the HEARTBEAT, detects PX4 or ArduPilot, requests telemetry), knows
where home is in the vehicle's local NED frame, turns the link's state into
mission-frame positions and :class:`~eamos.hal.api.Telemetry` samples, and
keeps the vehicle steered: PX4's setpoint stream and ArduPilot's refreshed
position target run on the link's ticker thread.

Everything here is read and written under :attr:`MavlinkVehicle.cond` (the
link's condition); methods documented "condition held" expect the caller to
hold it.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

from eamos.hal.api import POSITION_LOG_HZ, AdapterError, AdapterNotice, TakenOver, Telemetry
from eamos.hal.kinematics import GeoFrame
from eamos.hal.mavlink.autopilots import Autopilot, autopilot_from_heartbeat, autopilot_named
from eamos.hal.mavlink.command_protocol import CommandProtocol
from eamos.hal.mavlink.frames import NedOrigin, Vector, ned_to_mission
from eamos.hal.mavlink.geofence import GeofenceKeeper
from eamos.hal.mavlink.home import VehicleHomeCheck, capture_home
from eamos.hal.mavlink.keeper import ParamKeeper
from eamos.hal.mavlink.link import (
    MAV_SYS_STATUS_PREARM_CHECK,
    LinkError,
    LinkState,
    MavlinkLink,
)
from eamos.hal.mavlink.pilot import PilotHand, takeover_watch
from eamos.hal.mavlink.rates import RateKeeper, request_intervals, watched
from eamos.hal.mavlink.settling import Settling
from eamos.hal.mavlink.signing import (
    REFUSED_HEARTBEATS,
    SigningKeyError,
    await_signing,
    read_key,
    refused_reason,
)
from eamos.hal.mavlink.targets import (
    TYPE_MASK_POSITION,
    CirclePath,
    GuidedTarget,
    send_global,
    send_path,
    send_position,
)
from eamos.hal.settings import field_error

if TYPE_CHECKING:
    from eamos.hal.mavlink.settings import MavlinkSettings
    from eamos.logs import EventLog

MAV_CMD_SET_MESSAGE_INTERVAL = 511
MAV_LANDED_STATE_ON_GROUND = 1
#: Below this height (m above the take-off ground) a vehicle without
#: EXTENDED_SYS_STATE counts as on the ground.
GROUND_Z_M = 0.1
#: A vehicle that sends positions but no SYS_STATUS for this long (wall seconds) is
#: tried for arming without a pre-arm bit (older firmware, other stacks).
SYS_STATUS_GRACE_S = 3.0
#: ArduPilot position targets are re-sent this often (they need not stream,
#: but a lost UDP datagram must not strand the vehicle).
TARGET_REFRESH_S = 1.0
#: The adapter log gets the vehicle's position this often while it changes.
POSITION_LOG_S = 1.0 / POSITION_LOG_HZ
#: How often a mode change waiting for a failsafe's STATUSTEXT is looked at again.
TAKEOVER_TICK_S = 0.1
#: How often the telemetry rates are looked at (a window ends every RATE_WINDOW_S).
RATE_TICK_S = 0.25


def _signing_key(settings: MavlinkSettings) -> bytes | None:
    """The fleet's signing key from ``hal.signing_key`` (never logged), or None (no key,
    or ``hal.signing = "off"`` for this vehicle)."""
    if settings.signing_key is None or settings.signing == "off":
        return None
    try:
        return read_key(Path(settings.signing_key).expanduser())
    except SigningKeyError as exc:
        raise field_error("hal.signing_key", str(exc)) from None


def heartbeat_lost(st: LinkState, settings: MavlinkSettings) -> str:
    """Why an action ends when HEARTBEATs stop: the last STATUSTEXT, or that the vehicle's
    messages come unsigned (or signed with another key) since the last good HEARTBEAT."""
    text = st.last_statustext
    why = f" (last STATUSTEXT: {text})" if text else ""
    if st.refused_at > st.last_heartbeat:
        why = f" ({refused_reason(st, settings.connection)})"
    return (
        f"heartbeat lost: no HEARTBEAT from the vehicle for more than "
        f"{settings.heartbeat_timeout_s:g} s{why}"
    )


def armable(st: LinkState) -> bool:
    """A position estimate, and the pre-arm bit of SYS_STATUS when the vehicle reports it.

    Without a SYS_STATUS yet, only once positions have come for
    :data:`SYS_STATUS_GRACE_S`: ArduCopter streams positions as soon as asked, before
    "ArduPilot Ready", and a mode set before that is overwritten.
    """
    if st.local is None:
        return False
    present = st.sensors_present
    if present is None:
        since = st.local_since
        return since is not None and st.last_rx - since >= SYS_STATUS_GRACE_S
    if not present & MAV_SYS_STATUS_PREARM_CHECK:
        return True  # an autopilot that does not report the bit: try, and let it refuse
    return bool((st.sensors_health or 0) & MAV_SYS_STATUS_PREARM_CHECK)


class MavlinkVehicle:
    """An autopilot behind a :class:`MavlinkLink`, seen in the mission frame (module docstring)."""

    def __init__(self, drone: str, settings: MavlinkSettings, log: EventLog) -> None:
        self.drone = drone
        self.settings = settings
        self.log = log
        self.link = MavlinkLink(
            settings.connection,
            signing_key=_signing_key(settings),
            signing_setup=settings.signing_setup,
            source_system=settings.source_system,
            source_component=settings.source_component,
            system_id=settings.system_id,
            component_id=settings.component_id,
            heartbeat_timeout_s=settings.heartbeat_timeout_s,
            on_event=self._on_link_event,
        )
        self.commands = CommandProtocol(self.link)
        # One condition for the link's state and everything below, so any
        # predicate sees the vehicle and the adapter's bookkeeping at once.
        self.cond = self.link.cond
        self.state: LinkState = self.link.state
        # Serializes vehicle-changing steps (commands, targets) between the
        # action, hold and abort threads (see control.RunControl).
        self.cmd_lock = threading.Lock()
        self.autopilot: Autopilot = autopilot_named("px4")  # replaced by connect()
        self.origin: NedOrigin | None = None  # home, in the vehicle's NED frame
        # Home was taken from an estimate not (known to be) settled: take it again
        # before the first take-off, once the estimator says it settled.
        self.origin_provisional = False
        self.flown = False  # took off since connecting (home then stays where it is)
        self.geo: GeoFrame | None = None  # home, in WGS84
        self.commanded: Vector | None = None  # last motion target, mission frame
        self.stream_target: Vector | None = None  # PX4 setpoint stream (NED)
        #: A path streamed instead of a target, on both autopilots (Orbit), and since when.
        self.path: CirclePath | None = None
        #: How far round the vehicle has flown so far (radians), for the path's target.
        self.path_flown: Callable[[], float] = lambda: 0.0
        #: The heading every target carries once a Yaw set one (degrees); None: yaw ignored.
        self.stream_yaw: float | None = None
        #: Horizontal speed the vehicle was told (the drone type's, then SetSpeed's).
        self.horizontal_speed_mps = settings.horizontal_speed_mps
        # Speeds (and fence parameters) set, to restore; never written once a pilot has it.
        self.keeper = ParamKeeper(self.link, settings, log, lambda: self.taken_over is not None)
        self.stream_since = 0.0  # when the stream (re)started, time.monotonic()
        self.guided_target: GuidedTarget | None = None  # ArduPilot, refreshed every second
        # Whose every mode change is (pilot.py): once a pilot's, nothing but heartbeats is
        # sent any more (taken_over set; on_taken_over told, outside the condition).
        self.takeover = takeover_watch(settings)
        self.taken_over: TakenOver | None = None
        self.on_taken_over: Callable[[TakenOver], None] | None = None
        self.pilot = PilotHand(self)
        self.link.observe = self.pilot.observe
        self.notices: list[AdapterNotice] = []  # for the operator, drained by notices()
        self.geofence = GeofenceKeeper(self)
        self.rates = RateKeeper(self.link, log, self.notify, lambda: self.taken_over is not None)
        self.home_check = VehicleHomeCheck(self.link, settings, log, self.notify)
        self._was_armed = False
        #: When it is at rest, when a move has arrived (settling.py).
        self.settling = Settling(self)
        self._last_position_key: tuple[float | bool, ...] | None = None

    # -- connecting ----------------------------------------------------------------

    def connect(self, extra_jobs: tuple[tuple[float, Callable[[], None], str], ...] = ()) -> None:
        """Open the link, wait for the HEARTBEAT, detect the autopilot, request telemetry.

        ``extra_jobs`` (period, job, name) run on the link's ticker too.
        Raises :class:`AdapterError` ("no heartbeat from <connection> within
        30 s", a transport that cannot open, an autopilot that is not the one
        the settings name).
        """
        s = self.settings
        deadline = time.monotonic() + s.connect_timeout_s
        self.link.every(s.wall_period(s.setpoint_hz), self._steer_tick, "setpoints")
        self.link.every(TARGET_REFRESH_S, self._refresh_tick, "target-refresh")
        self.link.every(POSITION_LOG_S, self._position_log_tick, "position-log")
        self.link.every(TAKEOVER_TICK_S, self.pilot.tick, "takeover")
        self.link.every(RATE_TICK_S, self.rates.tick, "rates")
        self.link.every(1.0, self.home_check.tick, "home")
        for period, job, name in extra_jobs:
            self.link.every(period, job, name)
        try:
            self.link.open(deadline)
        except LinkError as exc:
            self.link.close()
            if exc.unreachable:
                raise AdapterError(
                    f"{self.drone}: no heartbeat from {s.connection} within "
                    f"{s.connect_timeout_s:g} s ({exc})"
                ) from exc
            raise AdapterError(f"{self.drone}: {exc}") from exc
        st = self.state
        if not self.link.wait_for(
            lambda: st.heartbeats > 0 or st.refused_heartbeats >= REFUSED_HEARTBEATS, deadline
        ):
            self.link.close()
            raise AdapterError(
                f"{self.drone}: no heartbeat from {s.connection} within {s.connect_timeout_s:g} s"
            )
        if st.heartbeats == 0:
            self.link.close()
            raise AdapterError(f"{self.drone}: {refused_reason(st, s.connection)}")
        await_signing(self.link, s.signing_timeout_s, s.speedup, self.drone, self.log)
        with self.cond:
            detected, sysid = self.state.autopilot or 0, self.state.system_id
        try:
            found = autopilot_from_heartbeat(detected, s.takeoff_mode)
        except ValueError as exc:
            self.link.close()
            raise AdapterError(f"{self.drone}: {exc}") from exc
        if s.autopilot not in ("auto", found.name):
            self.link.close()
            raise field_error(
                "hal.autopilot",
                f"is {s.autopilot!r} but the vehicle's HEARTBEAT "
                f"announces {found.name} ({detected})",
            )
        with self.cond:
            self.autopilot = found
            self.takeover.set_autopilot(found.name)
        self.log.info(
            "adapter.connected", system_id=sysid, autopilot=found.name, mode=self.mode_name()
        )
        request_intervals(self.commands, self.autopilot.name, s, self.log, deadline)
        self.rates.start(watched(s.telemetry_hz))
        self.apply_speeds()

    def notify(self, kind: Literal["taken_over", "warning"], text: str) -> None:
        """Queue something for the operator (AdapterNotice; any thread)."""
        with self.cond:
            self.notices.append(AdapterNotice(kind, text))

    def close(self) -> None:
        """Close the link (its threads end; waiters wake and see ``state.closed``)."""
        self.link.close()

    def wait_link_ok(self, timeout: float) -> bool:
        """Block until HEARTBEATs arrive (again); False after ``timeout`` seconds."""
        return self.link.wait_for(lambda: self.state.link_ok, time.monotonic() + timeout)

    # -- the vehicle in mission terms (condition held) -------------------------------

    def mode_name(self, st: LinkState | None = None) -> str:
        """The current mode's name, from the latest HEARTBEAT."""
        return self.autopilot.mode_name((st or self.state).custom_mode)

    def armable(self, st: LinkState) -> bool:
        """A position estimate, and the pre-arm bit of SYS_STATUS (:func:`armable`)."""
        return armable(st)

    def mission_position(self, st: LinkState | None = None) -> Vector:
        """Where the vehicle is, in the mission frame (needs a LOCAL_POSITION_NED)."""
        st = st or self.state
        assert st.local is not None
        origin = self.origin or NedOrigin(st.local[0], st.local[1], st.local[2])
        return ned_to_mission(st.local[:3], origin)

    def here_ned(self) -> Vector:
        """Where the vehicle is, in its local NED frame."""
        local = self.state.local
        assert local is not None
        return (local[0], local[1], local[2])

    def speed(self, st: LinkState) -> float:
        """The 3-D speed from LOCAL_POSITION_NED."""
        assert st.local is not None
        return math.sqrt(st.local[3] ** 2 + st.local[4] ** 2 + st.local[5] ** 2)

    def on_ground(self, st: LinkState) -> bool:
        """EXTENDED_SYS_STATE says ON_GROUND (without it: below GROUND_Z_M)."""
        if st.landed_state is not None and st.landed_state != 0:
            return st.landed_state == MAV_LANDED_STATE_ON_GROUND
        if st.local is None or self.origin is None:
            return not st.armed
        return self.mission_position(st)[2] < GROUND_Z_M

    def landed(self, st: LinkState) -> bool:
        """A landing is over: on the ground, or disarmed (it disarms itself after touchdown)."""
        return not st.armed or self.on_ground(st)

    def base_point(self) -> Vector:
        """Where relative moves start: the previous commanded target (else here).

        Relative moves add up exactly as in the simulator: neither a leg's
        tolerance nor a wandering estimate (PX4 SIH: +-0.5 m) accumulates.
        After a cancel the commanded point is where the vehicle came to rest.
        """
        if self.commanded is not None:
            return self.commanded
        return self.mission_position()

    def capture_origin(self, ground: bool = False) -> None:
        """Record home at the first (settled) fix and, with ``ground``, the ground height
        before arming (:func:`eamos.hal.mavlink.home.capture_home`; condition held)."""
        capture_home(self, ground)

    def sample(self) -> Telemetry | None:
        """A telemetry sample of the current state (None before the first position)."""
        st = self.state
        if st.local is None:
            return None
        self.capture_origin()
        if self.origin is None:  # found armed, its home not heard yet
            return None
        x, y, z = self.mission_position(st)
        if st.global_pos is not None:
            lat, lon, alt = st.global_pos.lat_deg, st.global_pos.lon_deg, st.global_pos.rel_alt_m
        elif self.geo is not None:
            lat, lon, alt = self.geo.to_lla(x, y, z)
        else:
            lat, lon, alt = 0.0, 0.0, z
        return Telemetry(
            drone=self.drone,
            time_s=time.time(),
            x_m=round(x, 2) + 0.0,
            y_m=round(y, 2) + 0.0,
            z_m=round(z, 2) + 0.0,
            lat_deg=round(lat, 7),
            lon_deg=round(lon, 7),
            alt_m=round(alt, 2) + 0.0,
            # Until SYS_STATUS/BATTERY_STATUS says otherwise, assume a full battery.
            battery_pct=round(st.battery_pct, 1) if st.battery_pct is not None else 100.0,
            armed=st.armed,
            landed=self.on_ground(st),
        )

    def lost_reason(self) -> str:
        """Why an action ends when HEARTBEATs stop (:func:`heartbeat_lost`)."""
        return heartbeat_lost(self.state, self.settings)

    # -- steering (link ticker thread) -------------------------------------------------

    def send_setpoint(self, target: Vector) -> None:
        """SET_POSITION_TARGET_LOCAL_NED, position only, MAV_FRAME_LOCAL_NED."""
        with self.cond:
            yaw = self.stream_yaw
        send_position(self.link, target, yaw)

    def send_guided_target(self, target: GuidedTarget) -> None:
        """A local or global (relative altitude) position target, with the held heading.

        ArduCopter resets its yaw mode to ``WP_YAW_BEHAVIOR`` on every GUIDED target that
        ignores yaw (the notes): a heading set by Yaw must travel inside each target.
        """
        with self.cond:
            yaw = self.stream_yaw
        kind, point = target
        if kind == "local":
            send_position(self.link, point, yaw)
        else:
            send_global(self.link, point, yaw)

    def send_path_point(self, path: CirclePath) -> None:
        """The target of ``path`` just ahead of the vehicle, with its velocity."""
        with self.cond:
            flown = self.path_flown()
        position, velocity, heading = path.at(flown)
        send_path(self.link, position, velocity, heading)

    def stop_steering(self) -> None:
        """No more setpoints, paths or position targets (condition held)."""
        self.stream_target = None
        self.path = None
        self.guided_target = None

    def apply_speeds(self) -> None:
        """Set the drone type's speeds on the vehicle (keeper.py)."""
        self.keeper.apply_speeds(self.autopilot.name)

    def restore_params(self) -> None:
        """Write back the parameters the adapter changed (speeds, fence), then the
        vehicle's own fence (geofence.py)."""
        self.keeper.restore()
        self.geofence.restore()

    def _steer_tick(self) -> None:
        with self.cond:
            if self.taken_over is not None:
                return  # a pilot has it: no setpoint ever again
            if self._was_armed and not self.state.armed:
                # Disarmed (landed, auto-disarm, or by someone else): stop steering.
                self.stop_steering()
            self._was_armed = self.state.armed
            target, path = self.stream_target, self.path
        if path is not None:
            self.send_path_point(path)
        elif target is not None:
            self.send_setpoint(target)

    def _refresh_tick(self) -> None:
        with self.cond:
            target = None if self.taken_over is not None else self.guided_target
        if target is not None:
            self.send_guided_target(target)

    def _position_log_tick(self) -> None:
        _log_position(self)

    def _on_link_event(self, name: str, event: dict[str, Any]) -> None:
        """Copy what the link saw into the adapter log (reader/ticker threads)."""
        if name == "vehicle.mode":
            self.log.info(
                "adapter.mode",
                mode=self.autopilot.mode_name(event["custom_mode"]),
                previous=self.autopilot.mode_name(event["previous"]),
            )
        elif name == "vehicle.armed":
            self.log.info("adapter.armed", armed=event["armed"])
        elif name == "vehicle.statustext":
            self.log.info("adapter.statustext", **event)
        elif name == "vehicle.ack":
            self.log.debug("adapter.ack", **event)
        elif self.pilot.event(name, event):
            pass  # a takeover, a failsafe (pilot.py)
        elif name in ("link.lost", "link.transport_error", "link.job_error", "link.send_error"):
            self.log.warning(f"adapter.{name}", **event)
        else:
            self.log.info(f"adapter.{name}", **event)


def _log_position(self: MavlinkVehicle) -> None:
    """``adapter.position`` when the rounded position or state changed (ticker thread)."""
    with self.cond:
        st = self.state
        if st.local is None:
            return
        x, y, z = self.mission_position(st)
        key = (round(x, 2), round(y, 2), round(z, 2), st.armed, self.on_ground(st))
        if key == self._last_position_key:
            return
        self._last_position_key = key
        fields = {
            "speed_mps": round(self.speed(st), 2),
            "mode": self.mode_name(st),
            "battery_pct": st.battery_pct,
        }
    self.log.info(
        "adapter.position",
        x_m=key[0],
        y_m=key[1],
        z_m=key[2],
        armed=key[3],
        landed=key[4],
        **fields,
    )


__all__ = [
    "GROUND_Z_M",
    "TYPE_MASK_POSITION",
    "GuidedTarget",
    "MavlinkVehicle",
    "armable",
]
