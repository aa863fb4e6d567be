"""Flying a MAVLink vehicle to a point: FlyByX/Y/Z, FlyToXYZ and FlyToLLA.

The target is worked out in the mission frame (relative moves add up from the last
commanded point, :meth:`~eamos.hal.mavlink.vehicle.MavlinkVehicle.base_point`; a
latitude/longitude goes through the vehicle's home in WGS84), sent the autopilot's way
(:meth:`~eamos.hal.mavlink.autopilots.Autopilot.goto`), and the move completes when the
vehicle is within tolerance of it and at rest over a settle window that began after the
command (:mod:`~eamos.hal.mavlink.completion`: the tolerance scaled for short moves).
"""

from __future__ import annotations

import time

from eamos.hal.api import ActionResult
from eamos.hal.mavlink.control import RunControl
from eamos.hal.mavlink.frames import mission_to_ned
from eamos.hal.mavlink.waits import Failed, Run, Waiter
from eamos.program.uniform import FlyBy, FlyToLLA, FlyToXYZ, target_xyz


class Moves:
    """Flying to a point in the mission frame, done within tolerance and at rest."""

    def __init__(self, waiter: Waiter) -> None:
        self.waiter = waiter
        self.v = waiter.v
        self.s = waiter.v.settings

    def fly(self, run: Run, ctl: RunControl, command: FlyBy | FlyToXYZ | FlyToLLA) -> ActionResult:
        """FlyByX/Y/Z, FlyToXYZ, FlyToLLA: go there, done within tolerance and slow."""
        v, s = self.v, self.s
        with v.cond:
            if not v.state.armed:
                raise Failed("not armed")
            if v.on_ground(v.state) or v.origin is None:
                raise Failed("not flying")
            lla: tuple[float, float, float] | None = None
            start = v.base_point()
            relative = target_xyz(command, start)
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
            v.geofence.check_target(target)  # outside the fleet's fence: fail, do not send
            v.commanded = target
            target_ned = mission_to_ned(target, v.origin)
        arrival = v.settling.arrival(start, target, time.monotonic())
        if lla is not None:
            v.autopilot.goto_global(ctl, lla[0], lla[1], lla[2], target_ned)
        else:
            v.autopilot.goto(ctl, target_ned)
        modes = frozenset({v.autopilot.motion_mode})
        self.waiter.confirm_modes(run, modes, done=lambda st: False)

        self.waiter.wait(
            run,
            lambda st: v.settling.arrived(st, arrival),
            run.started + s.scaled(s.action_timeout_s),
            self.waiter.timeout_reason("target not reached"),
            guard=self.waiter.guard(modes),
        )
        v.settling.log_arrival(command.action, arrival)
        return ActionResult("ok")


__all__ = ["Moves"]
