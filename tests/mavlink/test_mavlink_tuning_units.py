"""Pure parts of issue 16's adapter changes: speed plans, parameter encoding, settings,
the settle window.  No socket, no thread."""

from __future__ import annotations

import math
import threading
import time
from collections import deque
from typing import TYPE_CHECKING, cast

import pytest

from eamos.hal.api import AdapterError
from eamos.hal.mavlink.link import MAV_SYS_STATUS_PREARM_CHECK
from eamos.hal.mavlink.params import from_wire, speed_plan, to_wire
from eamos.hal.mavlink.settings import MavlinkSettings
from eamos.hal.mavlink.state import LinkState
from eamos.hal.mavlink.vehicle import SYS_STATUS_GRACE_S, armable
from eamos.hal.mavlink.waits import Failed, Run, Waiter

if TYPE_CHECKING:
    from eamos.hal.mavlink.vehicle import MavlinkVehicle


def test_speed_plans_name_each_autopilots_parameters_and_units():
    assert speed_plan("ardupilot", 2.0, 1.0, 0.7) == (
        ("WPNAV_SPEED", 200.0),
        ("WPNAV_SPEED_UP", 100.0),
        ("WPNAV_SPEED_DN", 70.0),
    )
    assert speed_plan("px4", 3.0, 1.5, 0.8) == (
        ("MPC_XY_VEL_MAX", 3.0),
        ("MPC_XY_CRUISE", 3.0),
        ("MPC_Z_VEL_MAX_UP", 1.5),
        ("MPC_Z_VEL_MAX_DN", 0.8),
    )
    with pytest.raises(ValueError, match="unknown autopilot"):
        speed_plan("inav", 1, 1, 1)


def test_integer_parameters_travel_bytewise_on_px4_only():
    wire = to_wire(5, 6, bytewise=True)
    assert wire != 5.0 and from_wire(wire, 6, bytewise=True) == 5.0
    assert to_wire(5, 6, bytewise=False) == 5.0  # ArduPilot casts
    assert to_wire(2.5, 9, bytewise=True) == 2.5  # floats are floats


def test_settings_for_speeds_signing_and_clock_rate():
    s = MavlinkSettings.from_mapping(
        {
            "connection": "tcp:h:1",
            "horizontal_speed_mps": 3,
            "speedup": 10,
            "rearm": False,
            "signing_key": "~/fleet/mavlink_signing.key",
        }
    )
    assert (s.horizontal_speed_mps, s.rearm, s.signing_key) == (
        3,
        False,
        "~/fleet/mavlink_signing.key",
    )
    assert s.scaled(120) == 12.0
    for bad, message in (
        ({"telemetry_hz": 5}, r"hal\.telemetry_hz: must be >= 10"),
        ({"rearm": "yes"}, r"hal\.rearm: expected true or false"),
        ({"speedup": 0}, r"hal\.speedup: must be > 0"),
        ({"tolerance_m": -1}, r"hal\.tolerance_m: must be > 0"),
    ):
        with pytest.raises(AdapterError, match=message):
            MavlinkSettings.from_mapping({"connection": "tcp:h:1", **bad})


def test_settle_window_needs_the_whole_window_and_averages_it():
    st = LinkState()
    assert st.window(10.0, 0.5) is None
    st.recent = deque()
    for i in range(11):  # 1 s of samples at 10 Hz, wandering +-0.4 m around x = 1
        x = 1.0 + (0.4 if i % 2 else -0.4)
        st.local = (x, 0.0, -2.0, 0.3 if i % 2 else -0.3, 0.0, 0.0)
        st.recent.append((9.0 + i * 0.1, st.local))
    seen = st.window(10.0, 0.5)
    assert seen is not None
    (x, y, z), speed = seen
    assert abs(x - 1.0) < 0.1 and (y, z) == (0.0, -2.0) and speed < 0.1
    assert st.window(10.0, 2.0) is None  # not heard for 2 s yet
    latest = st.window(10.0, 0.0)
    assert latest is not None and math.isclose(latest[1], 0.3)


def test_armable_waits_for_sys_status_when_positions_come_first():
    # ArduCopter streams LOCAL_POSITION_NED as soon as asked, before "ArduPilot Ready"
    # (which overwrites a mode set earlier): a position alone is not armable.
    st = LinkState()
    st.local, st.local_since, st.last_rx = (0.0,) * 6, 100.0, 100.5
    assert not armable(st)
    st.sensors_present = st.sensors_health = 0
    assert armable(st)  # SYS_STATUS without the pre-arm bit: try, and let it refuse
    st.sensors_present = MAV_SYS_STATUS_PREARM_CHECK
    assert not armable(st)
    st.sensors_health = MAV_SYS_STATUS_PREARM_CHECK
    assert armable(st)
    # An autopilot that never sends SYS_STATUS is tried once positions came for the grace.
    silent = LinkState()
    silent.local, silent.local_since = (0.0,) * 6, 100.0
    silent.last_rx = 100.0 + SYS_STATUS_GRACE_S - 0.1
    assert not armable(silent)
    silent.last_rx = 100.0 + SYS_STATUS_GRACE_S
    assert armable(silent)


class _Vehicle:
    """What a Waiter reads of its vehicle: a condition, a link state, no pilot."""

    def __init__(self) -> None:
        self.settings = MavlinkSettings.from_mapping({"connection": "tcp:h:1"})
        self.cond = threading.Condition()
        self.state = LinkState(link_ok=True)
        self.taken_over = None


def test_a_wait_answers_with_what_ended_it_not_with_a_second_look():
    # A settle window reads the clock: it said "arrived" when the wait ended, and a look a
    # moment later (the window slid on) said not.  That was reported as a timeout after
    # 2.2 s of a 15 s deadline (CI, PX4 personality with a wandering estimate).
    looks = iter((True, False, False))
    waiter = Waiter(cast("MavlinkVehicle", _Vehicle()))
    run = Run(None, None, "internal", time.monotonic())
    waiter.wait(run, lambda st: next(looks), time.monotonic() + 60.0, lambda st: "timed out")
    # And a guard's problem is the one it found, even if a second look finds none.
    problems = iter(("vehicle disarmed", None))
    with pytest.raises(Failed, match="vehicle disarmed"):
        waiter.wait(
            run,
            lambda st: False,
            time.monotonic() + 60.0,
            lambda st: "timed out",
            guard=lambda st: next(problems),
        )
