"""ReturnHome, Hold, Yaw, SetSpeed and Orbit on both autopilots (issues 13 and 27).

Hold, Orbit and ReturnHome stay in the motion mode (GUIDED / OFFBOARD) with targets the
adapter streams, and Yaw travels inside the targets (issue 27: ArduCopter's LOITER and
CIRCLE descended into the ground without RC, RTL climbs to its own altitude, a GUIDED
target that ignores yaw cancelled CONDITION_YAW).

Against the simulated vehicle, which answers the commands and modes each
autopilot really uses (eamos/hal/sitl/manoeuvres.py): the tests check the
commands and their acknowledgements, the modes, the parameters set (and put
back at close), and the vehicle's resulting state (position, heading, landed and
disarmed).
"""

from __future__ import annotations

import json
import math
import threading
from pathlib import Path
from typing import Any

import pytest

from eamos.hal.mavlink.manoeuvres import (
    AngleFlown,
    heading_error_deg,
    orbit_centre,
    orbit_speed_mps,
)
from eamos.hal.sitl import ACCEPTED
from eamos.hal.sitl.manoeuvres import turn_towards

from .test_sim_vehicle_core import Rig, command

pytestmark = [pytest.mark.e2e, pytest.mark.timeout(240)]

AUTOPILOTS = ["px4", "ardupilot"]
RTL, CONDITION_YAW, DO_ORBIT, DO_CHANGE_SPEED = 20, 115, 34, 178
MODES = {
    "px4": {"land": "AUTO.LAND", "motion": "OFFBOARD"},
    "ardupilot": {"land": "LAND", "motion": "GUIDED"},
}
#: Modes that take their climb rate from the RC throttle, or fly on their own rules.
NEVER = {"LOITER", "CIRCLE", "RTL", "HOLD", "ORBIT", "AUTO.RTL", "AUTO.LOITER"}


def vehicle_modes(tmp_path: Path) -> list[str]:
    path = next(tmp_path.glob("vehicle-*.log"))
    events = [json.loads(line) for line in path.read_text().splitlines() if line.strip()]
    return [e["mode"] for e in events if e.get("event") == "vehicle.mode"]


# -- pure parts ----------------------------------------------------------------------------


def test_headings_centres_and_angles() -> None:
    assert heading_error_deg(350.0, 10.0) == pytest.approx(20.0)
    assert heading_error_deg(10.0, 350.0) == pytest.approx(-20.0)
    assert turn_towards(350.0, 10.0, 5.0) == pytest.approx(355.0)
    assert orbit_centre((1.0, 2.0, 3.0), 90.0, 2.0) == pytest.approx((1.0, 4.0))
    assert orbit_speed_mps(5.0, 2.0) == pytest.approx(2.0)  # sqrt(2 m/s/s * 2 m)
    flown = AngleFlown(0.0, 0.0)
    # Clockwise seen from above (north, east, south, west, north): one full turn.
    for x, y in [(1, 0), (0, 1), (-1, 0), (0, -1), (1, 0)]:
        total = flown.add(x, y)
    assert total == pytest.approx(2 * math.pi)


# -- against the simulated vehicle ------------------------------------------------------------


@pytest.mark.parametrize("autopilot", AUTOPILOTS)
def test_return_home_flies_back_lands_and_disarms(
    flight: Any, autopilot: str, tmp_path: Path
) -> None:
    f = flight(autopilot, vehicle={"speedup": 5.0})
    f.airborne(2.0)
    f.ok("FlyToXYZ", 4.0, 3.0, 3.0)
    f.ok("ReturnHome")
    x, y, z = f.vehicle.position
    assert math.hypot(x, y) <= f.adapter.vehicle.settling.tolerance_m, (x, y)
    assert z == pytest.approx(0.0, abs=0.05) and not f.vehicle.armed
    # Flown home by the adapter, then landed: no RTL (its own return altitude).
    assert all(c != RTL for c, _ in f.vehicle.commands)
    modes = vehicle_modes(tmp_path)
    assert MODES[autopilot]["land"] in modes and not NEVER & set(modes), modes


@pytest.mark.parametrize("autopilot", AUTOPILOTS)
def test_hold_hovers_in_the_motion_mode_then_flies_on(
    flight: Any, autopilot: str, tmp_path: Path
) -> None:
    f = flight(autopilot, vehicle={"speedup": 5.0})
    f.airborne(2.0)
    before = f.vehicle.position
    f.ok("Hold", 3.0)
    assert f.vehicle.mode == MODES[autopilot]["motion"]
    assert not NEVER & set(vehicle_modes(tmp_path))
    assert math.dist(f.vehicle.position, before) < 0.3
    f.ok("FlyByX", 1.0)  # back in the motion mode
    assert f.vehicle.mode == MODES[autopilot]["motion"]
    assert f.vehicle.position[0] == pytest.approx(before[0] + 1.0, abs=0.3)


