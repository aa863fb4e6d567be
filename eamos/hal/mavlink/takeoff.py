"""Taking off on a MAVLink vehicle: from the ground to a height above it, at the same X/Y.

What each autopilot sends is :meth:`~eamos.hal.mavlink.autopilots.Autopilot.takeoff`'s
business (PX4: a setpoint above the ground in OFFBOARD, or AUTO.TAKEOFF; ArduPilot:
MAV_CMD_NAV_TAKEOFF in GUIDED); :class:`TakeOff` re-arms a vehicle that disarmed itself
while the mission kept it waiting, then waits until the height is reached and held.
"""

from __future__ import annotations

import time

from eamos.hal.api import ActionResult
from eamos.hal.mavlink.arming import Arming, disarmed_on_ground
from eamos.hal.mavlink.autopilots import CommandRejected
from eamos.hal.mavlink.control import RunControl
from eamos.hal.mavlink.frames import mission_to_ned
from eamos.hal.mavlink.waits import Failed, Run, Waiter


class TakeOff:
    """Climbing to a height above the take-off ground (re-arming once if need be)."""

    def __init__(self, waiter: Waiter, arming: Arming) -> None:
        self.waiter = waiter
        self.arming = arming
        self.v = waiter.v
        self.s = waiter.v.settings

    def fly(self, run: Run, ctl: RunControl, height: float) -> ActionResult:
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
                rearm = not st.armed and self.arming.armed_by_us and self.s.rearm
                if not st.armed and not rearm:
                    raise Failed("not armed")
            if rearm:
                self.arming.rearm(run, ctl)
            try:
                return self._climb(run, ctl, height)
            except (Failed, CommandRejected):  # ArduCopter: NAV_TAKEOFF FAILED when disarmed
                again = self.arming.armed_by_us and self.s.rearm and not attempt
                if not again or not disarmed_on_ground(self.waiter, self.v, run):
                    raise
        raise AssertionError("unreachable")

    def _climb(self, run: Run, ctl: RunControl, height: float) -> ActionResult:
        v, s = self.v, self.s
        with v.cond:
            if v.origin is None:
                raise Failed("no LOCAL_POSITION_NED from the vehicle yet")
            x, y, z = v.mission_position()
            v.commanded = (x, y, height)
            v.flown = True
            target_ned = mission_to_ned(v.commanded, v.origin)
        # Vertical only: a real take-off may drift a little sideways.
        arrival = v.settling.arrival((x, y, z), (x, y, height), time.monotonic(), vertical=True)
        v.autopilot.takeoff(ctl, target_ned, height)
        modes = v.autopilot.takeoff_modes()
        self.waiter.confirm_modes(run, modes, done=lambda st: False)

        self.waiter.wait(
            run,
            lambda st: v.settling.arrived(st, arrival),
            run.started + s.scaled(s.action_timeout_s),
            self.waiter.timeout_reason("take-off height not reached"),
            guard=self.waiter.guard(modes),
        )
        v.settling.log_arrival("Takeoff", arrival)
        return ActionResult("ok")


__all__ = ["TakeOff"]
