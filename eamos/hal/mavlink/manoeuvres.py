"""ReturnHome, Hold, Yaw, SetSpeed and Orbit on a MAVLink autopilot.

=========== ============================================ ===========================================
action      PX4                                          ArduCopter
=========== ============================================ ===========================================
ReturnHome  OFFBOARD back above home at the current     GUIDED back above home at the current
            height, then Land (AUTO.LAND), it disarms    height, then Land (LAND), it disarms
Hold        OFFBOARD, the setpoint stream at the point   GUIDED, a position target at the point
            where the drone is meant to be               where the drone is meant to be
Yaw         every setpoint from then on carries the yaw  every GUIDED target from then on carries
                                                         the yaw
SetSpeed    MPC_XY_VEL_MAX and MPC_XY_CRUISE (DO_CHANGE_ WPNAV_SPEED (cm/s), and in GUIDED
            SPEED is ignored in OFFBOARD)                MAV_CMD_DO_CHANGE_SPEED (lasts until the
                                                         next mode change)
Orbit       OFFBOARD, a streamed path round the centre   GUIDED, the same streamed path
            (position, velocity, nose to the centre)
=========== ============================================ ===========================================

Hold and Orbit stay in the mode where the adapter steers, with targets it streams:
ArduCopter's LOITER and CIRCLE take their climb rate from the RC throttle and, without
a transmitter (a SITL, a companion-only vehicle), descended into the ground at 2.5 m/s
(the notes); PX4's HOLD and ORBIT would do no harm, but one way for both is simpler to
test.  ReturnHome flies home the same way and lands there: RTL climbs to its own return
altitude unless a parameter says otherwise (PX4 60 m), and a parameter the vehicle
refuses (PX4 main echoed no RTL_RETURN_ALT) must not send a drone up there.  Yaw
travels inside the targets: ArduCopter resets its yaw mode on every GUIDED
target that ignores yaw, which cancelled a MAV_CMD_CONDITION_YAW heading within a second.

Every parameter changed is put back at close (:class:`~eamos.hal.mavlink.keeper.ParamKeeper`).
Completion is read from telemetry: ReturnHome when the vehicle is landed and
disarmed; Yaw when ATTITUDE's heading is within :data:`YAW_TOLERANCE_DEG`; Orbit
when the angle flown around the centre (unwrapped from LOCAL_POSITION_NED)
reaches ``turns`` full circles, after which the vehicle flies back to where it
started and settles there.
"""

from __future__ import annotations

import math
import time

from eamos.hal.api import ActionResult
from eamos.hal.mavlink.control import RunControl
from eamos.hal.mavlink.flight import Flight
from eamos.hal.mavlink.frames import mission_to_ned
from eamos.hal.mavlink.link import LinkState
from eamos.hal.mavlink.targets import CirclePath
from eamos.hal.mavlink.waits import Failed, Run
from eamos.program.uniform import Hold, Orbit, ReturnHome, SetSpeed, Yaw

#: The commands :func:`perform_manoeuvre` runs.
MANOEUVRES = (ReturnHome, Hold, Yaw, SetSpeed, Orbit)

MAV_CMD_DO_CHANGE_SPEED = 178
#: A Yaw is done within this many degrees of the heading.
YAW_TOLERANCE_DEG = 2.0
#: Orbits fly at most this centripetal acceleration (m/s/s): v <= sqrt(a r).
ORBIT_ACCEL_MPS2 = 2.0
#: After landing at home, the autopilot disarms within this long (vehicle seconds).
DISARM_AFTER_LANDING_S = 10.0


def heading_error_deg(heading: float, target: float) -> float:
    """The shortest signed turn from ``heading`` to ``target`` (degrees, pure)."""
    return (target - heading + 180.0) % 360.0 - 180.0


def orbit_centre(
    start: tuple[float, float, float], heading_deg: float, radius_m: float
) -> tuple[float, float]:
    """The point ``radius_m`` ahead of ``start`` along the compass heading (mission x, y)."""
    h = math.radians(heading_deg)
    return start[0] + radius_m * math.cos(h), start[1] + radius_m * math.sin(h)


def orbit_speed_mps(speed_mps: float, radius_m: float) -> float:
    """The speed an orbit of ``radius_m`` flies at (capped by :data:`ORBIT_ACCEL_MPS2`)."""
    return min(speed_mps, math.sqrt(ORBIT_ACCEL_MPS2 * radius_m))


