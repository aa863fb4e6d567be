"""The MAVLink adapter flying the simulated PX4 and ArduPilot vehicles (happy paths)."""

from __future__ import annotations

import math
import time

import pytest

from eamos.hal.api import AdapterError
from eamos.hal.kinematics import GeoFrame

from .mavlink_helpers import WAIT_S

pytestmark = [pytest.mark.e2e, pytest.mark.timeout(180)]

AUTOPILOTS = ["px4", "ardupilot"]


@pytest.mark.parametrize("autopilot", AUTOPILOTS)
def test_full_flight(flight, autopilot):
    f = flight(autopilot)
    assert f.adapter.autopilot == autopilot
    on_ground = f.sink.wait_for(lambda s: True)
    assert (on_ground.x_m, on_ground.y_m, on_ground.z_m) == (0.0, 0.0, 0.0)
    assert on_ground.landed and not on_ground.armed

    f.ok("Arm")
    assert f.vehicle.armed
    assert f.adapter.mode_name() == ("OFFBOARD" if autopilot == "px4" else "GUIDED")
    f.ok("Takeoff", 2.0)
    x, y, z = f.vehicle.position
    assert z == pytest.approx(2.0, abs=0.3) and math.hypot(x, y) < 0.05
    f.ok("FlyByX", 3.0)
    assert f.vehicle.position == pytest.approx((3.0, 0.0, 2.0), abs=0.3)
    f.ok("FlyToXYZ", -1.0, 2.0, 3.0)
    assert f.vehicle.position == pytest.approx((-1.0, 2.0, 3.0), abs=0.3)
    # A WGS84 point 4 m north, 1 m east of home, 2.5 m above it.
    lat, lon, alt = GeoFrame(46.6103, 14.2640, 450.0).to_lla(4.0, 1.0, 2.5)
    f.ok("FlyToLLA", lat, lon, alt)
    assert f.vehicle.position == pytest.approx((4.0, 1.0, 2.5), abs=0.3)
    flying = f.sink.wait_for(lambda s: s.z_m > 2.2 and s.x_m > 3.5)
    assert flying.armed and not flying.landed
    assert flying.lat_deg > 46.6103 and flying.alt_m > 2.0

    f.ok("Land")
    assert f.vehicle.position[2] == pytest.approx(0.0, abs=0.05)
    f.ok("Disarm")
    assert not f.vehicle.armed
    last = f.sink.wait_for(lambda s: not s.armed and s.landed and s.x_m > 3.5)
    assert last.z_m == pytest.approx(0.0, abs=0.1)


def test_px4_heights_are_relative_to_the_ground_not_the_local_origin(flight):
    # PX4 SIH reports z = +1.5 m (down) on the ground; the mission must see 0.
    f = flight("px4", vehicle={"ground_offset_m": 1.5})
    f.airborne(1.5)
    sample = f.sink.wait_for(lambda s: s.z_m > 1.2)
    assert sample.z_m == pytest.approx(1.5, abs=0.35)
    assert f.vehicle.position[2] == pytest.approx(1.5, abs=0.35)


def test_px4_auto_takeoff_mode(flight):
    f = flight("px4", takeoff_mode="auto")
    f.ok("Arm")
    assert f.adapter.mode_name() == "HOLD"  # no OFFBOARD before take-off in this mode
    f.ok("Takeoff", 2.0)
    assert f.vehicle.position[2] == pytest.approx(2.0, abs=0.3)
    f.ok("FlyByY", 1.0)  # the first move switches to OFFBOARD
    assert f.vehicle.mode == "OFFBOARD"
    assert f.vehicle.position == pytest.approx((0.0, 1.0, 2.0), abs=0.3)


@pytest.mark.parametrize("autopilot", AUTOPILOTS)
def test_cancel_holds_where_the_vehicle_is(flight, autopilot):
    f = flight(autopilot, vehicle={"speedup": 4.0})
    f.airborne(2.0)
    handle, done = f.run("FlyByX", 30.0)
    f.wait_vehicle(lambda v: v.position[0] > 3.0)
    f.adapter.cancel(handle)
    cancelled_at = f.vehicle.position
    known = f.sink.last()  # where the adapter's telemetry had it by then
    result = done.wait()
    assert result.status == "cancelled"
    # It brakes to rest at its stopping point (2 m/s braking at 2.5 m/s/s: 0.8 m on),
    # never flying back past where it was cancelled, and stays there.  "Where" is what
    # the adapter knew: on a loaded machine its telemetry ran 0.9 m (115 ms at x4)
    # behind the vehicle, and the stopping point it aimed at was behind the vehicle too.
    t0 = f.vehicle.sim_time_s
    f.wait_vehicle(lambda v: v.sim_time_s > t0 + 5.0)
    stop = f.vehicle.position
    assert known.x_m - 0.1 <= stop[0] <= cancelled_at[0] + 0.8 + 0.4, (known, cancelled_at, stop)
    t1 = f.vehicle.sim_time_s
    f.wait_vehicle(lambda v: v.sim_time_s > t1 + 3.0)
    assert f.vehicle.position == pytest.approx(stop, abs=0.1)
    # The next move starts from there.
    f.ok("FlyByY", 1.0)
    assert f.vehicle.position == pytest.approx((stop[0], 1.0, 2.0), abs=0.35)
    assert done.calls == 1


