"""The MAVLink adapter's flight procedures: one uniform action, from command to real completion.

:class:`Flight` runs each action on the caller's thread (the adapter gives
every action a thread of its own) and returns its :class:`ActionResult` or
raises why it failed.  Every wait (:class:`~eamos.hal.mavlink.waits.Waiter`) is
``Condition.wait_for`` on the vehicle's condition against a ``time.monotonic()``
deadline, and ends early when the action is finished by someone else (cancel,
abort, close), when HEARTBEATs stop, or when a guard sees that someone else took
the vehicle over.  ReturnHome, Hold, Yaw, SetSpeed and Orbit are in
:mod:`eamos.hal.mavlink.manoeuvres`, plugin actions in :mod:`eamos.hal.mavlink.payload`.

What differs between PX4 and ArduPilot is asked of the vehicle's
:class:`~eamos.hal.mavlink.autopilots.Autopilot`, through a :class:`RunControl`: the
:class:`~eamos.hal.mavlink.autopilots.Controller` bound to one running action.
"""

from __future__ import annotations

import threading
import time

from eamos.hal.api import ActionResult
from eamos.hal.mavlink.arming import await_settled, disarmed_on_ground
from eamos.hal.mavlink.autopilots import CommandRejected
from eamos.hal.mavlink.braking import brake_to_rest
from eamos.hal.mavlink.frames import Vector, mission_to_ned
from eamos.hal.mavlink.link import (
    MAV_RESULT_ACCEPTED,
    MAV_RESULT_TEMPORARILY_REJECTED,
    LinkState,
    result_name,
)
from eamos.hal.mavlink.vehicle import MavlinkVehicle
from eamos.hal.mavlink.waits import Ended, Failed, Run, TimedOut, Waiter
from eamos.program.uniform import (
    Arm,
    Disarm,
    FlyBy,
    FlyToLLA,
    FlyToXYZ,
    Land,
    PauseFor,
    Takeoff,
    target_xyz,
)

