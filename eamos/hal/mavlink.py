"""The MAVLink adapter (``adapter = "mavlink"``): fly a PX4 or ArduPilot vehicle.

:class:`MavlinkAdapter` drives one autopilot over one MAVLink connection
(serial, UDP or TCP; see :mod:`eamos.hal.mavlink_link`).  It detects the
autopilot from the vehicle's HEARTBEAT (or takes ``autopilot`` from the
settings) and delegates the flight steps that differ between PX4 and
ArduPilot to :mod:`eamos.hal.autopilots`.

Frames.  Missions speak X north, Y east, Z up from home; the vehicle speaks
local NED.  Home is the first LOCAL_POSITION_NED seen after :meth:`start`
(the vehicle is expected on the ground then); the ground height is taken
again before every arming, because PX4's local z on the ground drifts
between flights.  See :mod:`eamos.hal.mavlink_frames`.

Actions.  Each action runs on a thread of its own and waits for the vehicle
with ``Condition.wait_for`` against monotonic deadlines.  It completes on
real criteria: the armed flag in a HEARTBEAT (Arm/Disarm), position within
``tolerance_m`` and speed below ``settle_speed_mps`` (Takeoff, FlyBy*,
FlyTo*), EXTENDED_SYS_STATE ON_GROUND or disarmed (Land).  It fails with a
reason: the command's MAV_RESULT name and the vehicle's STATUSTEXT when a
command is refused, "heartbeat lost" when the vehicle is silent for more
than ``heartbeat_timeout_s``, "vehicle disarmed" or "vehicle switched to
mode X" when someone else takes over mid-action, a timeout after
``action_timeout_s`` (the vehicle then holds).  One motion action runs at a
time; another one fails "busy".

PX4 sometimes leaves OFFBOARD by itself: a second without setpoints (a link
hiccup) is a failsafe, and PX4 returns to OFFBOARD once the stream resumes.
A mode change within ``heartbeat_timeout_s`` after a link gap or a
"failsafe" STATUSTEXT is therefore tolerated for that long; any other mode
change ends the action (a pilot took over).

``cancel`` holds where the vehicle is (PX4: the setpoint becomes the current
position; ArduPilot: so does the GUIDED position target); ``abort`` cancels
everything and lands, then disarms.  Payload actions are acknowledged at
once (this vehicle has no payload); ``PauseFor`` is a timer.

Adapter log events: ``adapter.start``, ``adapter.connected``,
``adapter.interval``, ``adapter.action.start``/``.end``, ``adapter.cancel``,
``adapter.abort``/``.abort.done``, ``adapter.statustext``, ``adapter.mode``,
``adapter.armed``, ``adapter.link.*``, ``adapter.position`` (once a second
while it changes), ``adapter.close``.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, fields
from typing import Any, Literal

from eamos.hal.api import (
    ActionHandle,
    ActionResult,
    AdapterError,
    DoneCallback,
    Telemetry,
    TelemetryCallback,
)
from eamos.hal.autopilots import (
    Autopilot,
    CommandRejected,
    TakeoffMode,
    autopilot_from_heartbeat,
    autopilot_named,
)
from eamos.hal.kinematics import EARTH_RADIUS_M, GeoFrame
from eamos.hal.mavlink_frames import (
    NedOrigin,
    Vector,
    mission_to_ned,
    ned_to_mission,
)
from eamos.hal.mavlink_link import (
    MAV_RESULT_ACCEPTED,
    MAV_RESULT_TEMPORARILY_REJECTED,
    MAV_SYS_STATUS_PREARM_CHECK,
    LinkError,
    LinkState,
    MavlinkLink,
    check_connection,
    result_name,
)
from eamos.hal.settings import (
    COMMON_KEYS,
    check_keys,
    field_error,
    number,
    require_mapping,
)
from eamos.hal.uniform import ACTIONS
from eamos.logs import make_logger

# MAVLink numbers used below.
MAV_CMD_COMPONENT_ARM_DISARM = 400
MAV_CMD_DO_SET_MODE = 176
MAV_CMD_SET_MESSAGE_INTERVAL = 511
MAV_FRAME_LOCAL_NED = 1
MAV_FRAME_GLOBAL_RELATIVE_ALT_INT = 6
MAV_LANDED_STATE_ON_GROUND = 1
#: SET_POSITION_TARGET_* type_mask: use the position only (ignore velocity,
#: acceleration, yaw and yaw rate), so the vehicle keeps its heading.
TYPE_MASK_POSITION = 0x0FF8
#: Messages requested with MAV_CMD_SET_MESSAGE_INTERVAL at start, and at what
#: rate: None means ``telemetry_hz``.
MSG_LOCAL_POSITION_NED = 32
MSG_GLOBAL_POSITION_INT = 33
MSG_SYS_STATUS = 1
MSG_EXTENDED_SYS_STATE = 245
MSG_BATTERY_STATUS = 147
MSG_HOME_POSITION = 242
TELEMETRY_INTERVALS: dict[int, float | None] = {
    MSG_LOCAL_POSITION_NED: None,
    MSG_GLOBAL_POSITION_INT: None,
    MSG_EXTENDED_SYS_STATE: None,
    MSG_SYS_STATUS: 2.0,
    MSG_BATTERY_STATUS: 1.0,
    MSG_HOME_POSITION: 0.5,
}
#: Below this height (m above the take-off ground) a vehicle without
#: EXTENDED_SYS_STATE counts as on the ground.
GROUND_Z_M = 0.1
#: ArduPilot position targets are re-sent this often (they need not stream,
#: but a lost UDP datagram must not strand the vehicle).
TARGET_REFRESH_S = 1.0
#: After a refused arming (TEMPORARILY_REJECTED), try again this much later.
ARM_RETRY_S = 1.0
#: After a refused command, how long to wait for the STATUSTEXT explaining it.
STATUSTEXT_GRACE_S = 0.3

MOTION_ACTIONS = frozenset(
    {"Takeoff", "Land", "FlyByX", "FlyByY", "FlyByZ", "FlyToXYZ", "FlyToLLA"}
)


@dataclass(frozen=True)
class MavlinkSettings:
    """Settings of the MAVLink adapter; build with :meth:`from_mapping`."""

    connection: str
    system_id: int | None = None
    component_id: int = 1
    source_system: int = 245
    source_component: int = 191
    autopilot: Literal["auto", "px4", "ardupilot"] = "auto"
    takeoff_mode: TakeoffMode = "offboard"
    connect_timeout_s: float = 30.0
    armable_timeout_s: float = 60.0
    command_timeout_s: float = 1.5
    command_retries: int = 3
    heartbeat_timeout_s: float = 3.0
    action_timeout_s: float = 120.0
    tolerance_m: float = 0.3
    settle_speed_mps: float = 0.3
    setpoint_hz: float = 20.0
    telemetry_hz: float = 10.0

    @classmethod
    def from_mapping(cls, mapping: Mapping[str, Any], prefix: str = "hal") -> MavlinkSettings:
        """Validate a drone's ``hal`` settings; errors read ``"hal.<field>: <problem>"``."""
        mapping = require_mapping(mapping, prefix)
        check_keys(mapping, {f.name for f in fields(cls)} | COMMON_KEYS, prefix)
        if "connection" not in mapping:
            raise field_error(
                f"{prefix}.connection",
                'missing; e.g. "udpin:0.0.0.0:14540" (PX4 SITL), "tcp:127.0.0.1:5760" '
                '(ArduPilot SITL) or "/dev/ttyACM0,921600" (serial)',
            )
        connection = mapping["connection"]
        if not isinstance(connection, str):
            raise field_error(f"{prefix}.connection", f"expected a string, got {connection!r}")
        problem = check_connection(connection)
        if problem:
            raise field_error(f"{prefix}.connection", f"{problem}; got {connection!r}")

        def num(key: str, **bounds: float) -> float:
            return number(mapping, key, getattr(cls, key), prefix, **bounds)

        def integer(key: str, low: int, high: int, default: int | None) -> int | None:
            if key not in mapping:
                return default
            value = mapping[key]
            if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
                raise field_error(
                    f"{prefix}.{key}", f"expected an integer from {low} to {high}, got {value!r}"
                )
            return value

        def choice(key: str, options: tuple[str, ...]) -> Any:
            value = mapping.get(key, getattr(cls, key))
            if value not in options:
                raise field_error(
                    f"{prefix}.{key}", f"expected one of {', '.join(options)}; got {value!r}"
                )
            return value

        return cls(
            connection=connection,
            system_id=integer("system_id", 1, 255, None),
            component_id=integer("component_id", 0, 255, 1) or 0,
            source_system=integer("source_system", 1, 255, 245) or 245,
            source_component=integer("source_component", 0, 255, 191) or 0,
            autopilot=choice("autopilot", ("auto", "px4", "ardupilot")),
            takeoff_mode=choice("takeoff_mode", ("offboard", "auto")),
            connect_timeout_s=num("connect_timeout_s", gt=0),
            armable_timeout_s=num("armable_timeout_s", gt=0),
            command_timeout_s=num("command_timeout_s", gt=0),
            command_retries=integer("command_retries", 1, 100, 3) or 3,
            heartbeat_timeout_s=num("heartbeat_timeout_s", gt=0),
            action_timeout_s=num("action_timeout_s", gt=0),
            tolerance_m=num("tolerance_m", gt=0),
            settle_speed_mps=num("settle_speed_mps", gt=0),
            setpoint_hz=num("setpoint_hz", gt=2, le=100),
            telemetry_hz=num("telemetry_hz", gt=0, le=100),
        )


