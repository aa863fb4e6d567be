"""Stopping a MAVLink vehicle now, waiting until it is at rest, and holding there.

A position target at the current spot does not stop a fast vehicle well (ArduCopter
overshot 9.4 m at 5 m/s and came back), LAND brakes gently (10 m on ArduCopter, 14 m on
PX4), ArduCopter's BRAKE mode decelerates at only ~0.7 m/s/s (3.4 m from 2 m/s) and a
zero-velocity target is no better (1.8 m on ArduCopter, 5.6 m on PX4: both measured on
the SITLs).  What stops both soonest is a position target where the vehicle comes to
rest when it brakes at its own acceleration limit (:func:`stopping_point`): 0.9 m
(ArduCopter) and 0.7 m (PX4) from 2 m/s.  :func:`brake_to_rest` sends that
(:meth:`~eamos.hal.mavlink.autopilots.Autopilot.brake`) and waits on the vehicle's
condition until the settle window shows it at rest.  :class:`Brakes` does that for a
cancel (then holds where the vehicle came to rest, on a thread of its own), for Land
and for an abort.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable

from eamos.hal.mavlink.autopilots import CommandRejected, Controller
from eamos.hal.mavlink.completion import Arrival
from eamos.hal.mavlink.control import RunControl
from eamos.hal.mavlink.frames import Vector, ned_to_mission
from eamos.hal.mavlink.state import LinkState
from eamos.hal.mavlink.vehicle import MavlinkVehicle
from eamos.hal.mavlink.waits import Ended, Failed, Run, Waiter

#: ``wait(until, deadline, timeout_reason)``: the running action's wait (flight.Waiter).
Wait = Callable[[Callable[[LinkState], bool], float, Callable[[LinkState], str]], None]


def stopping_distance_m(speed_mps: float, decel_mps2: float) -> float:
    """How far a vehicle at ``speed_mps`` flies braking at ``decel_mps2``: v^2 / 2a (pure)."""
    return speed_mps**2 / (2.0 * decel_mps2)


def stopping_point(position_ned: Vector, velocity_ned: Vector, decel_mps2: float) -> Vector:
    """Where a vehicle comes to rest braking horizontally at ``decel_mps2`` (NED; pure)."""
    vn, ve = velocity_ned[0], velocity_ned[1]
    speed = math.hypot(vn, ve)
    if speed == 0:
        return position_ned
    ahead = stopping_distance_m(speed, decel_mps2) / speed
    return (position_ned[0] + vn * ahead, position_ned[1] + ve * ahead, position_ned[2])


def brake_to_rest(v: MavlinkVehicle, ctl: Controller, wait: Wait) -> None:
    """Stop now if flying faster than the settle speed: a position target at the
    stopping point (:func:`stopping_point`), then wait (``brake_timeout_s``) until the
    vehicle is at rest over the settle window."""
    with v.cond:
        st = v.state
        if st.local is None or v.on_ground(st) or v.speed(st) <= v.settling.settle_speed_mps:
            return
        speed, position = v.speed(st), v.mission_position()
        local = st.local
        stop_ned = stopping_point(local[:3], local[3:6], v.autopilot.brake_decel_mps2)
        if v.origin is not None:
            v.commanded = ned_to_mission(stop_ned, v.origin)
    t0 = time.monotonic()
    braking = v.autopilot.brake(ctl, stop_ned)
    v.log.info(
        "adapter.brake",
        braking=braking,
        speed_mps=round(speed, 2),
        x_m=round(position[0], 2),
        y_m=round(position[1], 2),
        z_m=round(position[2], 2),
        send_s=round(time.monotonic() - t0, 3),
    )
    if braking and v.origin is not None:
        # At rest at the stopping point: a vehicle that overshoots it turns round there
        # (ArduCopter's jerk-limited path), and a settle window at that turn is not rest.
        stop = ned_to_mission(stop_ned, v.origin)
        arrival = Arrival(stop, v.settling.tolerance_m, t0)
        until: Callable[[LinkState], bool] = lambda st: v.settling.arrived(st, arrival)  # noqa: E731
    else:
        until = v.settling.settled
    # How far along its way the vehicle got before it came back (it may overshoot).
    vn, ve = local[3], local[4]
    norm = math.hypot(vn, ve) or 1.0
    furthest = [0.0]

    def watched(st: LinkState) -> bool:
        if st.local is not None:
            along = ((st.local[0] - local[0]) * vn + (st.local[1] - local[1]) * ve) / norm
            furthest[0] = max(furthest[0], along)
        return until(st)

    wait(
        watched,
        time.monotonic() + v.settings.scaled(v.settings.brake_timeout_s),
        lambda st: f"vehicle still moving {v.speed(st):.1f} m/s after braking",
    )
    with v.cond:
        rest = v.mission_position()
    v.log.info(
        "adapter.brake.done",
        x_m=round(rest[0], 2),
        y_m=round(rest[1], 2),
        z_m=round(rest[2], 2),
        overshoot_m=round(math.dist(rest, position), 2),
        furthest_m=round(furthest[0], 2),
        duration_s=round(time.monotonic() - t0, 3),
    )


class Brakes:
    """Stopping the vehicle now and holding where it came to rest (cancel, timeout, Land).

    A hold runs on a thread of its own (a mode change may take a second); motion
    actions started later wait for it (:meth:`await_hold`), so it never overrides them.
    """

    def __init__(self, waiter: Waiter) -> None:
        self.waiter = waiter
        self.v = waiter.v
        self.s = waiter.v.settings
        self._pending_hold: threading.Thread | None = None

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
        """Wait for a hold still being set up (a motion action must not race it)."""
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
        ctl = RunControl(self.waiter, run)
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


__all__ = ["Brakes", "brake_to_rest"]