MAV_CMD_COMPONENT_ARM_DISARM = 400
MAV_CMD_DO_SET_MODE = 176
ARM = (1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
DISARM = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
#: After a refused arming (TEMPORARILY_REJECTED), try again this much later.
ARM_RETRY_S = 1.0
#: After a refused command, how long to wait for the STATUSTEXT explaining it.
STATUSTEXT_GRACE_S = 0.3
COMMAND_NAMES = {
    400: "MAV_CMD_COMPONENT_ARM_DISARM",
    176: "MAV_CMD_DO_SET_MODE",
    22: "MAV_CMD_NAV_TAKEOFF",
    21: "MAV_CMD_NAV_LAND",
    511: "MAV_CMD_SET_MESSAGE_INTERVAL",
    20: "MAV_CMD_NAV_RETURN_TO_LAUNCH",
    34: "MAV_CMD_DO_ORBIT",
    115: "MAV_CMD_CONDITION_YAW",
    178: "MAV_CMD_DO_CHANGE_SPEED",
    205: "MAV_CMD_DO_MOUNT_CONTROL",
    1000: "MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW",
    2000: "MAV_CMD_IMAGE_START_CAPTURE",
    2500: "MAV_CMD_VIDEO_START_CAPTURE",
    2501: "MAV_CMD_VIDEO_STOP_CAPTURE",
}


class RunControl:
    """The :class:`~eamos.hal.mavlink.autopilots.Controller` of one run: commands, targets, waits.

    Every vehicle-changing step takes the vehicle's command lock and checks
    that the run is still going, so a cancel's hold (which takes the same lock
    afterwards) always has the last word.
    """

    def __init__(self, flight: Flight, run: Run) -> None:
        self.flight = flight
        self.waiter = flight.waiter
        self.v = flight.v
        self.run = run

    def mode(self) -> str:
        with self.v.cond:
            return self.v.mode_name()

    def command(self, command: int, params: tuple[float, ...], frame: int | None = None) -> None:
        v, run, s = self.v, self.run, self.v.settings
        with v.cmd_lock:
            with v.cond:
                self.waiter.raise_if_over(run)
                text_seen = v.state.statustext_serial
            result = v.link.command_long(
                command,
                params,
                timeout_s=s.command_timeout_s,
                retries=s.command_retries,
                abandon=lambda: run.finished or not v.state.link_ok,
                frame=frame,
            )
        name = COMMAND_NAMES.get(command, f"MAV_CMD({command})")
        with v.cond:
            self.waiter.raise_if_over(run)
            if result is None:
                raise Failed(f"no COMMAND_ACK for {name} after {s.command_retries} tries")
            if result != MAV_RESULT_ACCEPTED:
                # The explanation (PX4's "Arming denied: ...") may trail the ack.
                v.cond.wait_for(
                    lambda: v.state.statustext_serial > text_seen, timeout=STATUSTEXT_GRACE_S
                )
                fresh = v.state.statustext_serial - text_seen
                texts = list(v.state.statustexts)[-fresh:] if fresh > 0 else []
                raise CommandRejected(name, result_name(result), "; ".join(texts))

    def set_mode(self, mode: str) -> None:
        if self.mode() == mode:
            return  # "already in that mode" is success
        self.command(MAV_CMD_DO_SET_MODE, (*self.v.autopilot.mode_params(mode), 0.0, 0.0, 0.0, 0.0))
        # An accepted mode change shows in the next HEARTBEAT; confirm it there.
        self.waiter.wait(
            self.run,
            lambda st: self.v.mode_name(st) == mode,
            time.monotonic() + self.waiter.confirm_s(),
            lambda st: (
                f"vehicle accepted mode {mode} but its HEARTBEAT still shows {self.v.mode_name(st)}"
            ),
        )

    def stream(self, target_ned: Vector | None) -> None:
        v = self.v
        with v.cmd_lock, v.cond:
            self.waiter.raise_if_over(self.run)
            if target_ned is not None and v.stream_target is None and not v.stream_stop:
                v.stream_since = time.monotonic()
            v.stream_target = target_ned
            v.stream_stop = False
        if target_ned is not None:
            v.send_setpoint(target_ned)  # at once, not at the next tick

    def set_yaw(self, heading_deg: float) -> None:
        with self.v.cond:
            self.v.stream_yaw = heading_deg

    def stop_target(self) -> None:
        v = self.v
        with v.cmd_lock, v.cond:
            self.waiter.raise_if_over(self.run)
            if v.stream_target is None and not v.stream_stop:
                v.stream_since = time.monotonic()
            v.stream_stop = True
            v.guided_target = None
        v.send_stop()  # at once: braking starts with this datagram

    def wait_stream_warm(self, seconds: float) -> None:
        with self.v.cond:
            since = self.v.stream_since
        self.waiter.wait(
            self.run, lambda st: False, since + seconds, lambda st: "", quiet_timeout=True
        )

    def position_target(self, target_ned: Vector) -> None:
        self._guided(("local", target_ned))

    def global_target(self, lat_deg: float, lon_deg: float, rel_alt_m: float) -> None:
        self._guided(("global", (lat_deg, lon_deg, rel_alt_m)))

    def _guided(self, target: tuple[str, Vector]) -> None:
        v = self.v
        with v.cmd_lock, v.cond:
            self.waiter.raise_if_over(self.run)
            v.guided_target = target
        v.send_guided_target(target)

    def amsl_m(self, height_m: float) -> float:
        v = self.v
        with v.cond:
            g = v.state.global_pos
            if g is None:
                raise Failed("no GLOBAL_POSITION_INT from the vehicle: cannot compute AMSL")
            return g.alt_amsl_m - v.mission_position()[2] + height_m

    def pause(self, seconds: float) -> None:
        """Wait ``seconds`` (on the condition; a cancel or link loss ends it early)."""
        self.waiter.wait(
            self.run,
            lambda st: False,
            time.monotonic() + seconds,
            lambda st: "",
            quiet_timeout=True,
        )


class Flight:
    """The flight procedures of one vehicle (see module docstring)."""

    def __init__(self, vehicle: MavlinkVehicle) -> None:
        self.v = vehicle
        self.s = vehicle.settings
        self.waiter = Waiter(vehicle)
        self._pending_hold: threading.Thread | None = None
        #: Our Arm succeeded and no Disarm of ours followed (the mission wants it armed).
        self.armed_by_us = False

    def perform(self, run: Run) -> ActionResult:
        """Run one action to its end: its result, or Failed/TimedOut/Ended/CommandRejected."""
        command = run.command
        assert command is not None
        ctl = RunControl(self, run)
        if isinstance(command, PauseFor):
            if command.duration_s < 0:
                raise Failed("duration_s must be >= 0")
            # A timer of our own: it does not need the vehicle, nor its link.
            self.waiter.wait(
                run,
                lambda st: False,
                run.started + command.duration_s,
                lambda st: "",
                quiet_timeout=True,
                watch_link=False,
            )
            return ActionResult("ok")
        with self.v.cond:
            self.waiter.raise_if_over(run)
        match command:
            case Arm():
                return self.arm(run, ctl)
            case Disarm():
                return self.disarm(run, ctl)
            case Takeoff(height_m=height):
                self.await_hold()
                return self.takeoff(run, ctl, height)
            case Land():
                self.await_hold()
                return self.land(run, ctl)
            case FlyBy() | FlyToXYZ() | FlyToLLA():
                self.await_hold()
                return self.move(run, ctl, command)
        raise Failed(f"{command.action} is not an action this vehicle flies")

    # -- the actions -------------------------------------------------------------------

    def arm(self, run: Run, ctl: RunControl) -> ActionResult:
        """Wait until armable, prepare (mode, stream), arm, see the armed flag."""
        v, s = self.v, self.s
        with v.cond:
            if v.state.armed:
                return ActionResult("ok")  # already armed is success
        deadline = run.started + s.scaled(s.armable_timeout_s)
        self._arm_now(run, ctl, deadline)
        return ActionResult("ok")

    def _arm_now(self, run: Run, ctl: RunControl, deadline: float) -> None:
        """Wait until armable (until ``deadline``), prepare, arm, see the armed flag."""
        v, s = self.v, self.s
        self.waiter.wait(
            run,
            v.armable,
            deadline,
            lambda st: (
                f"vehicle never became armable within {s.armable_timeout_s:g} s: "
                f"{st.last_statustext or 'no STATUSTEXT from the vehicle'}"
            ),
        )
        # The pre-arm bit is not enough: PX4 main accepts arming long before its estimate
        # settles, and home taken from that estimate is metres off.
        await_settled(self.waiter, v, run, deadline)
        with v.cond:
            v.capture_origin(ground=True)
            here = v.here_ned()
        v.autopilot.prepare_arm(ctl, here)
        while True:
            try:
                ctl.command(MAV_CMD_COMPONENT_ARM_DISARM, ARM)
                break
            except CommandRejected as exc:
                with v.cond:
                    if v.state.armed:
                        break
                temporary = exc.result == result_name(MAV_RESULT_TEMPORARILY_REJECTED)
                if temporary and time.monotonic() + ARM_RETRY_S < deadline:
                    ctl.pause(ARM_RETRY_S)  # not ready yet: PX4 says so, try again
                    continue
                why = f": {exc.statustext}" if exc.statustext else ""
                until = f" until the {s.armable_timeout_s:g} s armable timeout" if temporary else ""
                raise Failed(f"arming refused ({exc.result}{until}){why}") from exc
        # PX4's HEARTBEAT may show the armed flag up to a second after the ack.
        self.waiter.wait(
            run,
            lambda st: st.armed,
            time.monotonic() + self.waiter.confirm_s(),
            lambda st: "vehicle acknowledged arming but its HEARTBEAT never showed it armed",
        )
        with v.cond:
            self.armed_by_us = True

    def disarm(self, run: Run, ctl: RunControl) -> ActionResult:
        """Disarm on the ground ("in the air" otherwise); see the flag drop."""
        v = self.v
        with v.cond:
            if not v.state.armed:
                return ActionResult("ok")
            if not v.on_ground(v.state):
                raise Failed("in the air")
        try:
            ctl.command(MAV_CMD_COMPONENT_ARM_DISARM, DISARM)
        except CommandRejected:
            with v.cond:
                if not v.state.armed:  # it disarmed by itself meanwhile
                    return ActionResult("ok")
            raise
        self._confirm_disarmed(run)
        return ActionResult("ok")

    def _confirm_disarmed(self, run: Run) -> None:
        """Wait until a HEARTBEAT shows the vehicle disarmed (not the acknowledgement alone)."""
        v = self.v
        self.waiter.wait(
            run,
            lambda st: not st.armed,
            time.monotonic() + self.waiter.confirm_s(),
            lambda st: "vehicle acknowledged disarming but its HEARTBEAT still shows armed",
        )
        with v.cond:
            v.stop_steering()
            self.armed_by_us = False

    def takeoff(self, run: Run, ctl: RunControl, height: float) -> ActionResult:
        """Climb to ``height`` above the take-off ground at the current X/Y.

        The mission armed this drone and may have kept it waiting: when the
        autopilot disarmed itself meanwhile (COM_DISARM_PRFLT, DISARM_DELAY),
        before or just as the take-off starts (even before a HEARTBEAT showed
        it: :func:`~eamos.hal.mavlink.arming.disarmed_on_ground`), it is armed
        again (``rearm``), once.
        """
        if height <= 0:
            raise Failed("height_m must be > 0")
        for attempt in range(2):
            with self.v.cond:
                st = self.v.state
                rearm = not st.armed and self.armed_by_us and self.s.rearm
                if not st.armed and not rearm:
                    raise Failed("not armed")
            if rearm:
                self._rearm(run, ctl)
            try:
                return self._climb(run, ctl, height)
            except (Failed, CommandRejected):  # ArduCopter: NAV_TAKEOFF FAILED when disarmed
                again = self.armed_by_us and self.s.rearm and not attempt
                if not again or not disarmed_on_ground(self.waiter, self.v, run):
                    raise
        raise AssertionError("unreachable")

    def _rearm(self, run: Run, ctl: RunControl) -> None:
        v, s = self.v, self.s
        with v.cond:
            why = v.state.last_statustext
            here = v.here_ned()
        v.log.warning("adapter.rearm", reason=why or "vehicle disarmed itself")
        # PX4 left in OFFBOARD without a stream is never armable: stream first.
        v.autopilot.prepare_arm(ctl, here)
        self._arm_now(run, ctl, time.monotonic() + s.scaled(s.armable_timeout_s))

    def _climb(self, run: Run, ctl: RunControl, height: float) -> ActionResult:
        v, s = self.v, self.s
        with v.cond:
            if v.origin is None:
                raise Failed("no LOCAL_POSITION_NED from the vehicle yet")
            x, y, _ = v.mission_position()
            v.commanded = (x, y, height)
            v.flown = True
            target_ned = mission_to_ned(v.commanded, v.origin)
        v.autopilot.takeoff(ctl, target_ned, height)
        modes = v.autopilot.takeoff_modes()
        self.waiter.confirm_modes(run, modes, done=lambda st: False)

        def arrived(st: LinkState) -> bool:
            # Vertical only: a real take-off may drift a little sideways.
            return v.settled(st, (x, y, height), vertical=True)

        self.waiter.wait(
            run,
            arrived,
            run.started + s.scaled(s.action_timeout_s),
            self.waiter.timeout_reason("take-off height not reached"),
            guard=self.waiter.guard(modes),
        )
        return ActionResult("ok")

    def land(self, run: Run, ctl: RunControl) -> ActionResult:
        """MAV_CMD_NAV_LAND; done on the ground (or disarmed)."""
        v = self.v
        with v.cond:
            if v.on_ground(v.state):
                return ActionResult("ok")
        # LAND brakes gently (ArduCopter touched down 10 m, PX4 14 m past the point
        # where LAND was sent at full speed): come to rest first.
        self.brake(run, ctl)
        with v.cond:
            here = v.here_ned()
        v.autopilot.land(ctl, here)
        with v.cond:
            v.guided_target = None
        modes = frozenset({v.autopilot.land_mode})
        self.waiter.confirm_modes(run, modes, done=v.landed)
        self.waiter.wait(
            run,
            v.landed,
            run.started + self.s.scaled(self.s.action_timeout_s),
            self.waiter.timeout_reason("not landed"),
            guard=self.waiter.guard(modes, need_armed=False, unless=v.landed),
        )
        return ActionResult("ok")

    def move(self, run: Run, ctl: RunControl, command: FlyBy | FlyToXYZ | FlyToLLA) -> ActionResult:
        """FlyByX/Y/Z, FlyToXYZ, FlyToLLA: go there, done within tolerance and slow."""
        v, s = self.v, self.s
        with v.cond:
            if not v.state.armed:
                raise Failed("not armed")
            if v.on_ground(v.state) or v.origin is None:
                raise Failed("not flying")
            lla: tuple[float, float, float] | None = None
            relative = target_xyz(command, v.base_point())
            if relative is not None:
                target = relative
            elif isinstance(command, FlyToLLA):
                if v.geo is None:
                    raise Failed(
                        "no GLOBAL_POSITION_INT from the vehicle: cannot fly to a "
                        "latitude/longitude"
                    )
                lla = (command.lat_deg, command.lon_deg, command.alt_m)
                target = v.geo.from_lla(*lla)
            else:
                raise Failed(f"{command.action} has no target")
            if target[2] <= 0:
                raise Failed(f"target z {target[2]:.2f} m is not above ground (use Land)")
            v.commanded = target
            target_ned = mission_to_ned(target, v.origin)
        if lla is not None:
            v.autopilot.goto_global(ctl, lla[0], lla[1], lla[2], target_ned)
        else:
            v.autopilot.goto(ctl, target_ned)
        modes = frozenset({v.autopilot.motion_mode})
        self.waiter.confirm_modes(run, modes, done=lambda st: False)

        def arrived(st: LinkState) -> bool:
            return v.settled(st, target)

        self.waiter.wait(
            run,
            arrived,
            run.started + s.scaled(s.action_timeout_s),
            self.waiter.timeout_reason("target not reached"),
            guard=self.waiter.guard(modes),
        )
        return ActionResult("ok")

    # -- holding and aborting (their own threads) -----------------------------------------

    def start_hold(self, name: str) -> None:
        """Hold where the vehicle is, on a thread (a mode change may take a second).

        Motion actions started later wait for it, so the hold never overrides them.
        """
        thread = threading.Thread(target=self._hold, name=name, daemon=True)
        with self.v.cond:
            # Started under the condition: whoever sees it pending can join it.
            self._pending_hold = thread
            thread.start()

    def await_hold(self) -> None:
        with self.v.cond:
            hold = self._pending_hold
        if hold is not None:
            hold.join(self.s.scaled(self.s.brake_timeout_s) + self.waiter.confirm_s() * 3)

    def brake(self, run: Run, ctl: RunControl) -> None:
        """Stop now if flying (see :func:`brake_to_rest`)."""
        brake_to_rest(self.v, ctl, lambda until, end, why: self.waiter.wait(run, until, end, why))

    def _hold(self) -> None:
        v = self.v
        run = Run(None, None, "internal", time.monotonic())
        ctl = RunControl(self, run)
        try:
            self.brake(run, ctl)
            with v.cond:
                if v.state.local is None:
                    return
                here = v.here_ned()
                airborne = not v.on_ground(v.state)
                v.commanded = v.mission_position() if v.origin else None
            v.autopilot.hold(ctl, here, airborne)
            v.log.info(
                "adapter.hold",
                north_m=round(here[0], 2),
                east_m=round(here[1], 2),
                down_m=round(here[2], 2),
            )
        except (Failed, Ended, CommandRejected) as exc:
            v.log.warning("adapter.hold_failed", error=str(exc))

    def abort(self, why: str = "abort") -> bool:
        """Brake, land (if flying), then disarm and see it in a HEARTBEAT; logs how it
        went as ``adapter.<why>.done`` / ``.failed`` (abort thread, or close)."""
        v = self.v
        run = Run(None, None, "internal", time.monotonic())
        ctl = RunControl(self, run)
        self.await_hold()
        try:
            with v.cond:
                known = v.state.local is not None
                airborne = known and not v.on_ground(v.state)
            if airborne:
                self.brake(run, ctl)
                with v.cond:
                    here = v.here_ned()
                v.autopilot.land(ctl, here)
                with v.cond:
                    v.guided_target = None
                self.waiter.wait(
                    run,
                    v.landed,
                    time.monotonic() + self.s.scaled(self.s.action_timeout_s),
                    self.waiter.timeout_reason("not landed"),
                )
            with v.cond:
                armed = v.state.armed
            if armed:
                ctl.command(MAV_CMD_COMPONENT_ARM_DISARM, DISARM)
            self._confirm_disarmed(run)
            v.log.info(f"adapter.{why}.done")
            return True
        except (Failed, Ended, CommandRejected) as exc:
            v.log.error(f"adapter.{why}.failed", error=str(exc))
            return False


__all__ = ["Ended", "Failed", "Flight", "Run", "RunControl", "TimedOut", "Waiter"]
