"""The MAVLink adapter's flight procedures: one uniform action, from command to real completion.

:class:`Flight` runs each action on the caller's thread (the adapter gives
every action a thread of its own) and returns its :class:`ActionResult` or
raises why it failed.  Every wait (:class:`~eamos.hal.mavlink.waits.Waiter`) is
``Condition.wait_for`` on the vehicle's condition against a ``time.monotonic()``
deadline, and ends early when the action is finished by someone else (cancel,
abort, close), when HEARTBEATs stop, or when a guard sees that someone else took
the vehicle over.

Each phase of a flight is a class of its own, in the module of that phase:
:class:`~eamos.hal.mavlink.arming.Arming` (Arm, Disarm, re-arming),
:class:`~eamos.hal.mavlink.takeoff.TakeOff`, :class:`~eamos.hal.mavlink.moves.Moves`
(FlyBy*, FlyTo*), :class:`~eamos.hal.mavlink.landing.Landing` (Land, an abort's landing,
landing at close) and :class:`~eamos.hal.mavlink.braking.Brakes` (stop now, hold after a
cancel).  ReturnHome, Hold, Yaw, SetSpeed and Orbit are in
:mod:`eamos.hal.mavlink.manoeuvres`, plugin actions in :mod:`eamos.hal.mavlink.payload`.

What differs between PX4 and ArduPilot is asked of the vehicle's
:class:`~eamos.hal.mavlink.autopilots.Autopilot`, through a
:class:`~eamos.hal.mavlink.control.RunControl`: the
:class:`~eamos.hal.mavlink.autopilots.Controller` bound to one running action.
"""

from __future__ import annotations

from eamos.hal.api import ActionResult
from eamos.hal.mavlink.arming import Arming
from eamos.hal.mavlink.braking import Brakes
from eamos.hal.mavlink.control import RunControl
from eamos.hal.mavlink.landing import Landing
from eamos.hal.mavlink.moves import Moves
from eamos.hal.mavlink.takeoff import TakeOff
from eamos.hal.mavlink.vehicle import MavlinkVehicle
from eamos.hal.mavlink.waits import Failed, Run, Waiter
from eamos.program.uniform import Arm, Disarm, FlyBy, FlyToLLA, FlyToXYZ, Land, PauseFor, Takeoff


class Flight:
    """One vehicle's flight phases, and which of them flies a command (module docstring)."""

    def __init__(self, vehicle: MavlinkVehicle) -> None:
        self.v = vehicle
        self.s = vehicle.settings
        self.waiter = Waiter(vehicle)
        self.brakes = Brakes(self.waiter)
        self.arming = Arming(self.waiter)
        self.takeoff = TakeOff(self.waiter, self.arming)
        self.moves = Moves(self.waiter)
        self.landing = Landing(self.waiter, self.brakes, self.arming)

    def perform(self, run: Run) -> ActionResult:
        """Run one action to its end: its result, or Failed/TimedOut/Ended/CommandRejected."""
        command = run.command
        assert command is not None
        ctl = RunControl(self.waiter, run)
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
                return self.arming.arm(run, ctl)
            case Disarm():
                return self.arming.disarm(run, ctl)
            case Takeoff(height_m=height):
                self.brakes.await_hold()
                return self.takeoff.fly(run, ctl, height)
            case Land():
                self.brakes.await_hold()
                return self.landing.land(run, ctl)
            case FlyBy() | FlyToXYZ() | FlyToLLA():
                self.brakes.await_hold()
                return self.moves.fly(run, ctl, command)
        raise Failed(f"{command.action} is not an action this vehicle flies")


__all__ = ["Flight"]