class AngleFlown:
    """The clockwise angle (radians) flown around a centre, unwrapped sample by sample."""

    def __init__(self, cx: float, cy: float) -> None:
        self.cx, self.cy = cx, cy
        self.total = 0.0
        self._last: float | None = None

    def add(self, x: float, y: float) -> float:
        """Fold in one position (mission x north, y east); the total so far."""
        bearing = math.atan2(y - self.cy, x - self.cx)  # grows clockwise seen from above
        if self._last is not None:
            self.total += math.remainder(bearing - self._last, 2 * math.pi)
        self._last = bearing
        return self.total


def perform_manoeuvre(flight: Flight, run: Run) -> ActionResult:
    """Run ReturnHome, Hold, Yaw, SetSpeed or Orbit to its end (see module docstring);
    raises like :meth:`~eamos.hal.mavlink.flight.Flight.perform`."""
    command = run.command
    assert command is not None
    ctl = RunControl(flight.waiter, run)
    with flight.v.cond:
        flight.waiter.raise_if_over(run)
    flight.brakes.await_hold()  # a cancel's brake and hold finish first
    if isinstance(command, SetSpeed):
        return set_speed(flight, ctl, command.speed_m_s)
    _need_flying(flight)
    if isinstance(command, ReturnHome):
        return return_home(flight, run, ctl)
    if isinstance(command, Hold):
        return hold(flight, run, ctl, command.duration_s)
    if isinstance(command, Yaw):
        return yaw(flight, run, ctl, command.heading_deg)
    if isinstance(command, Orbit):
        return orbit(flight, run, ctl, command.radius_m, command.turns)
    raise Failed(f"{command.action} is not an action this vehicle flies")


def _need_flying(flight: Flight) -> None:
    v = flight.v
    with v.cond:
        if not v.state.armed:
            raise Failed("not armed")
        if v.on_ground(v.state) or v.origin is None:
            raise Failed("not flying")


def _set(flight: Flight, name: str, value: float) -> None:
    if not flight.v.keeper.set_param(name, value):
        raise Failed(f"the vehicle did not take parameter {name} = {value:g}")


def return_home(flight: Flight, run: Run, ctl: RunControl) -> ActionResult:
    """Back above home at the current height, land there and disarm (steered by the
    adapter in GUIDED / OFFBOARD, then the autopilot's LAND)."""
    v, s, waiter = flight.v, flight.s, flight.waiter
    flight.brakes.brake(run, ctl)  # at rest first
    with v.cond:
        here = v.mission_position()
        home = (0.0, 0.0, here[2])
        v.commanded = home
        arrival = v.settling.arrival(here, home, time.monotonic())
        assert v.origin is not None
        home_ned = mission_to_ned(home, v.origin)
    v.autopilot.goto(ctl, home_ned)
    modes = frozenset({v.autopilot.motion_mode})
    waiter.confirm_modes(run, modes, done=lambda st: False)
    waiter.wait(
        run,
        lambda st: v.settling.arrived(st, arrival),
        run.started + s.scaled(s.action_timeout_s),
        waiter.timeout_reason("not back above home"),
        guard=waiter.guard(modes),
    )
    flight.landing.land(run, ctl)
    waiter.wait(
        run,
        lambda st: not st.armed,
        time.monotonic() + s.scaled(DISARM_AFTER_LANDING_S) + waiter.confirm_s(),
        lambda st: "landed at home but the vehicle did not disarm",
    )
    with v.cond:
        v.stop_steering()
        v.commanded = None
        flight.arming.armed_by_us = False
    return ActionResult("ok")


def _stay(flight: Flight, ctl: RunControl) -> frozenset[str]:
    """Fly to (stay at) the point where the drone is meant to be, in the motion mode; the
    modes the action must stay in."""
    v = flight.v
    with v.cond:
        here = v.base_point()
        v.commanded = here
        assert v.origin is not None
        here_ned = mission_to_ned(here, v.origin)
    v.autopilot.goto(ctl, here_ned)
    modes = frozenset({v.autopilot.motion_mode})
    flight.waiter.confirm_modes(ctl.run, modes, done=lambda st: False)
    return modes


def hold(flight: Flight, run: Run, ctl: RunControl, duration_s: float) -> ActionResult:
    """Hover where the drone is meant to be for ``duration_s`` (GUIDED / OFFBOARD)."""
    s, waiter = flight.s, flight.waiter
    if duration_s < 0:
        raise Failed("duration_s must be >= 0")
    modes = _stay(flight, ctl)
    waiter.wait(
        run,
        lambda st: False,
        run.started + s.scaled(duration_s),
        lambda st: "",
        guard=waiter.guard(modes),
        quiet_timeout=True,
    )
    return ActionResult("ok")


