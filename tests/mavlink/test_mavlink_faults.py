"""Bad situations: unreachable vehicles, refusals, take-overs, link drops. Every wait is bounded."""

from __future__ import annotations

import json
import socket
import threading
import time

import pytest

from eamos.ground.vehicles import free_port
from eamos.hal.api import AdapterError
from eamos.hal.sitl.vehicle import (
    DENIED,
    FAILED,
    TEMPORARILY_REJECTED,
    SimVehicle,
    VehicleOptions,
)

from .mavlink_helpers import WAIT_S

pytestmark = [pytest.mark.e2e, pytest.mark.timeout(180)]

AUTOPILOTS = ["px4", "ardupilot"]


# -- unreachable ----------------------------------------------------------------------------


def test_unreachable_udp_vehicle(make_adapter):
    port = free_port(socket.SOCK_DGRAM)
    adapter = make_adapter(f"udpin:127.0.0.1:{port}", connect_timeout_s=1.0)
    t0 = time.monotonic()
    with pytest.raises(
        AdapterError,
        match=rf"D1: no heartbeat from udpin:127\.0\.0\.1:{port} "
        r"within 1 s$",
    ):
        adapter.start(lambda s: None)
    assert 0.9 < time.monotonic() - t0 < 3.0


def test_unreachable_tcp_vehicle(make_adapter):
    port = free_port(socket.SOCK_STREAM)  # nobody listens: every dial is refused
    adapter = make_adapter(f"tcp:127.0.0.1:{port}", connect_timeout_s=1.5)
    t0 = time.monotonic()
    with pytest.raises(
        AdapterError,
        match=rf"no heartbeat from tcp:127\.0\.0\.1:{port} within "
        r"1\.5 s \(TCP: .*refused",
    ):
        adapter.start(lambda s: None)
    assert 1.4 < time.monotonic() - t0 < 4.0


def test_port_already_taken(make_adapter):
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as taken:
        taken.bind(("127.0.0.1", 0))
        port = taken.getsockname()[1]
        adapter = make_adapter(f"udpin:127.0.0.1:{port}", connect_timeout_s=5.0)
        with pytest.raises(AdapterError, match=rf"cannot open udpin:127\.0\.0\.1:{port}: .*in use"):
            adapter.start(lambda s: None)


def test_tcp_vehicle_that_starts_late_is_reached(make_adapter):
    # ArduPilot SITL may still be starting when the companion dials: keep dialling.
    port = free_port(socket.SOCK_STREAM)
    adapter = make_adapter(f"tcp:127.0.0.1:{port}", connect_timeout_s=15.0)
    vehicle = SimVehicle(VehicleOptions("ardupilot", f"tcpin:127.0.0.1:{port}", speedup=5))
    starter = threading.Timer(1.0, vehicle.start)  # the vehicle comes up a second later
    starter.start()
    try:
        adapter.start(lambda s: None)
        assert adapter.autopilot == "ardupilot"
    finally:
        starter.join()
        vehicle.stop()


# -- refusals ---------------------------------------------------------------------------------


def test_command_rejected_names_the_result(flight):
    f = flight("ardupilot", vehicle={"reject": {22: DENIED}})
    f.ok("Arm")
    result = f.do("Takeoff", 2.0)
    assert result.status == "failed"
    assert result.reason.startswith("MAV_CMD_NAV_TAKEOFF rejected with MAV_RESULT_DENIED")
    assert "Command 22 rejected (test fault)" in result.reason  # the STATUSTEXT


def test_land_rejected_px4(flight):
    f = flight("px4", vehicle={"reject": {21: FAILED}})
    f.airborne(1.5)
    result = f.do("Land")
    assert result.reason.startswith("MAV_CMD_NAV_LAND rejected with MAV_RESULT_FAILED")
    assert f.vehicle.armed and f.vehicle.position[2] > 1.0  # still up there, holding


