"""Pure parts of the MAVLink layer: frames, mode encodings, settings, connection strings."""

from __future__ import annotations

import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from eamos.hal import ADAPTERS, AdapterError, make_adapter
from eamos.hal.mavlink.adapter import MavlinkAdapter, MavlinkSettings
from eamos.hal.mavlink.autopilots import (
    ArduPilot,
    Px4,
    autopilot_from_heartbeat,
    px4_custom_mode,
    px4_mode_of,
)
from eamos.hal.mavlink.frames import (
    NedOrigin,
    mission_to_ned,
    ned_to_mission,
    ned_velocity_to_mission,
)
from eamos.hal.mavlink.link import check_connection, result_name
from eamos.hal.sitl.vehicle import ACCEPTED, DENIED, FAILED, parse_reject
from eamos.logs import make_logger

pytestmark = pytest.mark.timeout(60)

# -- frames -------------------------------------------------------------------------------


def test_mission_to_ned_examples():
    origin = NedOrigin(0.0, 0.0, 0.0)
    assert mission_to_ned((1.0, 2.0, 3.0), origin) == (1.0, 2.0, -3.0)  # up is -down
    # PX4 SIH: the ground is 1.5 m "down" of the local origin.
    ground = NedOrigin(10.0, -4.0, 1.5)
    assert mission_to_ned((0.0, 0.0, 0.0), ground) == (10.0, -4.0, 1.5)
    assert mission_to_ned((1.0, 1.0, 2.0), ground) == (11.0, -3.0, -0.5)


def test_ned_to_mission_examples():
    ground = NedOrigin(10.0, -4.0, 1.5)
    assert ned_to_mission((10.0, -4.0, 1.5), ground) == (0.0, 0.0, 0.0)
    assert ned_to_mission((12.0, -4.0, -3.5), ground) == (2.0, 0.0, 5.0)  # 5 m up, 2 m north
    x, _y, z = ned_to_mission((0.0, 0.0, 0.0), NedOrigin())
    assert (math.copysign(1, x), math.copysign(1, z)) == (1, 1)  # no negative zeros


def test_ground_recapture_keeps_the_horizontal_home():
    origin = NedOrigin(1.0, 2.0, 1.3).with_ground(4.0)
    assert origin == NedOrigin(1.0, 2.0, 4.0)


def test_velocity_up_is_minus_down():
    assert ned_velocity_to_mission((1.0, -2.0, -0.5)) == (1.0, -2.0, 0.5)


finite = st.floats(min_value=-1e4, max_value=1e4, allow_nan=False)


@given(finite, finite, finite, finite, finite, finite)
def test_frames_round_trip(x, y, z, n0, e0, d0):
    origin = NedOrigin(n0, e0, d0)
    back = ned_to_mission(mission_to_ned((x, y, z), origin), origin)
    assert back == pytest.approx((x, y, z), abs=1e-6)
    ned = (x, y, z)
    assert mission_to_ned(ned_to_mission(ned, origin), origin) == pytest.approx(ned, abs=1e-6)


# -- modes --------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("name", "custom"),
    [
        ("OFFBOARD", 0x00060000),
        ("AUTO.TAKEOFF", 0x02040000),
        ("HOLD", 0x03040000),
        ("AUTO.LAND", 0x06040000),
        ("POSCTL", 0x00030000),
    ],
)
def test_px4_custom_modes_match_the_notes(name, custom):
    px4 = Px4()
    assert px4.mode_name(custom) == name
    main, sub = px4_mode_of(custom)
    assert px4_custom_mode(main, sub) == custom
    assert px4.mode_params(name) == (1.0, float(main), float(sub))


def test_ardupilot_modes():
    ap = ArduPilot()
    assert [ap.mode_name(m) for m in (0, 4, 9, 17)] == ["STABILIZE", "GUIDED", "LAND", "BRAKE"]
    assert ap.mode_params("GUIDED") == (1.0, 4.0, 0.0)
    assert ap.mode_name(99) == "ArduCopter(99)"


def test_autopilot_detected_from_heartbeat():
    assert autopilot_from_heartbeat(12).name == "px4"
    assert autopilot_from_heartbeat(3).name == "ardupilot"
    with pytest.raises(ValueError, match=r"only PX4 \(12\) and ArduPilot \(3\)"):
        autopilot_from_heartbeat(8)