def test_cancel_of_a_landing_holds_in_the_air(flight):
    f = flight("ardupilot", vehicle={"speedup": 3.0})
    f.airborne(4.0)
    handle, done = f.run("Land")
    f.wait_vehicle(lambda v: v.position[2] < 3.0)
    f.adapter.cancel(handle)
    assert done.wait().status == "cancelled"
    f.wait_vehicle(lambda v: v.mode == "GUIDED" and v.speed_mps < 0.05)
    assert 0.5 < f.vehicle.position[2] < 3.0 and f.vehicle.armed


@pytest.mark.parametrize("autopilot", AUTOPILOTS)
def test_abort_lands_and_disarms(flight, autopilot):
    f = flight(autopilot)
    f.airborne(3.0)
    _handle, done = f.run("FlyByX", 50.0)
    f.adapter.abort()
    assert done.wait().status == "cancelled" and done.result.reason == "aborted"
    f.wait_vehicle(lambda v: not v.armed and v.position[2] == 0.0)
    f.sink.wait_for(lambda s: s.landed and not s.armed)


def test_rules_and_payload(flight):
    f = flight("px4")
    assert f.do("Takeoff", 1.0).reason == "not armed"
    assert f.do("FlyByX", 1.0).reason == "not armed"
    for payload in ("TurnOn", "PreFlightCheck", "Calibrate", "TurnOnCamera", "AdjustCamera"):
        assert f.do(payload).ok
    assert f.do("Land").ok  # already on the ground
    assert f.do("Disarm").ok  # already disarmed
    f.airborne(1.5)
    assert f.do("Arm").ok  # already armed
    assert f.do("Disarm").reason == "in the air"
    assert f.do("FlyByZ", -5.0).reason.startswith("target z -3.50 m is not above ground")
    handle, first = f.run("FlyByX", 20.0)
    assert f.do("FlyByY", 1.0).reason == "busy"
    f.adapter.cancel(handle)
    assert first.wait().status == "cancelled"
    # Unknown actions and bad arguments are refused by the uniform-API actor,
    # which decodes every call (tests/actors/test_uniform_api.py).


def test_pause_for_is_a_timer(flight):
    f = flight("ardupilot")
    t0 = time.monotonic()
    assert f.do("PauseFor", 0.5).ok
    assert 0.45 <= time.monotonic() - t0 < 5.0
    handle, done = f.run("PauseFor", 100.0)
    f.adapter.cancel(handle)
    assert done.wait(5).status == "cancelled"


def test_autopilot_setting_must_match_the_heartbeat(make_vehicle, make_adapter):
    _, conn = make_vehicle("ardupilot")
    adapter = make_adapter(conn, autopilot="px4")
    with pytest.raises(
        AdapterError,
        match=r"hal\.autopilot: is 'px4' but the vehicle's "
        r"HEARTBEAT announces ardupilot \(3\)",
    ):
        adapter.start(lambda s: None)


def test_two_vehicles_side_by_side(flight):
    # Two adapters, two vehicles, one process: nothing is shared between them.
    a = flight("px4")
    b = flight("ardupilot")
    a.ok("Arm")
    b.ok("Arm")
    _ha, da = a.run("Takeoff", 1.5)
    _hb, db = b.run("Takeoff", 2.5)
    assert da.wait(WAIT_S).ok and db.wait(WAIT_S).ok
    assert a.vehicle.position[2] == pytest.approx(1.5, abs=0.3)
    assert b.vehicle.position[2] == pytest.approx(2.5, abs=0.3)


def test_close_ends_running_actions(flight):
    f = flight("px4", vehicle={"speedup": 2.0})
    f.airborne(1.5)
    _, done = f.run("FlyByX", 100.0)
    f.adapter.close()
    assert done.wait(5).status == "cancelled"
    f.adapter.close()  # idempotent