class _Ended(Exception):
    """The action was already finished (cancelled, aborted, closed): just stop."""


class _Failed(Exception):
    """The action fails with this reason."""


class _TimedOut(_Failed):
    """The action fails because its deadline passed (the vehicle then holds)."""


_Kind = Literal["motion", "arm", "disarm", "timer", "internal"]


@dataclass(eq=False)
class _Run:
    """One running action (or an internal job such as hold/abort, never finished early)."""

    handle: ActionHandle | None
    done: DoneCallback | None
    kind: _Kind
    started: float  # time.monotonic()
    finished: bool = False


class _Control:
    """The :class:`~eamos.hal.autopilots.Controller` of one run: commands and waits.

    Every vehicle-changing step happens under the adapter's command lock after
    checking that the run is still going, so a cancel's hold (which takes the
    same lock afterwards) always has the last word.
    """

    def __init__(self, adapter: MavlinkAdapter, run: _Run) -> None:
        self.a = adapter
        self.run = run

    def _check(self) -> None:
        with self.a._cond:
            self.a._raise_if_over(self.run)

    def mode(self) -> str:
        with self.a._cond:
            return self.a._mode_name(self.a._state)

    def command(self, command: int, params: tuple[float, ...]) -> None:
        a, run = self.a, self.run
        s = a.settings
        with a._cmd_lock:
            with a._cond:
                a._raise_if_over(run)
                text_seen = a._state.statustext_serial
            result = a._link.command_long(
                command, params, timeout_s=s.command_timeout_s, retries=s.command_retries,
                abandon=lambda: run.finished or not a._state.link_ok,
            )
        name = _command_name(command)
        with a._cond:
            a._raise_if_over(run)
            if result is None:
                raise _Failed(f"no COMMAND_ACK for {name} after {s.command_retries} tries")
            if result != MAV_RESULT_ACCEPTED:
                # The explanation (PX4 "Arming denied: ...") may trail the ack.
                a._cond.wait_for(lambda: a._state.statustext_serial > text_seen,
                                 timeout=STATUSTEXT_GRACE_S)
                texts = list(a._state.statustexts)[-(a._state.statustext_serial - text_seen):] \
                    if a._state.statustext_serial > text_seen else []
                raise CommandRejected(name, result_name(result), "; ".join(texts))

    def set_mode(self, mode: str) -> None:
        a = self.a
        if self.mode() == mode:
            return  # "already in that mode" is success
        self.command(MAV_CMD_DO_SET_MODE, (*a._autopilot.mode_params(mode), 0.0, 0.0, 0.0, 0.0))
        s = a.settings
        deadline = time.monotonic() + s.command_timeout_s * s.command_retries
        # An accepted mode change shows in the next HEARTBEAT; confirm it there.
        a._wait(self.run, lambda st: a._mode_name(st) == mode, deadline,
                lambda st: f"vehicle accepted mode {mode} but its HEARTBEAT still shows "
                           f"{a._mode_name(st)}")

    def stream(self, target_ned: Vector | None) -> None:
        a = self.a
        with a._cmd_lock, a._cond:
            a._raise_if_over(self.run)
            if target_ned is not None and a._stream_target is None:
                a._stream_since = time.monotonic()
            a._stream_target = target_ned
        if target_ned is not None:
            a._send_setpoint(target_ned)  # at once, not at the next tick

    def wait_stream_warm(self, seconds: float) -> None:
        a = self.a
        with a._cond:
            since = a._stream_since
        a._wait(self.run, lambda st: a._stream_target is None, since + seconds,
                lambda st: "", quiet_timeout=True)

    def position_target(self, target_ned: Vector) -> None:
        a = self.a
        with a._cmd_lock, a._cond:
            a._raise_if_over(self.run)
            a._guided_target = ("local", target_ned)
        a._send_guided_target(("local", target_ned))

    def global_target(self, lat_deg: float, lon_deg: float, rel_alt_m: float) -> None:
        a = self.a
        target = ("global", (lat_deg, lon_deg, rel_alt_m))
        with a._cmd_lock, a._cond:
            a._raise_if_over(self.run)
            a._guided_target = target
        a._send_guided_target(target)

    def amsl_m(self, height_m: float) -> float:
        a = self.a
        with a._cond:
            g = a._state.global_pos
            if g is None:
                raise _Failed("no GLOBAL_POSITION_INT from the vehicle: cannot compute AMSL")
            z = a._mission_position(a._state)[2]
            return g.alt_amsl_m - z + height_m

    def pause(self, seconds: float) -> None:
        """Wait ``seconds`` (on the condition; a cancel or link loss ends it early)."""
        self.a._wait(self.run, lambda st: False, time.monotonic() + seconds, lambda st: "",
                     quiet_timeout=True)


