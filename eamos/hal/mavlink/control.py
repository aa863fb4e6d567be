"""A running action's hold on the vehicle: the autopilots' :class:`Controller`, bound to one run.

An :class:`~eamos.hal.mavlink.autopilots.Autopilot` turns a flight step into calls on a
:class:`~eamos.hal.mavlink.autopilots.Controller`; :class:`RunControl` carries them out for
one :class:`~eamos.hal.mavlink.waits.Run` (commands and their acknowledgement, mode
changes confirmed by a HEARTBEAT, setpoint streams and position targets), so every step
stops when the run is over and a cancel's hold has the last word.
"""

from __future__ import annotations

import time
from collections.abc import Callable

from eamos.hal.mavlink.autopilots import CommandRejected
from eamos.hal.mavlink.command_protocol import MAV_RESULT_ACCEPTED
from eamos.hal.mavlink.frames import Vector
from eamos.hal.mavlink.state import result_name
from eamos.hal.mavlink.targets import CirclePath
from eamos.hal.mavlink.waits import Failed, Run, Waiter

MAV_CMD_DO_SET_MODE = 176
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

    def __init__(self, waiter: Waiter, run: Run) -> None:
        self.waiter = waiter
        self.v = waiter.v
        self.run = run

    def mode(self) -> str:
        with self.v.cond:
            return self.v.mode_name()

    def command(self, command: int, params: tuple[float, ...], frame: int | None = None) -> None:
        v, run, s = self.v, self.run, self.v.settings
        # A mode change nobody explained yet may be a pilot's: know before commanding.
        self.waiter.settle_mode(run)
        with v.cmd_lock:
            with v.cond:
                self.waiter.raise_if_over(run)
                v.takeover.expect_command(command, time.monotonic())
                text_seen = v.state.statustext_serial
            result = v.commands.request(
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
        with self.v.cond:
            # Ours, when the HEARTBEAT shows it (a mode nobody asked for is a pilot's).
            self.v.takeover.expect({mode}, time.monotonic())
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
            if target_ned is not None and v.stream_target is None and v.path is None:
                v.stream_since = time.monotonic()
            v.stream_target = target_ned
            v.path = None
        if target_ned is not None:
            v.send_setpoint(target_ned)  # at once, not at the next tick

    def set_yaw(self, heading_deg: float) -> None:
        with self.v.cond:
            self.v.stream_yaw = heading_deg

    def follow(self, path: CirclePath, flown: Callable[[], float]) -> None:
        """Stream ``path`` (both autopilots, in the motion mode) instead of a target;
        ``flown()`` (condition held) says how far round the vehicle has got."""
        v = self.v
        with v.cmd_lock, v.cond:
            self.waiter.raise_if_over(self.run)
            v.path, v.path_flown = path, flown
            v.stream_target = None
            v.guided_target = None
        v.send_path_point(path)  # at once, not at the next tick

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
            v.path = None
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


__all__ = ["COMMAND_NAMES", "RunControl"]