@pytest.mark.parametrize(
    ("autopilot", "text"),
    [
        ("px4", "Preflight Fail: ekf2 missing data"),
        ("ardupilot", "PreArm: EKF3 still initialising"),
    ],
)
def test_vehicle_that_never_becomes_armable(flight, autopilot, text, tmp_path):
    f = flight(autopilot, vehicle={"prearm_delay_s": float("inf")}, armable_timeout_s=2.0)
    t0 = time.monotonic()
    result = f.do("Arm")
    assert result.status == "failed"
    assert result.reason == f"vehicle never became armable within 2 s: {text}"
    assert 1.9 < time.monotonic() - t0 < 6.0
    assert not f.vehicle.armed
    # The vehicle's explanation is in the adapter log too.
    log = [json.loads(line) for line in (tmp_path / "D1-adapter.log").read_text().splitlines()]
    assert any(e["event"] == "adapter.statustext" and e["text"] == text for e in log)


def test_arming_refused(flight):
    f = flight("px4", vehicle={"reject": {400: DENIED}})
    result = f.do("Arm")
    assert result.reason == "arming refused (MAV_RESULT_DENIED): Command 400 rejected (test fault)"


def test_arming_temporarily_rejected_is_retried_until_armable(flight):
    # Firmware that does not report the pre-arm bit in SYS_STATUS gives the
    # adapter no way to wait: it tries, PX4 answers TEMPORARILY_REJECTED while
    # unready, and the adapter tries again until arming is accepted.
    # (Its estimator reports settled from the start: only the pre-arm checks are late.)
    vehicle = {
        "prearm_delay_s": 10.0,
        "speedup": 5.0,
        "report_prearm": False,
        "estimator_settle_s": 0.0,
    }
    f = flight("px4", vehicle=vehicle)
    f.ok("Arm")
    assert f.vehicle.sim_time_s >= 10.0
    assert (400, TEMPORARILY_REJECTED) in f.vehicle.commands
    assert f.vehicle.commands[-1] == (400, 0)


def test_arming_temporarily_rejected_until_the_armable_timeout(flight):
    f = flight("px4", vehicle={"reject": {400: TEMPORARILY_REJECTED}}, armable_timeout_s=3.0)
    result = f.do("Arm")
    assert result.reason.startswith(
        "arming refused (MAV_RESULT_TEMPORARILY_REJECTED until the "
        "3 s armable timeout): Command 400 rejected (test fault)"
    )
    assert f.vehicle.commands.count((400, TEMPORARILY_REJECTED)) >= 2  # it did try again


# -- someone else takes over ------------------------------------------------------------------


@pytest.mark.parametrize("autopilot", AUTOPILOTS)
def test_vehicle_disarmed_mid_air(flight, autopilot):
    f = flight(autopilot, vehicle={"speedup": 3.0})
    f.airborne(3.0)
    _, done = f.run("FlyByX", 40.0)
    f.wait_vehicle(lambda v: v.position[0] > 2.0)
    f.vehicle.force_disarm()
    result = done.wait()
    assert result.status == "failed"
    assert result.reason == "vehicle disarmed (Disarmed by RC emergency stop)"


@pytest.mark.parametrize(("autopilot", "mode"), [("px4", "POSCTL"), ("ardupilot", "LOITER")])
def test_pilot_switches_mode_mid_action(flight, autopilot, mode):
    f = flight(autopilot, vehicle={"speedup": 3.0})
    f.airborne(2.0)
    _, done = f.run("FlyByY", 40.0)
    f.wait_vehicle(lambda v: v.position[1] > 2.0)
    f.vehicle.set_mode(mode)
    result = done.wait()
    # Issue 27: not "switched to mode ... under us" (nor a stale STATUSTEXT): the pilot's.
    assert result.reason == f"taken over by the pilot ({mode})"
    # The mission never takes the vehicle back: no action reaches it any more.
    assert f.do("FlyByY", 1.0).reason == f"taken over by the pilot ({mode})"
    f.adapter.abort()  # no landing either
    f.adapter.close()
    assert f.vehicle.mode == mode and f.vehicle.armed


