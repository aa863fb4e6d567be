"""Stopping a MAVLink vehicle now, and waiting until it is at rest (cancel, Land, abort).

A position target at the current spot does not stop a fast vehicle (ArduCopter
overshot 9.4 m at 5 m/s, braking at WPNAV_ACCEL), and LAND brakes gently (10 m
on ArduCopter, 14 m on PX4).  :func:`brake_to_rest` asks the autopilot for its
fastest documented stop (:meth:`~eamos.hal.mavlink.autopilots.Autopilot.brake`:
PX4 a zero-velocity setpoint, ArduPilot BRAKE mode) and waits on the vehicle's
condition until the settle window shows it at rest.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable

from eamos.hal.mavlink.autopilots import Controller
from eamos.hal.mavlink.state import LinkState
from eamos.hal.mavlink.vehicle import MavlinkVehicle

#: ``wait(until, deadline, timeout_reason)``: the running action's wait (flight.Waiter).
Wait = Callable[[Callable[[LinkState], bool], float, Callable[[LinkState], str]], None]


def brake_to_rest(v: MavlinkVehicle, ctl: Controller, wait: Wait) -> None:
    """Stop now if flying faster than the settle speed: the autopilot's fastest stop
    (PX4: a zero-velocity setpoint; ArduPilot: BRAKE mode), then wait
    (``brake_timeout_s``) until the vehicle is at rest over the settle window."""
    with v.cond:
        st = v.state
        if st.local is None or v.on_ground(st) or v.speed(st) <= v.settle_speed_mps:
            return
        speed, position = v.speed(st), v.mission_position()
    t0 = time.monotonic()
    braking = v.autopilot.brake(ctl)
    v.log.info(
        "adapter.brake",
        braking=braking,
        speed_mps=round(speed, 2),
        x_m=round(position[0], 2),
        y_m=round(position[1], 2),
        z_m=round(position[2], 2),
        send_s=round(time.monotonic() - t0, 3),
    )
    wait(
        lambda st: v.settled(st),
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
        duration_s=round(time.monotonic() - t0, 3),
    )


__all__ = ["brake_to_rest"]