# -- settings -----------------------------------------------------------------------------


def test_mavlink_is_a_registered_adapter():
    assert "mavlink" in ADAPTERS
    adapter = make_adapter(
        "D1", {"adapter": "mavlink", "connection": "udpin:0.0.0.0:14540"}, make_logger(None)
    )
    try:
        assert isinstance(adapter, MavlinkAdapter)
    finally:
        adapter.close()


def test_settings_defaults():
    s = MavlinkSettings.from_mapping({"connection": "tcp:127.0.0.1:5760"})
    assert (s.system_id, s.component_id, s.source_system, s.source_component) == (None, 1, 245, 191)
    assert (s.autopilot, s.takeoff_mode) == ("auto", "offboard")
    assert (s.connect_timeout_s, s.armable_timeout_s, s.command_timeout_s) == (30, 60, 1.5)
    assert (s.command_retries, s.heartbeat_timeout_s, s.action_timeout_s) == (3, 3, 120)
    assert (s.tolerance_m, s.settle_speed_mps, s.settle_s) == (None, None, None)
    assert (s.setpoint_hz, s.telemetry_hz, s.speedup) == (20, 10, 1)
    assert (s.horizontal_speed_mps, s.climb_speed_mps, s.descent_speed_mps) == (2, 1, 0.7)
    assert s.set_speeds and s.rearm and s.land_on_close


@pytest.mark.parametrize(
    ("settings", "message"),
    [
        ({}, r"hal\.connection: missing; e\.g\. \"udpin:0\.0\.0\.0:14540\""),
        ({"connection": 14540}, r"hal\.connection: expected a string"),
        ({"connection": "udp:localhost"}, r"hal\.connection: expected udpin:HOST:PORT"),
        ({"connection": "tcp:127.0.0.1:70000"}, r"hal\.connection: port 70000 is out of range"),
        ({"connection": "/dev/ttyACM0,fast"}, r"hal\.connection: baud rate 'fast'"),
        ({"connection": "tcp:h:1", "autopilot": "inav"}, r"hal\.autopilot: expected one of auto"),
        ({"connection": "tcp:h:1", "system_id": 0}, r"hal\.system_id: expected an integer from 1"),
        ({"connection": "tcp:h:1", "command_retries": 1.5}, r"hal\.command_retries: expected an"),
        ({"connection": "tcp:h:1", "heartbeat_timeout_s": -1}, r"hal\.heartbeat_timeout_s: must"),
        ({"connection": "tcp:h:1", "setpoint_hz": 1}, r"hal\.setpoint_hz: must be > 2"),
        ({"connection": "tcp:h:1", "takeoff_mode": "x"}, r"hal\.takeoff_mode: expected one of"),
        (
            {"connection": "tcp:h:1", "tolerance": 1},
            r"hal\.tolerance: unknown setting \(did you "
            r"mean 'tolerance_m'\?\)",
        ),
    ],
)
def test_settings_errors_name_the_field(settings, message):
    with pytest.raises(AdapterError, match=message):
        MavlinkSettings.from_mapping(settings)


@pytest.mark.parametrize(
    "text",
    [
        "udpin:0.0.0.0:14540",
        "udpout:127.0.0.1:14580",
        "tcp:127.0.0.1:5760",
        "tcpin:0.0.0.0:5760",
        "/dev/ttyACM0",
        "/dev/ttyAMA0,921600",
        "COM3,57600",
    ],
)
def test_connection_strings_accepted(text):
    assert check_connection(text) == ""


def test_result_names():
    assert result_name(0) == "MAV_RESULT_ACCEPTED"
    assert result_name(1) == "MAV_RESULT_TEMPORARILY_REJECTED"
    assert result_name(None) == "no COMMAND_ACK"


def test_parse_reject():
    assert parse_reject(["MAV_CMD_NAV_TAKEOFF", "NAV_LAND=failed", "400=DENIED"]) == {
        22: DENIED,
        21: FAILED,
        400: DENIED,
    }
    with pytest.raises(ValueError, match="unknown MAVLink command"):
        parse_reject(["MAV_CMD_FLY_TO_THE_MOON"])
    with pytest.raises(ValueError, match="result must be one of"):
        parse_reject(["22=ACCEPTED"])
    assert ACCEPTED == 0