@pytest.mark.parametrize(("autopilot", "hold"), [("px4", "HOLD"), ("ardupilot", "BRAKE")])
def test_a_failsafe_that_holds_a_landing_vehicle_is_answered_with_land_again(
    flight, autopilot, hold, tmp_path
):
    # PX4 SITL: a vehicle landing on its geofence's line (the estimate wandering across it)
    # was held by "Failsafe activated" a metre above the ground; Land failed and the drone
    # hovered.  A failsafe that only holds is not a pilot: Land sends LAND again.
    f = flight(autopilot, vehicle={"speedup": 3.0})
    f.airborne(3.0)
    _, done = f.run("Land")
    f.wait_vehicle(lambda v: v.position[2] < 2.0)
    f.vehicle.failsafe(hold)
    result = done.wait()
    assert result.ok, result
    assert f.vehicle.position[2] < 0.2
    lines = [json.loads(x) for x in (tmp_path / "D1-adapter.log").read_text().splitlines()]
    resumed = [e for e in lines if e["event"] == "adapter.land.resumed"]
    assert len(resumed) == 1 and resumed[0]["level"] == "warning", resumed
    assert "Failsafe activated" in resumed[0]["failsafe"]


def test_a_pilot_who_holds_a_landing_vehicle_keeps_it(flight):
    # The same hold by a pilot's switch is a takeover: no LAND again, ever.
    f = flight("px4", vehicle={"speedup": 3.0})
    f.airborne(3.0)
    _, done = f.run("Land")
    f.wait_vehicle(lambda v: v.position[2] < 2.0)
    f.vehicle.set_mode("HOLD")
    result = done.wait()
    assert result.reason == "taken over by the pilot (HOLD)"
    assert f.vehicle.mode == "HOLD" and f.vehicle.position[2] > 0.5


# -- link drops ---------------------------------------------------------------------------------


@pytest.mark.parametrize("autopilot", AUTOPILOTS)
def test_short_link_drop_does_not_fail_the_action(flight, autopilot, tmp_path):
    f = flight(autopilot, vehicle={"speedup": 2.0}, heartbeat_timeout_s=3.0)
    f.airborne(2.0)
    _, done = f.run("FlyByX", 14.0)
    f.wait_vehicle(lambda v: v.position[0] > 1.0)
    f.vehicle.drop_link(1.5)
    result = done.wait()
    assert result.ok, result
    assert f.vehicle.position[0] == pytest.approx(14.0, abs=0.35)
    if autopilot == "px4":
        # 1.5 s without setpoints is PX4's offboard-loss failsafe; it came back by itself.
        log = (tmp_path / "vehicle-0.log").read_text()
        assert "Failsafe activated" in log and "Failsafe deactivated" in log
        assert f.vehicle.mode == "OFFBOARD"


@pytest.mark.parametrize("autopilot", AUTOPILOTS)
def test_long_link_drop_fails_the_action_and_later_actions_work(flight, autopilot):
    f = flight(autopilot, vehicle={"speedup": 2.0}, heartbeat_timeout_s=1.5)
    f.airborne(2.0)
    _, done = f.run("FlyByX", 30.0)
    f.wait_vehicle(lambda v: v.position[0] > 1.0)
    t0 = time.monotonic()
    f.vehicle.drop_link(4.0)
    result = done.wait()
    assert result.status == "failed"
    assert result.reason.startswith(
        "heartbeat lost: no HEARTBEAT from the vehicle for more than 1.5 s"
    )
    assert 0.9 < time.monotonic() - t0 < 3.5  # last HEARTBEAT + 1.5 s
    # While the link is down, new actions fail at once rather than hang.
    assert f.do("FlyByY", 1.0, timeout=5).reason.startswith("heartbeat lost")
    # Once heartbeats are back, the adapter flies again.
    assert f.adapter.wait_link_ok(WAIT_S)
    f.ok("FlyToXYZ", 0.0, 0.0, 2.0)
    assert f.vehicle.position == pytest.approx((0.0, 0.0, 2.0), abs=0.35)
    f.ok("Land")
    f.ok("Disarm")


def test_close_while_waiting_to_arm_returns_promptly(flight):
    f = flight("px4", vehicle={"prearm_delay_s": float("inf")}, armable_timeout_s=100.0)
    _, done = f.run("Arm")
    t0 = time.monotonic()
    f.adapter.close()
    assert done.wait(5).status == "cancelled"
    assert time.monotonic() - t0 < 5.0
