"""Bringing a MAVLink vehicle down: Land, an abort's landing, and a vehicle still flying at close.

Land comes to rest first (:class:`~eamos.hal.mavlink.braking.Brakes`: LAND alone brakes
gently, metres past the point), then lands the autopilot's way and is done on the
ground or disarmed.  An abort (and an adapter closed while the vehicle flies) also
disarms and sees it in a HEARTBEAT; when it cannot land the vehicle, it says so
(``adapter.stranded``, at error level): a drone is never left in the air silently.
"""

from __future__ import annotations

import time

from eamos.hal.api import ActionResult
from eamos.hal.mavlink.arming import DISARM, MAV_CMD_COMPONENT_ARM_DISARM, Arming
from eamos.hal.mavlink.autopilots import CommandRejected
from eamos.hal.mavlink.braking import Brakes
from eamos.hal.mavlink.control import RunControl
from eamos.hal.mavlink.waits import Ended, Failed, Run, TimedOut, Waiter

#: How many times Land sends LAND again after a failsafe held the vehicle where it was
#: (a vehicle touching down on a geofence's line, its estimate wandering across it, is
#: held again each time the estimate is outside).
LAND_RESUMES = 3
#: Modes in which the vehicle lands or returns by itself (either autopilot's names): a
#: failsafe that chose one of them is left alone.
LANDING_MODES = frozenset({"LAND", "RTL", "SMART_RTL", "AUTO.LAND", "AUTO.RTL", "AUTO.PRECLAND"})


class Landing:
    """Landing the vehicle where it is: the Land action, an abort, and landing at close."""

    def __init__(self, waiter: Waiter, brakes: Brakes, arming: Arming) -> None:
        self.waiter = waiter
        self.brakes = brakes
        self.arming = arming
        self.v = waiter.v
        self.s = waiter.v.settings

    def land(self, run: Run, ctl: RunControl) -> ActionResult:
        """MAV_CMD_NAV_LAND; done on the ground (or disarmed)."""
        v = self.v
        with v.cond:
            if v.on_ground(v.state):
                return ActionResult("ok")
        # LAND brakes gently (ArduCopter touched down 10 m, PX4 14 m past the point
        # where LAND was sent at full speed): come to rest first.
        self.brakes.brake(run, ctl)
        with v.cond:
            here = v.here_ned()
        v.autopilot.land(ctl, here)
        with v.cond:
            v.guided_target = None
        modes = frozenset({v.autopilot.land_mode})
        self.waiter.confirm_modes(run, modes, done=v.landed)
        resumes = 0
        while True:
            try:
                self.waiter.wait(
                    run,
                    v.landed,
                    run.started + self.s.scaled(self.s.action_timeout_s),
                    self.waiter.timeout_reason("not landed"),
                    guard=self.waiter.guard(modes, need_armed=False, unless=v.landed),
                )
                return ActionResult("ok")
            except TimedOut:
                raise
            except Failed as exc:
                held = self._held_by_failsafe()
                if held is None or resumes == LAND_RESUMES:
                    raise
                resumes += 1
                v.log.warning("adapter.land.resumed", failsafe=held, after=str(exc))
                with v.cond:
                    here = v.here_ned()
                v.autopilot.land(ctl, here)
                self.waiter.confirm_modes(run, modes, done=v.landed)

    def _held_by_failsafe(self) -> str | None:
        """The failsafe that stopped a landing where it was (HOLD, BRAKE, LOITER: PX4's
        geofence holds a vehicle that touches down on the fence's line), or None when
        a pilot has it, the vehicle disarmed, or the failsafe lands or returns it."""
        v = self.v
        with v.cond:
            failsafe = v.takeover.failsafe
            mode = v.mode_name(v.state)
            if (
                v.taken_over is not None
                or failsafe is None
                or failsafe.mode != mode
                or mode in LANDING_MODES
                or not v.state.armed
                or not v.state.link_ok
            ):
                return None
            return failsafe.why or mode

    def land_and_disarm(self, why: str = "abort") -> bool:
        """Brake, land (if flying), then disarm and see it in a HEARTBEAT; logs how it
        went as ``adapter.<why>.done`` / ``.failed`` (abort thread, or close)."""
        v = self.v
        run = Run(None, None, "internal", time.monotonic())
        ctl = RunControl(self.waiter, run)
        self.brakes.await_hold()
        try:
            with v.cond:
                known = v.state.local is not None
                airborne = known and not v.on_ground(v.state)
            if airborne:
                self.brakes.brake(run, ctl)
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
            self.arming.confirm_disarmed(run)
            v.log.info(f"adapter.{why}.done")
            return True
        except (Failed, Ended, CommandRejected) as exc:
            v.log.error(f"adapter.{why}.failed", error=str(exc))
            return False

    def disarm_at_close(self) -> None:
        """A vehicle armed on the ground at close is disarmed, seen in a HEARTBEAT
        (``adapter.close_disarm``); when it will not, ``adapter.armed_at_close`` says so at
        error level.  It is never sent LAND: ArduCopter, told to land on the ground, stays
        armed in LAND and never reports landed (the notes)."""
        v = self.v
        run = Run(None, None, "internal", time.monotonic())
        ctl = RunControl(self.waiter, run)
        v.log.info("adapter.close_disarm", note="armed on the ground at close: disarming")
        try:
            with v.cond:
                armed = v.state.armed
            if armed:
                ctl.command(MAV_CMD_COMPONENT_ARM_DISARM, DISARM)
            self.arming.confirm_disarmed(run)
        except (Failed, Ended, CommandRejected) as exc:
            with v.cond:
                armed = v.state.armed
            if armed:
                v.log.error("adapter.armed_at_close", reason=str(exc))

    def land_at_close(self) -> None:
        """Never leave a flying vehicle silently at close: land it (``land_on_close``), or
        log ``adapter.stranded`` at error level with where it was left and why; a vehicle
        armed on the ground is disarmed (:meth:`disarm_at_close`)."""
        v = self.v
        with v.cond:
            st = v.state
            known = st.local is not None
            flying = known and st.armed and not v.on_ground(st)
            armed_on_ground = known and st.armed and not flying
            link_ok = st.link_ok
            where = v.mission_position() if known and v.origin else None
        if armed_on_ground and link_ok:
            self.disarm_at_close()
        if not flying:
            return
        why = ""
        if not link_ok:
            why = "link lost: no HEARTBEAT from the vehicle"
        elif not self.s.land_on_close:
            why = "hal.land_on_close = false"
        else:
            v.log.warning("adapter.close_land", note="vehicle still flying at close: landing")
            if self.land_and_disarm("close_land"):
                return
            why = "landing at close failed (see adapter.close_land.failed)"
        with v.cond:
            armed = v.state.armed
            if v.state.local is not None and v.origin is not None:
                where = v.mission_position()
        v.log.error(
            "adapter.stranded",
            reason=why,
            armed=armed,
            x_m=None if where is None else round(where[0], 2),
            y_m=None if where is None else round(where[1], 2),
            z_m=None if where is None else round(where[2], 2),
        )


__all__ = ["Landing"]
