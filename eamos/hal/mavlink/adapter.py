"""The MAVLink adapter (``adapter = "mavlink"``): fly a PX4 or ArduPilot vehicle.

:class:`MavlinkAdapter` drives one autopilot over one MAVLink connection
(serial, UDP or TCP).  It detects the autopilot from the vehicle's
HEARTBEAT (or takes ``autopilot`` from the settings).  The work is split:

* :mod:`eamos.hal.mavlink.link`: the connection, its reader thread (the
  vehicle's state under one condition), sends; :mod:`~eamos.hal.mavlink.ticker`
  the periodic jobs, :mod:`~eamos.hal.mavlink.command_protocol` and
  :mod:`~eamos.hal.mavlink.param_protocol` the MAVLink exchanges,
  :mod:`~eamos.hal.mavlink.signing` the link's signing;
* :mod:`eamos.hal.mavlink.vehicle`: the vehicle in mission terms (home,
  frames, modes, telemetry samples, PX4's setpoint stream);
* :mod:`eamos.hal.mavlink.flight`: the flight phases (arming, take-off, moves,
  landing, braking and holding) and their waits;
* :mod:`eamos.hal.mavlink.autopilots`: what differs between PX4 and ArduPilot;
* :mod:`eamos.hal.mavlink.runs` (the running actions, one ``done`` each) and
  :mod:`eamos.hal.mavlink.publisher` (telemetry samples to the mission);
* this module: the Adapter protocol (a thread per action, cancel, abort, close).

Frames.  Missions speak X north, Y east, Z up from home; the vehicle speaks
local NED.  Home is the first LOCAL_POSITION_NED seen after :meth:`start`
(the vehicle is expected on the ground then); the ground height is taken
again before every arming, because PX4's local z on the ground drifts
between flights.  See :mod:`eamos.hal.mavlink.frames`.

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

``cancel`` ends the action at once and brakes the vehicle with a position target
at its stopping point (what stopped both real autopilots soonest, braking.py),
then holds where it came to rest; the next motion action waits for that
(:class:`~eamos.hal.mavlink.braking.Brakes`).  ``abort`` cancels
everything, brakes, lands and disarms.  :meth:`MavlinkAdapter.close` never
leaves a flying vehicle silently: it lands it first, or logs
``adapter.stranded`` at error level.  After connecting, the drone type's
speeds are set on the vehicle and restored at close
(:mod:`eamos.hal.mavlink.params`); a vehicle that disarmed itself after our
Arm is armed again before Takeoff (``adapter.rearm``); Arm waits for a position
estimate good enough to fly, as the autopilot reports it (:mod:`eamos.hal.mavlink.arming`,
:mod:`~eamos.hal.mavlink.estimator`).  ReturnHome, Hold, Yaw, SetSpeed and Orbit are
flown in the motion mode with targets the adapter streams
(:mod:`eamos.hal.mavlink.manoeuvres`).
Plugin actions (TakePhoto, Gimbal...) run their "mavlink" implementation on the
action's thread (:mod:`eamos.hal.mavlink.payload`); the fixed payload actions (TurnOn,
Calibrate...) are acknowledged at once; ``PauseFor`` is a timer.

Telemetry: x/y/z from LOCAL_POSITION_NED (mission frame), lat/lon/alt from
GLOBAL_POSITION_INT (alt = relative_alt), battery from SYS_STATUS or
BATTERY_STATUS, armed from the HEARTBEAT, landed from EXTENDED_SYS_STATE (or
z below 0.1 m without it); sampled at ``telemetry_hz`` of vehicle time (scaled by
``speedup``) and sent only when it changed, plus one sample when an action ends,
so whoever reacts to the end already sees the state it ended in.

Adapter log events: ``adapter.start``, ``adapter.connected``,
``adapter.interval``, ``adapter.home``, ``adapter.action.start``/``.end``,
``adapter.payload``, ``adapter.cancel``, ``adapter.hold``,
``adapter.abort``/``.abort.done``/``.abort.failed``, ``adapter.brake``/``.brake.done``,
``adapter.rearm``, ``adapter.land.resumed``, ``adapter.param.*``,
``adapter.close_land``/``.done``/``.failed``,
``adapter.stranded``, ``adapter.statustext``,
``adapter.mode``, ``adapter.armed``, ``adapter.ack``, ``adapter.link.*``
(``vehicle``, ``lost``, ``restored``, ``gap``, ``transport_error``),
``adapter.position`` (at ``POSITION_LOG_HZ`` while it changes), ``adapter.close``.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Mapping
from typing import Any

from eamos.hal.api import (
    ActionHandle,
    ActionResult,
    AdapterError,
    AdapterNotice,
    DoneCallback,
    TakenOver,
    TelemetryCallback,
)
from eamos.hal.mavlink.autopilots import CommandRejected
from eamos.hal.mavlink.control import RunControl
from eamos.hal.mavlink.flight import Flight
from eamos.hal.mavlink.frames import Vector
from eamos.hal.mavlink.geofence import GeofenceError
from eamos.hal.mavlink.manoeuvres import MANOEUVRES, perform_manoeuvre
from eamos.hal.mavlink.payload import payload_context
from eamos.hal.mavlink.publisher import TelemetryPublisher
from eamos.hal.mavlink.runs import ActionBook
from eamos.hal.mavlink.settings import MavlinkSettings
from eamos.hal.mavlink.vehicle import MavlinkVehicle
from eamos.hal.mavlink.waits import Ended, Failed, Run, RunKind, TimedOut
from eamos.logs import EventLog, make_logger
from eamos.program.plugins import EMPTY_PLUGINS, PluginError, PluginRegistry, discover_plugins
from eamos.program.uniform import Arm, Command, Disarm, PluginAction


class MavlinkAdapter:
    """An :class:`~eamos.hal.api.Adapter` for a MAVLink autopilot (see module docstring)."""

    #: The adapter family plugin actions name implementations for (docs/plugins.md).
    family = "mavlink"

    def __init__(
        self,
        drone: str,
        settings: MavlinkSettings,
        adapter_log: EventLog | None = None,
        plugins: PluginRegistry = EMPTY_PLUGINS,
    ) -> None:
        self.drone = drone
        self.settings = settings
        #: The plugin actions it runs (their "mavlink" code, eamos.hal.mavlink.payload).
        self.plugins = plugins
        self._log: EventLog = adapter_log if adapter_log is not None else make_logger(None)
        self.vehicle = MavlinkVehicle(drone, settings, self._log)
        self._flight = Flight(self.vehicle)
        # The vehicle's condition also guards this adapter's bookkeeping.
        self._cond = self.vehicle.cond
        self._telemetry = TelemetryPublisher(self.vehicle, self._log)
        self._actions = ActionBook(self.vehicle, self._log, self._telemetry.publish)
        self._started = False
        self._closed = False
        self._aborting = False
        self._abort_thread: threading.Thread | None = None
        self.vehicle.on_taken_over = self._on_taken_over

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
            self._telemetry.connect(on_telemetry)
        self._log.info(
            "adapter.start",
            adapter="mavlink",
            connection=s.connection,
            autopilot=s.autopilot,
            system_id=s.system_id,
            source_system=s.source_system,
            source_component=s.source_component,
            # Where the fleet places its home (the check, monitor, report and replay too).
            home_m=None if s.home_m is None else list(s.home_m),
        )
        self.vehicle.connect(
            # At the vehicle's own rate: a condition is seen as early in vehicle time at
            # a speed-up of 10 as at 1 (telemetry_hz of wall time was a tenth of it).
            extra_jobs=((s.wall_period(s.telemetry_hz), self._telemetry.publish, "telemetry"),)
        )

    def run(self, command: Command, done: DoneCallback) -> ActionHandle:
        """Start ``command`` on its own thread; ``done`` is called exactly once."""
        handle = ActionHandle.of(command)
        kind: RunKind = "timer"
        if command.moves:
            kind = "motion"
        elif isinstance(command, Arm):
            kind = "arm"
        elif isinstance(command, Disarm):
            kind = "disarm"
        run = Run(handle, done, kind, time.monotonic(), command)
        refused: str | None = None  # a plugin action without a "mavlink" implementation
        if isinstance(command, PluginAction):
            try:
                self.plugins.implementation(command.name, self.family)
            except PluginError as exc:
                refused = str(exc)
        with self._cond:
            if self._closed:
                raise AdapterError(f"{self.drone}: adapter closed")
            if self.vehicle.taken_over is not None:
                refused = self.vehicle.taken_over.reason()  # never command it again
            immediate = self._actions.admit(run, self._started, self._aborting, refused)
        if immediate is not None:
            self._actions.finish(run, immediate)
            return handle
        threading.Thread(
            target=self._execute,
            args=(run,),
            daemon=True,
            name=f"mavlink-{self.drone}-{handle.action}-{handle.id}",
        ).start()
        return handle

    def cancel(self, handle: ActionHandle) -> None:
        """End ``handle`` with "cancelled"; a motion action brakes, then holds where it stops."""
        with self._cond:
            run = self._actions.running(handle.id)
            if run is None:
                return
            self._log.info("adapter.cancel", action=handle.action, handle=handle.id)
        if (
            self._actions.finish(run, ActionResult("cancelled", "cancelled"))
            and run.kind == "motion"
            and self.taken_over is None  # the pilot's vehicle is not braked by us
        ):
            self._flight.brakes.start_hold(f"mavlink-{self.drone}-hold")

    def abort(self) -> None:
        """Cancel every action, then land and disarm (on a thread of its own)."""
        with self._cond:
            if self._closed or not self._started:
                return
            taken = self.vehicle.taken_over
            self._aborting = taken is None
            runs = self._actions.all_running()
        self._log.info("adapter.abort", running=len(runs))
        for run in runs:
            self._actions.finish(run, ActionResult("cancelled", "aborted"))
        if taken is not None:
            # A pilot has it: no landing, no disarm (adapter.taken_over said so).
            self._log.warning("adapter.abort.skipped", reason=taken.reason())
            return
        thread = threading.Thread(
            target=self._abort, name=f"mavlink-{self.drone}-abort", daemon=True
        )
        with self._cond:
            self._abort_thread = thread
        thread.start()

    def close(self) -> None:
        """End running actions ("cancelled"), never leave a vehicle flying silently, put
        back the parameters the adapter changed, then close the link.

        A vehicle still in the air is braked, landed and disarmed first
        (``land_on_close``; ``adapter.close_land.done``); when it cannot be (link
        lost, landing failed, ``land_on_close = false``) ``adapter.stranded`` is
        logged at error level with where it was left and why.  A vehicle armed on the
        ground is disarmed (``adapter.close_disarm``).  Last, a telemetry sample of the
        state it ended in is published.
        """
        with self._cond:
            if self._closed:
                return
            self._closed = True
            runs = self._actions.all_running()
            started = self._started
            abort = self._abort_thread
        for run in runs:
            self._actions.finish(run, ActionResult("cancelled", "adapter closed"))
        if started:
            if abort is not None:
                abort.join(self.settings.scaled(self.settings.action_timeout_s))
            with self._cond:
                link_ok = self.vehicle.state.link_ok
                taken = self.vehicle.taken_over
            if taken is not None:
                self._leave_to_pilot(taken)
            else:
                self._flight.landing.land_at_close()
                if link_ok:
                    self.vehicle.restore_params()
            # The state the vehicle ended in (every landing and disarm above seen in a
            # HEARTBEAT) reaches the mission before the link closes: a summary must not
            # say "armed" of a vehicle that disarmed.
            self._telemetry.publish()
        self.vehicle.close()
        self._log.info("adapter.close")

    # -- a pilot's takeover (takeover.py) ---------------------------------------

    @property
    def taken_over(self) -> TakenOver | None:
        """The pilot's takeover, once seen (the Adapter protocol's optional part)."""
        with self._cond:
            return self.vehicle.taken_over

    def _on_taken_over(self, taken: TakenOver) -> None:
        """A pilot took the vehicle (link thread): every running action fails with it,
        and the operator hears it at once."""
        left = self._params_left()
        kept = f"; parameters left as EAMOS set them: {left}" if left else ""
        self.vehicle.notify(
            "taken_over",
            f"{taken.describe()}: EAMOS no longer commands it (no land, no disarm, "
            f"no mode change){kept}",
        )
        with self._cond:
            runs = self._actions.all_running()
        for run in runs:
            self._actions.finish(run, ActionResult("failed", taken.reason()))
        self._telemetry.publish()

    def _params_left(self) -> str:
        """The parameters the adapter changed, as they stay on a vehicle a pilot has."""
        return ", ".join(
            f"{c.name} = {c.after:g} (was {c.before:g})" for c in self.vehicle.keeper.changes
        )

    def _leave_to_pilot(self, taken: TakenOver) -> None:
        """At close, a vehicle a pilot has: not landed, not disarmed, nothing restored;
        the log says which parameters stay as the adapter set them."""
        self._log.warning(
            "adapter.close.taken_over",
            mode=taken.mode,
            params_left=self._params_left(),
            note="left to the pilot: not landed, not disarmed, parameters not restored",
        )

    def notices(self) -> list[AdapterNotice]:
        """What the operator must hear, each once (the Adapter protocol's optional part)."""
        with self._cond:
            out, self.vehicle.notices = self.vehicle.notices, []
        return out

    def facts(self) -> dict[str, Any]:
        """What the run's summary records about this vehicle (the Adapter protocol's
        optional part): the autopilot, whether the link was signed, whether the fleet's
        geofence went on the vehicle (None: the fleet has none), a takeover."""
        with self._cond:
            taken = self.vehicle.taken_over
            fence = self.vehicle.geofence
            out: dict[str, Any] = {
                "autopilot": self.vehicle.autopilot.name if self._started else None,
                "signed": self.vehicle.link.signed,
                "fence": fence.uploaded if fence.wanted else None,
            }
        if taken is not None:
            out["taken_over"] = taken.to_json()
        return out

    def autopilot_status(self) -> tuple[str, int, list[tuple[int, str]]]:
        """The vehicle's own flight mode, how many STATUSTEXTs it sent, and the latest
        (severity, text) pairs: the operator's page shows them (the Adapter protocol's
        optional part, read by the uniform API at each telemetry sample)."""
        with self._cond:
            st = self.vehicle.state
            texts = list(zip(st.severities, st.statustexts, strict=False))
            return self.vehicle.mode_name(), st.statustext_serial, texts

    # -- observation (tests, tools) ------------------------------------------

    @property
    def autopilot(self) -> str:
        """``"px4"`` or ``"ardupilot"`` (known after :meth:`start`)."""
        return self.vehicle.autopilot.name

    def mode_name(self) -> str:
        """The vehicle's mode from its latest HEARTBEAT."""
        with self._cond:
            return self.vehicle.mode_name()

    @property
    def link_ok(self) -> bool:
        """True while HEARTBEATs arrive."""
        with self._cond:
            return self.vehicle.state.link_ok

    def wait_link_ok(self, timeout: float) -> bool:
        """Block until HEARTBEATs arrive (again); False after ``timeout`` seconds."""
        return self.vehicle.wait_link_ok(timeout)

    def position(self) -> Vector | None:
        """The vehicle's position in the mission frame, or None before the first fix."""
        with self._cond:
            if self.vehicle.state.local is None or self.vehicle.origin is None:
                return None
            return self.vehicle.mission_position()

    # -- running actions -------------------------------------------------------

    def _execute(self, run: Run) -> None:
        assert run.handle is not None
        try:
            if run.kind == "motion":
                self._await_frame(run)
            if isinstance(run.command, PluginAction):
                result = self._plugin(run, run.command)
            elif isinstance(run.command, MANOEUVRES):
                result = perform_manoeuvre(self._flight, run)
            else:
                result = self._flight.perform(run)
        except Ended:
            return  # finished already (cancel, abort, close): its done was called
        except TimedOut as exc:
            # Like the simulator: a move that never arrives stops where it is.
            if run.kind == "motion":
                self._flight.brakes.start_hold(f"mavlink-{self.drone}-hold")
            result = ActionResult("failed", str(exc))
        except (Failed, CommandRejected, GeofenceError) as exc:
            result = ActionResult("failed", str(exc))
        except Exception as exc:  # a bug must still answer the caller
            self._log.exception("adapter.error", action=run.handle.action, error=repr(exc))
            result = ActionResult("failed", f"adapter error: {exc!r}")
        self._actions.finish(run, result)

    def _await_frame(self, run: Run) -> None:
        """A move waits until the adapter knows where home is (the mission frame).

        At the first position it does at once; a vehicle found armed (its node
        restarted mid-flight) has none until its HOME_POSITION arrives, and a move
        sent before that would read "on the ground" at (0, 0, 0).
        """
        v = self.vehicle
        self._flight.waiter.wait(
            run,
            lambda st: v.origin is not None,
            run.started + self.settings.connect_timeout_s,
            lambda st: (
                "no mission frame: the vehicle's position (found armed: its HOME_POSITION) "
                f"did not arrive within {self.settings.connect_timeout_s:g} s"
            ),
        )

    def _plugin(self, run: Run, command: PluginAction) -> ActionResult:
        """A plugin action's "mavlink" implementation, on this action's thread."""
        with self._cond:
            self._flight.waiter.raise_if_over(run)
        implementation = self.plugins.implementation(command.name, self.family)
        ctx = payload_context(self.vehicle, RunControl(self._flight.waiter, run), run)
        result = implementation(ctx, command)
        if not isinstance(result, ActionResult):
            raise Failed(f"plugin {command.name} returned {result!r}, not an ActionResult")
        return result

    def _abort(self) -> None:
        try:
            self._flight.landing.land_and_disarm()
        finally:
            with self._cond:
                self._aborting = False
            # The state it ended in (disarmed, seen in a HEARTBEAT) reaches the
            # mission before it reports: the summary must not say "armed".
            self._telemetry.publish()


def mavlink_adapter_from_settings(
    drone: str, settings: Mapping[str, Any], adapter_log: EventLog | None = None
) -> MavlinkAdapter:
    """Build a :class:`MavlinkAdapter` from a drone's ``hal`` settings mapping.

    It runs the plugin actions installed through entry points (``eamos.actions``) that
    have a "mavlink" implementation; broken plugins are logged
    (``adapter.plugin_problem``) and left out.
    """
    log = adapter_log if adapter_log is not None else make_logger(None)
    # Looked up on first use (a mission without plugin actions never reads the entry
    # points: reading them costs a measurable part of a node's start-up, see
    # docs/performance.md); problems logged then.
    plugins = discover_plugins(
        on_problem=lambda problem: log.warning("adapter.plugin_problem", problem=problem)
    )
    return MavlinkAdapter(drone, MavlinkSettings.from_mapping(settings), log, plugins)


__all__ = [
    "MavlinkAdapter",
    "MavlinkSettings",
    "mavlink_adapter_from_settings",
]