def _command_name(command: int) -> str:
    return {
        400: "MAV_CMD_COMPONENT_ARM_DISARM",
        176: "MAV_CMD_DO_SET_MODE",
        22: "MAV_CMD_NAV_TAKEOFF",
        21: "MAV_CMD_NAV_LAND",
        511: "MAV_CMD_SET_MESSAGE_INTERVAL",
    }.get(command, f"MAV_CMD({command})")


class MavlinkAdapter:
    """An :class:`~eamos.hal.api.Adapter` for a MAVLink autopilot (see module docstring)."""

    def __init__(self, drone: str, settings: MavlinkSettings, adapter_log: Any = None) -> None:
        self.drone = drone
        self.settings = settings
        self._log = adapter_log if adapter_log is not None else make_logger(None)
        self._link = MavlinkLink(
            settings.connection, source_system=settings.source_system,
            source_component=settings.source_component, system_id=settings.system_id,
            component_id=settings.component_id, heartbeat_timeout_s=settings.heartbeat_timeout_s,
            on_event=self._on_link_event,
        )
        # One condition guards the vehicle state (written by the link's reader)
        # and this adapter's bookkeeping, so every predicate sees both at once.
        self._cond = self._link.cond
        self._state: LinkState = self._link.state
        # Serializes vehicle-changing steps (commands, targets) between action,
        # hold and abort threads; see _Control.
        self._cmd_lock = threading.Lock()
        self._emit_lock = threading.Lock()
        self._autopilot: Autopilot = autopilot_named("px4")  # replaced in start()
        self._on_telemetry: TelemetryCallback | None = None
        self._started = False
        self._closed = False
        self._runs: dict[int, _Run] = {}
        self._motion: _Run | None = None
        self._aborting = False
        self._pending_hold: threading.Thread | None = None
        self._origin: NedOrigin | None = None
        self._geo: GeoFrame | None = None
        self._commanded: Vector | None = None  # last motion target, mission frame
        self._stream_target: Vector | None = None  # PX4 setpoint stream (NED)
        self._stream_since = 0.0
        self._guided_target: tuple[str, Vector] | None = None  # ArduPilot target refresh
        self._was_armed = False
        self._last_key: tuple[Any, ...] | None = None
        self._last_position_log = -math.inf
        self._last_position_key: tuple[Any, ...] | None = None

    # -- Adapter protocol ----------------------------------------------------

    def start(self, on_telemetry: TelemetryCallback) -> None:
        """Connect, wait for the vehicle's HEARTBEAT, request telemetry.

        Raises :class:`AdapterError` ``"no heartbeat from <connection> within
        30 s"`` when the vehicle stays silent for ``connect_timeout_s``.
        """
        s = self.settings
        with self._cond:
            if self._closed:
                raise AdapterError(f"{self.drone}: adapter already closed")
            if self._started:
                raise AdapterError(f"{self.drone}: adapter already started")
            self._started = True
            self._on_telemetry = on_telemetry
        self._log.info("adapter.start", adapter="mavlink", connection=s.connection,
                       autopilot=s.autopilot, system_id=s.system_id,
                       source_system=s.source_system, source_component=s.source_component)
        deadline = time.monotonic() + s.connect_timeout_s
        self._link.every(1.0 / s.setpoint_hz, self._stream_tick, "setpoints")
        self._link.every(TARGET_REFRESH_S, self._refresh_tick, "target-refresh")
        self._link.every(1.0 / s.telemetry_hz, self._telemetry_tick, "telemetry")
        try:
            self._link.open(deadline)
        except LinkError as exc:
            self._link.close()
            if exc.unreachable:
                raise AdapterError(f"{self.drone}: no heartbeat from {s.connection} within "
                                   f"{s.connect_timeout_s:g} s ({exc})") from exc
            raise AdapterError(f"{self.drone}: {exc}") from exc
        if not self._link.wait_for(lambda: self._state.heartbeats > 0, deadline):
            self._link.close()
            raise AdapterError(
                f"{self.drone}: no heartbeat from {s.connection} within {s.connect_timeout_s:g} s"
            )
        with self._cond:
            detected, sysid = self._state.autopilot or 0, self._state.system_id
        try:
            found = autopilot_from_heartbeat(detected, s.takeoff_mode)
        except ValueError as exc:
            self._link.close()
            raise AdapterError(f"{self.drone}: {exc}") from exc
        if s.autopilot not in ("auto", found.name):
            self._link.close()
            raise field_error("hal.autopilot", f"is {s.autopilot!r} but the vehicle's HEARTBEAT "
                                               f"announces {found.name} ({detected})")
        self._autopilot = found
        self._log.info("adapter.connected", system_id=sysid, autopilot=found.name,
                       mode=self.mode_name())
        self._request_intervals(deadline)

    def run(self, action: str, args: tuple[float, ...], done: DoneCallback) -> ActionHandle:
        """Start ``action`` on its own thread; ``done`` is called exactly once."""
        handle = ActionHandle(action, tuple(args))
        spec = ACTIONS.get(action)
        kind: _Kind = "timer"
        if action in MOTION_ACTIONS:
            kind = "motion"
        elif action == "Arm":
            kind = "arm"
        elif action == "Disarm":
            kind = "disarm"
        run = _Run(handle, done, kind, time.monotonic())
        immediate: ActionResult | None = None
        with self._cond:
            if self._closed:
                raise AdapterError(f"{self.drone}: adapter closed")
            self._runs[handle.id] = run
            self._log.info("adapter.action.start", action=action, args=list(args),
                           handle=handle.id)
            if spec is None:
                immediate = ActionResult("failed", f"unknown action {action!r}")
            elif len(args) != len(spec.params) or not all(
                isinstance(v, int | float) and math.isfinite(v) for v in args
            ):
                immediate = ActionResult(
                    "failed",
                    f"{action} takes {len(spec.params)} finite number(s), got {list(args)}",
                )
            elif spec.payload:
                self._log.info("adapter.payload", action=action,
                               note="no payload on this vehicle: acknowledged")
                immediate = ActionResult("ok")
            elif not self._started:
                immediate = ActionResult("failed", "adapter not started")
            elif self._aborting and action != "PauseFor":
                immediate = ActionResult("failed", "aborting")
            elif kind == "motion":
                if self._motion is not None:
                    immediate = ActionResult("failed", "busy")
                else:
                    self._motion = run
        if immediate is not None:
            self._finish(run, immediate)
            return handle
        threading.Thread(target=self._execute, args=(run,), daemon=True,
                         name=f"mavlink-{self.drone}-{action}-{handle.id}").start()
        return handle

    def cancel(self, handle: ActionHandle) -> None:
        """End ``handle`` with "cancelled"; a motion action leaves the vehicle holding."""
        with self._cond:
            run = self._runs.get(handle.id)
            if run is None:
                return
            self._log.info("adapter.cancel", action=handle.action, handle=handle.id)
        if self._finish(run, ActionResult("cancelled", "cancelled")) and run.kind == "motion":
            self._start_hold()

    def abort(self) -> None:
        """Cancel every action, then land and disarm (on a thread of its own)."""
        with self._cond:
            if self._closed or not self._started:
                return
            self._aborting = True
            runs = list(self._runs.values())
        self._log.info("adapter.abort", running=len(runs))
        for run in runs:
            self._finish(run, ActionResult("cancelled", "aborted"))
        threading.Thread(target=self._abort_job, name=f"mavlink-{self.drone}-abort",
                         daemon=True).start()

    def close(self) -> None:
        """Stop the link's threads and close it; running actions end "cancelled"."""
        with self._cond:
            if self._closed:
                return
            self._closed = True
            runs = list(self._runs.values())
        for run in runs:
            self._finish(run, ActionResult("cancelled", "adapter closed"))
        self._link.close()
        self._log.info("adapter.close")

    # -- observation (tests, tools) ------------------------------------------

    @property
    def autopilot(self) -> str:
        """``"px4"`` or ``"ardupilot"`` (known after :meth:`start`)."""
        return self._autopilot.name

    def mode_name(self) -> str:
        """The vehicle's mode from its latest HEARTBEAT."""
        with self._cond:
            return self._mode_name(self._state)

    @property
    def link_ok(self) -> bool:
        """True while HEARTBEATs arrive."""
        with self._cond:
            return self._state.link_ok

    def position(self) -> Vector | None:
        """The vehicle's position in the mission frame, or None before the first fix."""
        with self._cond:
            if self._state.local is None or self._origin is None:
                return None
            return self._mission_position(self._state)

    # -- running actions -------------------------------------------------------

    def _execute(self, run: _Run) -> None:
        assert run.handle is not None
        try:
            result = self._procedure(run)
        except _Ended:
            return
        except _TimedOut as exc:
            # Like the simulator: a move that never arrives stops where it is.
            if run.kind == "motion":
                self._start_hold()
            result = ActionResult("failed", str(exc))
        except _Failed as exc:
            result = ActionResult("failed", str(exc))
        except CommandRejected as exc:
            result = ActionResult("failed", str(exc))
        except Exception as exc:  # a bug must still answer the caller
            self._log.exception("adapter.error", action=run.handle.action, error=repr(exc))
            result = ActionResult("failed", f"adapter error: {exc!r}")
        self._finish(run, result)

    def _procedure(self, run: _Run) -> ActionResult:
        assert run.handle is not None
        name, args = run.handle.action, run.handle.args
        ctl = _Control(self, run)
        if name == "PauseFor":
            if args[0] < 0:
                raise _Failed("duration_s must be >= 0")
            self._wait(run, lambda st: False, run.started + args[0], lambda st: "",
                       quiet_timeout=True, watch_link=False)
            return ActionResult("ok")
        with self._cond:
            if not self._state.link_ok:
                raise _Failed(self._lost_reason())
        if name == "Arm":
            return self._arm(run, ctl)
        if name == "Disarm":
            return self._disarm(run, ctl)
        hold = self._pending_hold
        if hold is not None:
            hold.join(self.settings.command_timeout_s * self.settings.command_retries * 3)
        if name == "Takeoff":
            return self._takeoff(run, ctl, args[0])
        if name == "Land":
            return self._land(run, ctl)
        return self._move(run, ctl, name, args)

    def _arm(self, run: _Run, ctl: _Control) -> ActionResult:
        s = self.settings
        with self._cond:
            if self._state.armed:
                return ActionResult("ok")  # already armed is success
        deadline = run.started + s.armable_timeout_s
        self._wait(
            run, self._armable, deadline,
            lambda st: f"vehicle never became armable within {s.armable_timeout_s:g} s: "
                       f"{st.last_statustext or 'no STATUSTEXT from the vehicle'}",
        )
        with self._cond:
            self._capture_origin(ground=True)
            here = self._here_ned()
        self._autopilot.prepare_arm(ctl, here)
        while True:
            try:
                ctl.command(MAV_CMD_COMPONENT_ARM_DISARM, (1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0))
                break
            except CommandRejected as exc:
                with self._cond:
                    if self._state.armed:
                        break
                temporary = exc.result == result_name(MAV_RESULT_TEMPORARILY_REJECTED)
                if temporary and time.monotonic() + ARM_RETRY_S < deadline:
                    ctl.pause(ARM_RETRY_S)
                    continue
                why = f": {exc.statustext}" if exc.statustext else ""
                until = f" until the {s.armable_timeout_s:g} s armable timeout" if temporary else ""
                raise _Failed(f"arming refused ({exc.result}{until}){why}") from exc
        # PX4's HEARTBEAT may show the armed flag up to a second after the ack.
        self._wait(run, lambda st: st.armed, time.monotonic() + self._confirm_s(),
                   lambda st: "vehicle acknowledged arming but its HEARTBEAT never showed it armed")
        return ActionResult("ok")

    def _disarm(self, run: _Run, ctl: _Control) -> ActionResult:
        with self._cond:
            if not self._state.armed:
                return ActionResult("ok")
            if not self._on_ground(self._state):
                raise _Failed("in the air")
        try:
            ctl.command(MAV_CMD_COMPONENT_ARM_DISARM, (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0))
        except CommandRejected:
            with self._cond:
                if not self._state.armed:  # it disarmed by itself meanwhile
                    return ActionResult("ok")
            raise
        self._wait(run, lambda st: not st.armed, time.monotonic() + self._confirm_s(),
                   lambda st: "vehicle acknowledged disarming but its HEARTBEAT still shows armed")
        with self._cond:
            self._stream_target = None
            self._guided_target = None
        return ActionResult("ok")

    def _takeoff(self, run: _Run, ctl: _Control, height: float) -> ActionResult:
        if height <= 0:
            raise _Failed("height_m must be > 0")
        with self._cond:
            if not self._state.armed:
                raise _Failed("not armed")
            if self._origin is None:
                raise _Failed("no LOCAL_POSITION_NED from the vehicle yet")
            x, y, _ = self._mission_position(self._state)
            target = (x, y, height)
            self._commanded = target
            target_ned = mission_to_ned(target, self._origin)
        self._autopilot.takeoff(ctl, target_ned, height)
        modes = self._autopilot.takeoff_modes()
        self._confirm_modes(run, modes, done=lambda st: False)
        tol, settle = self.settings.tolerance_m, self.settings.settle_speed_mps

        def arrived(st: LinkState) -> bool:
            # Vertical only: a real take-off may drift a little sideways.
            z = self._mission_position(st)[2]
            return abs(z - height) <= tol and self._speed(st) <= settle

        self._wait(run, arrived, run.started + self.settings.action_timeout_s,
                   self._timeout_reason("take-off height not reached"),
                   guard=self._guard(modes))
        return ActionResult("ok")

    def _land(self, run: _Run, ctl: _Control) -> ActionResult:
        with self._cond:
            if self._on_ground(self._state):
                return ActionResult("ok")
            here = self._here_ned()
        self._autopilot.land(ctl, here)
        with self._cond:
            self._guided_target = None

        def landed(st: LinkState) -> bool:
            return not st.armed or st.landed_state == MAV_LANDED_STATE_ON_GROUND or (
                st.landed_state is None and self._mission_position(st)[2] < GROUND_Z_M
            )

        modes = frozenset({self._autopilot.land_mode})
        self._confirm_modes(run, modes, done=landed)
        self._wait(run, landed, run.started + self.settings.action_timeout_s,
                   self._timeout_reason("not landed"),
                   guard=self._guard(modes, need_armed=False, unless=landed))
        return ActionResult("ok")

    def _move(self, run: _Run, ctl: _Control, name: str, args: tuple[float, ...]) -> ActionResult:
        s = self.settings
        with self._cond:
            if not self._state.armed:
                raise _Failed("not armed")
            if self._on_ground(self._state) or self._origin is None:
                raise _Failed("not flying")
            x, y, z = self._base_point()
            lla: tuple[float, float, float] | None = None
            if name == "FlyByX":
                target = (x + args[0], y, z)
            elif name == "FlyByY":
                target = (x, y + args[0], z)
            elif name == "FlyByZ":
                target = (x, y, z + args[0])
            elif name == "FlyToXYZ":
                target = (args[0], args[1], args[2])
            else:  # FlyToLLA
                if self._geo is None:
                    raise _Failed("no GLOBAL_POSITION_INT from the vehicle: cannot fly to a "
                                  "latitude/longitude")
                lla = (args[0], args[1], args[2])
                target = self._geo.from_lla(*lla)
            if target[2] <= 0:
                raise _Failed(f"target z {target[2]:.2f} m is not above ground (use Land)")
            self._commanded = target
            target_ned = mission_to_ned(target, self._origin)
        if lla is not None:
            self._autopilot.goto_global(ctl, lla[0], lla[1], lla[2], target_ned)
        else:
            self._autopilot.goto(ctl, target_ned)
        modes = frozenset({self._autopilot.motion_mode})
        self._confirm_modes(run, modes, done=lambda st: False)

        def arrived(st: LinkState) -> bool:
            return (
                math.dist(self._mission_position(st), target) <= s.tolerance_m
                and self._speed(st) <= s.settle_speed_mps
            )

        self._wait(run, arrived, run.started + s.action_timeout_s,
                   self._timeout_reason("target not reached"), guard=self._guard(modes))
        return ActionResult("ok")

    # -- waiting ------------------------------------------------------------------

    def _wait(
        self,
        run: _Run,
        until: Callable[[LinkState], bool],
        deadline: float,
        timeout_reason: Callable[[LinkState], str],
        *,
        guard: Callable[[LinkState], str | None] | None = None,
        quiet_timeout: bool = False,
        watch_link: bool = True,
    ) -> None:
        """Wait on the condition until ``until(state)``; raise why not.

        Ends early (raising) when the run is finished by someone else, the
        adapter closes, HEARTBEATs stop (``watch_link``) or ``guard`` names a
        problem.  At ``deadline`` it raises ``_Failed(timeout_reason(state))``,
        or returns quietly with ``quiet_timeout`` (a plain timer).
        """
        st = self._state

        def ready() -> bool:
            return (
                run.finished or st.closed or (watch_link and not st.link_ok) or until(st)
                or (guard is not None and guard(st) is not None)
            )

        with self._cond:
            self._cond.wait_for(ready, timeout=max(0.0, deadline - time.monotonic()))
            self._raise_if_over(run, watch_link=watch_link)
            if until(st):
                return
            problem = guard(st) if guard is not None else None
            if problem is not None:
                raise _Failed(problem)
            if quiet_timeout:
                return
            raise _TimedOut(timeout_reason(st))

    def _raise_if_over(self, run: _Run, watch_link: bool = True) -> None:
        """Raise if ``run`` must stop (condition held)."""
        if run.finished:
            raise _Ended
        if self._state.closed or self._closed:
            raise _Failed("adapter closed")
        if watch_link and not self._state.link_ok:
            raise _Failed(self._lost_reason())

    def _lost_reason(self) -> str:
        text = self._state.last_statustext
        return (f"heartbeat lost: no HEARTBEAT from the vehicle for more than "
                f"{self.settings.heartbeat_timeout_s:g} s" + (f" (last STATUSTEXT: {text})"
                                                              if text else ""))

    def _confirm_modes(
        self, run: _Run, modes: frozenset[str], done: Callable[[LinkState], bool]
    ) -> None:
        """Wait until a HEARTBEAT shows one of ``modes`` (or ``done``): acks run ahead of it."""
        self._wait(
            run, lambda st: self._mode_name(st) in modes or done(st),
            time.monotonic() + self._confirm_s(),
            lambda st: f"vehicle is in mode {self._mode_name(st)}, expected "
                       f"{' or '.join(sorted(modes))}",
        )

    def _guard(
        self,
        modes: frozenset[str],
        need_armed: bool = True,
        unless: Callable[[LinkState], bool] | None = None,
    ) -> Callable[[LinkState], str | None]:
        """A check that someone else has not taken the vehicle over mid-action."""
        grace = self.settings.heartbeat_timeout_s

        def check(st: LinkState) -> str | None:
            if unless is not None and unless(st):
                return None
            text = f" ({st.last_statustext})" if st.last_statustext else ""
            if need_armed and not st.armed:
                return f"vehicle disarmed{text}"
            mode = self._mode_name(st)
            if mode not in modes:
                # PX4 leaves OFFBOARD when setpoints stop for a second and comes
                # back when they resume: tolerate that after a gap or failsafe.
                if time.monotonic() < max(st.gap_ended_at, st.failsafe_at) + grace:
                    return None
                return f"vehicle switched to mode {mode} under us{text}"
            return None

        return check

    def _timeout_reason(self, what: str) -> Callable[[LinkState], str]:
        t = self.settings.action_timeout_s
        return lambda st: f"timeout after {t:g} s: {what}"

    def _confirm_s(self) -> float:
        """How long a HEARTBEAT may take to confirm an acknowledged change."""
        s = self.settings
        return max(2.5, s.command_timeout_s * s.command_retries)

    # -- vehicle state helpers (condition held) --------------------------------

    def _mode_name(self, st: LinkState) -> str:
        return self._autopilot.mode_name(st.custom_mode)

    def _armable(self, st: LinkState) -> bool:
        if st.local is None:
            return False  # no position estimate yet
        present = st.sensors_present
        if present is None or not present & MAV_SYS_STATUS_PREARM_CHECK:
            return present is not None or st.local_count > 0
        return bool((st.sensors_health or 0) & MAV_SYS_STATUS_PREARM_CHECK)

    def _mission_position(self, st: LinkState) -> Vector:
        assert st.local is not None
        origin = self._origin or NedOrigin(st.local[0], st.local[1], st.local[2])
        return ned_to_mission(st.local[:3], origin)

    def _here_ned(self) -> Vector:
        local = self._state.local
        assert local is not None
        return (local[0], local[1], local[2])

    def _speed(self, st: LinkState) -> float:
        assert st.local is not None
        return math.sqrt(st.local[3] ** 2 + st.local[4] ** 2 + st.local[5] ** 2)

    def _on_ground(self, st: LinkState) -> bool:
        if st.landed_state is not None and st.landed_state != 0:
            return st.landed_state == MAV_LANDED_STATE_ON_GROUND
        if st.local is None or self._origin is None:
            return not st.armed
        return self._mission_position(st)[2] < GROUND_Z_M

    def _base_point(self) -> Vector:
        """Where relative moves start: the last target if we are there, else here.

        Using the target keeps FlyBy sequences from accumulating each leg's
        tolerance (as the simulator does).
        """
        here = self._mission_position(self._state)
        if self._commanded is not None and math.dist(here, self._commanded) <= \
                self.settings.tolerance_m:
            return self._commanded
        return here

    def _capture_origin(self, ground: bool = False) -> None:
        """Record home (first fix) and, with ``ground``, the ground height before arming."""
        st = self._state
        if st.local is None:
            return
        if self._origin is None:
            self._origin = NedOrigin(st.local[0], st.local[1], st.local[2])
            self._log.info("adapter.home", north_m=round(st.local[0], 3),
                           east_m=round(st.local[1], 3), down_m=round(st.local[2], 3))
        elif ground and not st.armed:
            self._origin = self._origin.with_ground(st.local[2])
        if self._geo is None and st.global_pos is not None:
            # The WGS84 point of home: the vehicle's fix shifted back by where
            # it stands in the mission frame.
            g = st.global_pos
            x, y, z = ned_to_mission(st.local[:3], self._origin)
            lat0 = g.lat_deg - math.degrees(x / EARTH_RADIUS_M)
            lon0 = g.lon_deg - math.degrees(
                y / (EARTH_RADIUS_M * math.cos(math.radians(g.lat_deg)))
            )
            self._geo = GeoFrame(lat0, lon0, g.alt_amsl_m - z)

    # -- holding and aborting ----------------------------------------------------

    def _start_hold(self) -> None:
        """Hold where the vehicle is, on a thread (mode changes may take a second)."""
        thread = threading.Thread(target=self._hold_job, name=f"mavlink-{self.drone}-hold",
                                  daemon=True)
        with self._cond:
            self._pending_hold = thread
        thread.start()

    def _hold_job(self) -> None:
        run = _Run(None, None, "internal", time.monotonic())
        try:
            with self._cond:
                if self._state.local is None:
                    return
                here = self._here_ned()
                airborne = not self._on_ground(self._state)
                self._commanded = self._mission_position(self._state) if self._origin else None
            self._autopilot.hold(_Control(self, run), here, airborne)
            self._log.info("adapter.hold", north_m=round(here[0], 2), east_m=round(here[1], 2),
                           down_m=round(here[2], 2))
        except (_Failed, _Ended, CommandRejected) as exc:
            self._log.warning("adapter.hold_failed", error=str(exc))

    def _abort_job(self) -> None:
        run = _Run(None, None, "internal", time.monotonic())
        ctl = _Control(self, run)
        hold = self._pending_hold
        if hold is not None:
            hold.join(self.settings.command_timeout_s * self.settings.command_retries * 3)
        try:
            with self._cond:
                airborne = self._state.local is not None and not self._on_ground(self._state)
                here = self._here_ned() if self._state.local is not None else (0.0, 0.0, 0.0)
            if airborne:
                self._autopilot.land(ctl, here)
                with self._cond:
                    self._guided_target = None
                self._wait(run, lambda st: not st.armed or self._on_ground(st),
                           time.monotonic() + self.settings.action_timeout_s,
                           self._timeout_reason("not landed"))
            with self._cond:
                armed = self._state.armed
            if armed:
                ctl.command(MAV_CMD_COMPONENT_ARM_DISARM, (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0))
            self._log.info("adapter.abort.done")
        except (_Failed, _Ended, CommandRejected) as exc:
            self._log.error("adapter.abort.failed", error=str(exc))
        finally:
            with self._cond:
                self._aborting = False

    # -- bookkeeping ------------------------------------------------------------------

    def _finish(self, run: _Run, result: ActionResult) -> bool:
        """Finish ``run`` once; call its done callback outside the condition."""
        with self._cond:
            if run.finished:
                return False
            run.finished = True
            if run.handle is not None:
                self._runs.pop(run.handle.id, None)
            if self._motion is run:
                self._motion = None
            self._cond.notify_all()
            pos = (self._mission_position(self._state)
                   if self._state.local is not None else (math.nan,) * 3)
        if run.handle is not None:
            self._log.info(
                "adapter.action.end", action=run.handle.action, args=list(run.handle.args),
                handle=run.handle.id, status=result.status, reason=result.reason,
                duration_s=round(time.monotonic() - run.started, 3),
                x_m=round(pos[0], 3), y_m=round(pos[1], 3), z_m=round(pos[2], 3),
            )
        if run.done is not None:
            # Publish the state the action ended in before anyone reacts to its end
            # (a mission that completes right after Disarm reports that sample).
            self._telemetry_tick()
            try:
                run.done(result)
            except Exception as exc:
                self._log.exception("adapter.callback_error", error=repr(exc))
        return True

    def _request_intervals(self, deadline: float) -> None:
        """Ask for the telemetry this adapter reads (best effort, logged)."""
        s = self.settings
        for msg_id, hz in TELEMETRY_INTERVALS.items():
            rate = s.telemetry_hz if hz is None else min(hz, s.telemetry_hz)
            if time.monotonic() >= deadline:
                break
            result = self._link.command_long(
                MAV_CMD_SET_MESSAGE_INTERVAL, (float(msg_id), 1e6 / rate, 0, 0, 0, 0, 0),
                timeout_s=s.command_timeout_s, retries=1,
            )
            self._log.info("adapter.interval", message=msg_id, hz=rate, result=result_name(result))

    # -- periodic jobs (link ticker thread) ---------------------------------------

    def _stream_tick(self) -> None:
        with self._cond:
            target = self._stream_target
        if target is not None:
            self._send_setpoint(target)

    def _send_setpoint(self, target: Vector) -> None:
        system, component = self._link.target
        self._link.send(
            "set_position_target_local_ned", self._link.time_boot_ms(), system, component,
            MAV_FRAME_LOCAL_NED, TYPE_MASK_POSITION, target[0], target[1], target[2],
            0, 0, 0, 0, 0, 0, 0, 0,
        )

    def _refresh_tick(self) -> None:
        with self._cond:
            target = self._guided_target
        if target is not None:
            self._send_guided_target(target)

    def _send_guided_target(self, target: tuple[str, Vector]) -> None:
        kind, point = target
        if kind == "local":
            self._send_setpoint(point)
            return
        system, component = self._link.target
        lat, lon, alt = point
        self._link.send(
            "set_position_target_global_int", self._link.time_boot_ms(), system, component,
            MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, TYPE_MASK_POSITION, round(lat * 1e7),
            round(lon * 1e7), alt, 0, 0, 0, 0, 0, 0, 0, 0,
        )

    def _telemetry_tick(self) -> None:
        # Serialized: the ticker and finishing actions both publish, and samples
        # must reach the mission in the order they were taken.
        with self._emit_lock:
            self._publish()

    def _publish(self) -> None:
        with self._cond:
            st = self._state
            if st.local is None:
                return
            self._capture_origin()
            if self._was_armed and not st.armed:
                # Disarmed (landed, auto-disarm, or by someone else): stop steering.
                self._stream_target = None
                self._guided_target = None
            self._was_armed = st.armed
            sample = self._sample(st)
            key = _sample_key(sample)
            fresh = key != self._last_key
            self._last_key = key
            now = time.monotonic()
            log_position = now - self._last_position_log >= 1.0 and \
                key[:3] + key[7:] != self._last_position_key
            if log_position:
                self._last_position_log = now
                self._last_position_key = key[:3] + key[7:]
                speed = self._speed(st)
                mode = self._mode_name(st)
        if log_position:
            self._log.info("adapter.position", x_m=sample.x_m, y_m=sample.y_m, z_m=sample.z_m,
                           speed_mps=round(speed, 2), armed=sample.armed, landed=sample.landed,
                           battery_pct=sample.battery_pct, mode=mode)
        callback = self._on_telemetry
        if fresh and callback is not None:
            try:
                callback(sample)
            except Exception as exc:
                self._log.exception("adapter.telemetry_error", error=repr(exc))

    def _sample(self, st: LinkState) -> Telemetry:
        x, y, z = self._mission_position(st)
        if st.global_pos is not None:
            lat, lon, alt = st.global_pos.lat_deg, st.global_pos.lon_deg, st.global_pos.rel_alt_m
        elif self._geo is not None:
            lat, lon, alt = self._geo.to_lla(x, y, z)
        else:
            lat, lon, alt = 0.0, 0.0, z
        return Telemetry(
            drone=self.drone, time_s=time.time(),
            x_m=round(x, 2) + 0.0, y_m=round(y, 2) + 0.0, z_m=round(z, 2) + 0.0,
            lat_deg=round(lat, 7), lon_deg=round(lon, 7), alt_m=round(alt, 2) + 0.0,
            # Unknown until SYS_STATUS/BATTERY_STATUS says otherwise.
            battery_pct=round(st.battery_pct, 1) if st.battery_pct is not None else 100.0,
            armed=st.armed, landed=self._on_ground(st),
        )

    def _on_link_event(self, name: str, event: dict[str, Any]) -> None:
        """Copy what the link saw into the adapter log (reader/ticker threads)."""
        if name == "vehicle.mode":
            self._log.info("adapter.mode", mode=self._autopilot.mode_name(event["custom_mode"]),
                           previous=self._autopilot.mode_name(event["previous"]))
        elif name == "vehicle.armed":
            self._log.info("adapter.armed", armed=event["armed"])
        elif name == "vehicle.statustext":
            self._log.info("adapter.statustext", **event)
        elif name == "vehicle.ack":
            self._log.debug("adapter.ack", **event)
        elif name in ("link.lost", "link.transport_error", "link.job_error", "link.send_error"):
            self._log.warning(f"adapter.{name}", **event)
        else:
            self._log.info(f"adapter.{name}", **event)


def _sample_key(sample: Telemetry) -> tuple[Any, ...]:
    """A sample without its timestamp: equal keys carry no news."""
    return (
        sample.x_m, sample.y_m, sample.z_m, sample.lat_deg, sample.lon_deg, sample.alt_m,
        sample.battery_pct, sample.armed, sample.landed,
    )


def mavlink_adapter_from_settings(
    drone: str, settings: Mapping[str, Any], adapter_log: Any = None
) -> MavlinkAdapter:
    """Build a :class:`MavlinkAdapter` from a drone's ``hal`` settings mapping."""
    return MavlinkAdapter(drone, MavlinkSettings.from_mapping(settings), adapter_log)


__all__ = [
    "MavlinkAdapter",
    "MavlinkSettings",
    "mavlink_adapter_from_settings",
]