def yaw(flight: Flight, run: Run, ctl: RunControl, heading_deg: float) -> ActionResult:
    """Turn on the spot to ``heading_deg`` (kept by every later target); done when
    ATTITUDE shows it."""
    s, waiter = flight.s, flight.waiter
    target = heading_deg % 360.0
    ctl.set_yaw(target)
    modes = _stay(flight, ctl)

    def turned(st: LinkState) -> bool:
        return (
            st.heading_deg is not None
            and abs(heading_error_deg(st.heading_deg, target)) <= YAW_TOLERANCE_DEG
        )

    waiter.wait(
        run,
        turned,
        run.started + s.scaled(s.action_timeout_s),
        lambda st: (
            f"timeout after {s.action_timeout_s:g} s: heading {st.heading_deg} not "
            f"{target:g} (no ATTITUDE?)"
        ),
        guard=waiter.guard(modes),
    )
    return ActionResult("ok")


def set_speed(flight: Flight, ctl: RunControl, speed_mps: float) -> ActionResult:
    """Fly later horizontal moves at ``speed_mps`` (parameters, restored at close)."""
    v = flight.v
    if not speed_mps > 0:
        raise Failed("speed_m_s must be > 0")
    for name, value in v.autopilot.speed_params(speed_mps):
        _set(flight, name, value)
    if v.autopilot.name == "ardupilot" and ctl.mode() == "GUIDED":
        # Effective at once, mid-flight: param1 1 = ground speed, param3 -1: throttle as is.
        ctl.command(MAV_CMD_DO_CHANGE_SPEED, (1.0, speed_mps, -1.0, 0.0, 0.0, 0.0, 0.0))
    with v.cond:
        v.horizontal_speed_mps = speed_mps
    return ActionResult("ok")


def orbit(flight: Flight, run: Run, ctl: RunControl, radius_m: float, turns: float) -> ActionResult:
    """Circle ``turns`` times clockwise around the point ``radius_m`` ahead, the nose to the
    centre (a streamed path, :class:`~eamos.hal.mavlink.targets.CirclePath`), then back
    at the start."""
    v, s, waiter = flight.v, flight.s, flight.waiter
    if not radius_m > 0 or not turns > 0:
        raise Failed("radius_m and turns must be > 0")
    with v.cond:
        heading = v.state.heading_deg
        if heading is None:
            raise Failed("no ATTITUDE from the vehicle: its heading (and so the centre) unknown")
        start = v.base_point()
        cx, cy = orbit_centre(start, heading, radius_m)
        speed = orbit_speed_mps(v.horizontal_speed_mps, radius_m)
        assert v.origin is not None
        centre_ned = mission_to_ned((cx, cy, start[2]), v.origin)
    # The nose to the centre: at the start that is the heading the vehicle has now.
    ctl.set_yaw(heading)
    modes = _stay(flight, ctl)
    goal = turns * 2 * math.pi
    path = CirclePath(
        centre_ned[0],
        centre_ned[1],
        centre_ned[2],
        radius_m,
        speed,
        math.radians(heading + 180.0),
        goal,
    )
    flown = AngleFlown(cx, cy)
    ctl.follow(path, lambda: flown.total)
    # The path ends at the start and the vehicle follows it from behind: the angle it
    # flew approaches the goal from below; within the position tolerance is round.
    round_enough = goal - v.settling.tolerance_m / radius_m

    def around(st: LinkState) -> bool:
        if st.local is None:
            return False
        x, y, _ = v.mission_position(st)
        return flown.add(x, y) >= round_enough

    lap_s = 2 * math.pi * radius_m / speed
    waiter.wait(
        run,
        around,
        time.monotonic() + s.scaled(s.action_timeout_s + 2 * turns * lap_s),
        lambda st: f"orbit not finished: {math.degrees(flown.total):.0f} of {turns * 360:g} deg",
        guard=waiter.guard(modes),
    )
    # Back to where it started (the path ends there too), settled there.
    with v.cond:
        v.commanded = start
        arrival = v.settling.arrival(v.mission_position(), start, time.monotonic())
        assert v.origin is not None
        start_ned = mission_to_ned(start, v.origin)
    v.autopilot.goto(ctl, start_ned)
    waiter.wait(
        run,
        lambda st: v.settling.arrived(st, arrival),
        time.monotonic() + s.scaled(s.action_timeout_s),
        waiter.timeout_reason("orbit's start point not reached again"),
        guard=waiter.guard(modes),
    )
    return ActionResult("ok")


__all__ = [
    "MANOEUVRES",
    "AngleFlown",
    "heading_error_deg",
    "orbit_centre",
    "orbit_speed_mps",
    "perform_manoeuvre",
]