@pytest.mark.parametrize("autopilot", AUTOPILOTS)
def test_yaw_turns_on_the_spot(flight: Any, autopilot: str) -> None:
    f = flight(autopilot, vehicle={"speedup": 5.0})
    f.airborne(2.0)
    before = f.vehicle.position
    f.ok("Yaw", 90.0)
    assert abs(heading_error_deg(f.vehicle.heading_deg, 90.0)) <= 3.0
    assert math.dist(f.vehicle.position, before) < 0.3
    f.ok("Yaw", -45.0)  # 315
    assert abs(heading_error_deg(f.vehicle.heading_deg, 315.0)) <= 3.0
    # The targets carry the yaw on both autopilots; no CONDITION_YAW (ArduCopter's next
    # GUIDED target would cancel it).
    assert all(c != CONDITION_YAW for c, _ in f.vehicle.commands)
    assert f.vehicle.mode == MODES[autopilot]["motion"]


@pytest.mark.parametrize("autopilot", AUTOPILOTS)
def test_set_speed_changes_the_cruise_speed(flight: Any, autopilot: str) -> None:
    f = flight(autopilot, vehicle={"speedup": 4.0}, horizontal_speed_mps=3.0)
    f.airborne(2.0)
    f.ok("SetSpeed", 1.0)
    top = [0.0]
    stop = threading.Event()

    def sample() -> None:
        while not stop.is_set():
            top[0] = max(top[0], f.vehicle.speed_mps)
            stop.wait(0.02)

    watcher = threading.Thread(target=sample, daemon=True)
    watcher.start()
    f.ok("FlyByX", 4.0)
    stop.set()
    watcher.join()
    assert 0.8 <= top[0] <= 1.15, top[0]
    params = f.vehicle.params
    if autopilot == "ardupilot":
        assert params["WPNAV_SPEED"][0] == pytest.approx(100.0)
        assert (DO_CHANGE_SPEED, ACCEPTED) in f.vehicle.commands
    else:
        assert params["MPC_XY_VEL_MAX"][0] == pytest.approx(1.0)
    f.adapter.close()
    if autopilot == "ardupilot":
        assert f.vehicle.params["WPNAV_SPEED"][0] == pytest.approx(500.0)
    else:
        assert f.vehicle.params["MPC_XY_VEL_MAX"][0] == pytest.approx(12.0)


@pytest.mark.parametrize("autopilot", AUTOPILOTS)
def test_orbit_circles_the_point_ahead_and_ends_where_it_started(
    flight: Any, autopilot: str, tmp_path: Path
) -> None:
    f = flight(autopilot, vehicle={"speedup": 5.0})
    f.airborne(2.0)
    start = f.vehicle.position
    seen: list[tuple[float, float, float]] = []
    stop = threading.Event()

    def sample() -> None:
        while not stop.is_set():
            seen.append(f.vehicle.position)
            stop.wait(0.02)

    watcher = threading.Thread(target=sample, daemon=True)
    watcher.start()
    f.ok("Orbit", 2.0, 1.0)
    stop.set()
    watcher.join()
    # Heading north: the centre is 2 m north of the start; the far side 4 m north.
    centre = (start[0] + 2.0, start[1])
    assert max(p[0] for p in seen) - start[0] > 3.5
    assert max(p[1] for p in seen) - start[1] > 1.5  # clockwise: east first...
    assert min(p[1] for p in seen) - start[1] < -1.5  # ...then west
    radii = [math.dist(p[:2], centre) for p in seen if math.dist(p[:2], start[:2]) > 0.5]
    assert min(radii) > 1.3 and max(radii) < 2.7, (min(radii), max(radii))
    assert math.dist(f.vehicle.position, start) <= f.adapter.vehicle.settling.tolerance_m
    # A path streamed in the motion mode: never CIRCLE nor ORBIT, no DO_ORBIT.
    assert not NEVER & set(vehicle_modes(tmp_path))
    assert f.vehicle.mode == MODES[autopilot]["motion"]
    assert all(c != DO_ORBIT for c, _ in f.vehicle.commands)


def test_manoeuvres_on_the_ground_fail_with_a_reason(flight: Any) -> None:
    f = flight("ardupilot", vehicle={"speedup": 5.0})
    for action, args in (
        ("ReturnHome", ()),
        ("Hold", (1.0,)),
        ("Yaw", (90.0,)),
        ("Orbit", (2.0, 1.0)),
    ):
        result = f.do(action, *args)
        assert (result.status, result.reason) == ("failed", "not armed"), action


def test_each_autopilot_refuses_the_other_ones_commands() -> None:
    # Airborne needs not matter: the command is not there at all.
    px4, ardu = Rig("px4", prearm_delay_s=0.0), Rig("ardupilot", prearm_delay_s=0.0)
    px4.run_s(1.5)
    ardu.run_s(1.5)
    unsupported = 3
    assert px4.ask(command(CONDITION_YAW, 90.0, 0.0, 0.0, 0.0)) == unsupported
    assert px4.ask(command(DO_CHANGE_SPEED, 1.0, 2.0, -1.0)) == unsupported
    assert ardu.ask(command(DO_ORBIT, 5.0, 1.0, 0.0)) == unsupported
    # RTL on the ground is refused by both.
    assert px4.ask(command(RTL)) != ACCEPTED and ardu.ask(command(RTL)) != ACCEPTED
