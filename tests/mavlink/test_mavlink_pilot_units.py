"""Issue 27 items 3-7, the pure parts: whose mode change, rates, refused frames, the
fence plan, and what the uniform API, the summary, the display and the monitor do
with a vehicle a pilot took over.  No threads, no clocks, no vehicle."""

from __future__ import annotations

import os
from typing import Any

import pytest

from eamos.actors.report import DroneReport
from eamos.actors.uniform_api import ActionFinished, RunAction, UniformSpace
from eamos.ground.display import format_event
from eamos.ground.summary import DroneResult
from eamos.hal.api import (
    ActionHandle,
    ActionResult,
    AdapterNotice,
    TakenOver,
    adapter_notices,
    taken_over,
    vehicle_facts,
)
from eamos.hal.kinematics import GeoFrame
from eamos.hal.mavlink.geofence import (
    FENCE_TYPE_ALT_MAX,
    FENCE_TYPE_POLYGON,
    MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION,
    fence_plan,
)
from eamos.hal.mavlink.home import check_home
from eamos.hal.mavlink.pilot import FAILSAFE_GRACE_MIN_S, takeover_watch
from eamos.hal.mavlink.rates import RateWatch
from eamos.hal.mavlink.settings import MavlinkSettings
from eamos.hal.mavlink.signing import refused_frame
from eamos.hal.mavlink.takeover import (
    FAILSAFE_GRACE_S,
    MAV_CMD_NAV_LAND,
    MAV_CMD_NAV_TAKEOFF,
    TakeoverWatch,
    announces_failsafe,
)
from eamos.logs import make_logger
from eamos.net import wire
from eamos.program.plugins import EMPTY_PLUGINS
from eamos.program.uniform import Command

# -- whose mode change (takeover.py) -------------------------------------------------------------


def flying(autopilot: str = "ardupilot", grace: float = 1.5) -> TakeoverWatch:
    watch = TakeoverWatch(autopilot, grace_s=grace, window_s=5.0, link_grace_s=3.0)
    watch.expect({"GUIDED" if autopilot == "ardupilot" else "OFFBOARD"}, 0.0)
    return watch


def test_modes_the_adapter_asked_for_are_its_own():
    watch = flying()
    assert watch.mode_seen("STABILIZE", "GUIDED", True, 1.0).verdict == "ours"
    watch.expect_command(MAV_CMD_NAV_LAND, 20.0)  # LAND switches the mode by itself
    assert watch.mode_seen("GUIDED", "LAND", True, 20.5).verdict == "ours"
    assert watch.taken is None


def test_a_change_into_the_companion_mode_hands_the_vehicle_to_the_adapter():
    watch = flying("px4")
    watch.expect_command(MAV_CMD_NAV_LAND, 1.0)
    assert watch.mode_seen("AUTO.LAND", "OFFBOARD", True, 60.0).verdict == "ours"


def test_px4_takeoff_switching_itself_to_hold_is_not_a_pilot():
    watch = flying("px4")
    watch.expect_command(MAV_CMD_NAV_TAKEOFF, 1.0)
    assert watch.mode_seen("OFFBOARD", "AUTO.TAKEOFF", True, 1.2).verdict == "ours"
    assert watch.mode_seen("AUTO.TAKEOFF", "HOLD", True, 30.0).verdict == "ours"


def test_a_mode_nobody_asked_for_is_the_pilots_once_the_grace_is_over():
    watch = flying()
    change = watch.mode_seen("GUIDED", "LOITER", True, 30.0)
    assert change.verdict == "pending" and watch.pending is not None
    assert watch.tick(31.0) is None  # a failsafe's STATUSTEXT may still come
    taken = watch.tick(31.6)
    assert taken is not None and taken.verdict == "pilot" and taken.mode == "LOITER"
    assert watch.taken == taken and watch.pending is None
    # Never cleared: whatever the vehicle does next, it is the pilot's.
    assert watch.mode_seen("LOITER", "GUIDED", True, 40.0).verdict == "pilot"


def test_a_failsafe_announced_before_or_just_after_its_mode_change_is_not_a_takeover():
    before = flying()
    assert before.statustext("GCS Failsafe", 29.0) is None
    change = before.mode_seen("GUIDED", "RTL", True, 30.0)
    assert change.verdict == "failsafe" and change.why == "GCS Failsafe"
    after = flying()
    assert after.mode_seen("GUIDED", "LAND", True, 30.0).verdict == "pending"
    late = after.statustext("Battery Failsafe", 30.4)
    assert late is not None and late.verdict == "failsafe" and after.failsafe == late
    assert after.tick(40.0) is None and after.taken is None
    px4 = flying("px4")
    px4.statustext("Failsafe activated", 10.0)
    assert px4.mode_seen("OFFBOARD", "AUTO.RTL", True, 10.1).verdict == "failsafe"


def test_failsafe_texts_of_both_autopilots_are_recognised():
    for text in (
        "Radio Failsafe",
        "GCS Failsafe - Continuing Landing",
        "Failsafe: Terrain data missing",
        "EKF Failsafe: changed to LAND Mode",
        "EKF variance",
        "Polygon fence breached",
        "Failsafe activated",
        "Failsafe activated, entering Hold for 5 seconds",
    ):
        assert announces_failsafe(text), text
    for text in ("Arming motors", "EKF3 IMU0 is using GPS", "Takeoff detected"):
        assert not announces_failsafe(text), text


def test_mode_changes_after_a_silent_link_or_of_a_vehicle_not_flown_are_not_takeovers():
    px4 = flying("px4")
    px4.link_gap(10.0)  # PX4 leaves OFFBOARD when setpoints stop for a second
    assert px4.mode_seen("OFFBOARD", "HOLD", True, 11.0).verdict == "link"
    idle = TakeoverWatch("ardupilot")  # connected, never commanded
    assert idle.mode_seen("STABILIZE", "LOITER", True, 1.0).verdict == "ours"
    disarmed = flying()
    disarmed.disarmed()
    assert disarmed.mode_seen("GUIDED", "LOITER", False, 50.0).verdict == "ours"
    assert disarmed.taken is None


def test_a_pilot_flicking_through_modes_is_timed_from_the_first():
    watch = flying()
    watch.mode_seen("GUIDED", "LOITER", True, 10.0)
    watch.mode_seen("LOITER", "ALT_HOLD", True, 11.0)
    taken = watch.tick(11.6)
    assert taken is not None and taken.mode == "ALT_HOLD"


# -- rates (rates.py) --------------------------------------------------------------------------


def test_a_lowered_rate_is_asked_for_again_and_reported_once_when_it_stays_low():
    watch = RateWatch({"LOCAL_POSITION_NED": (32, 10.0)}, window_s=2.0)
    count = 0

    def window(hz: float, t: float) -> list[Any]:
        nonlocal count
        count += int(hz * 2)
        return watch.window({"LOCAL_POSITION_NED": count}, t)

    assert watch.window({"LOCAL_POSITION_NED": 0}, 0.0) == []
    assert window(10, 2.0) == []  # as asked
    first = window(1, 4.0)  # a second ground station lowered it
    assert [f.action for f in first] == ["request"] and first[0].seen_hz == 1.0
    assert [f.action for f in window(10, 6.0)] == []  # asking again worked
    assert [f.action for f in window(1, 8.0)] == ["request"]
    assert [f.action for f in window(1, 10.0)] == ["request"]
    reported = window(1, 12.0)
    assert sorted(f.action for f in reported) == ["report", "request"]
    later = [window(1, 14.0 + 2 * i) for i in range(3)]
    assert all(f.action == "request" for w in later for f in w)  # reported once


def test_rates_are_measured_on_the_vehicles_clock():
    watch = RateWatch({"ATTITUDE": (30, 10.0)}, window_s=2.0)
    watch.window({"ATTITUDE": 5}, 100.0)
    assert watch.window({"ATTITUDE": 15}, 101.0) == []  # 1 vehicle second: not a window yet
    # 20 in 2 s of the vehicle's time_boot_ms: as asked, however slow the wall clock ran.
    assert watch.window({"ATTITUDE": 25}, 102.0) == []
    assert watch.window({"ATTITUDE": 30}, 1.0) == []  # it rebooted: a new window
    assert [f.action for f in watch.window({"ATTITUDE": 32}, 3.0)] == ["request"]


# -- signing: who sent a refused frame ------------------------------------------------------------


def test_refused_frames_say_who_sent_them_and_whether_they_were_signed():
    os.environ.setdefault("MAVLINK20", "1")
    from pymavlink.dialects.v20 import common

    vehicle = common.MAVLink(None, srcSystem=4, srcComponent=1)
    unsigned = refused_frame(vehicle.heartbeat_encode(2, 12, 0, 0, 4).pack(vehicle))
    assert unsigned is not None and not unsigned.signed and unsigned.vehicle_heartbeat
    assert (unsigned.system_id, unsigned.autopilot) == (4, 12)
    vehicle.signing.secret_key = bytes(32)
    vehicle.signing.sign_outgoing = True
    signed = refused_frame(vehicle.heartbeat_encode(2, 3, 0, 0, 4).pack(vehicle))
    assert signed is not None and signed.signed and signed.autopilot == 3
    gcs = common.MAVLink(None, srcSystem=255, srcComponent=190)
    other = refused_frame(gcs.heartbeat_encode(6, 8, 0, 0, 4).pack(gcs))
    assert other is not None and not other.vehicle_heartbeat
    assert refused_frame(b"\x01\x02") is None


# -- the fence plan and home (geofence.py, home.py) --------------------------------------------


def test_the_fleet_fence_is_placed_from_the_vehicles_home_in_the_fleet_frame():
    geo = GeoFrame(-35.363261, 149.165230, 584.0)
    square = [(-10.0, -5.0), (-10.0, 15.0), (10.0, 15.0), (10.0, -5.0)]
    plan = fence_plan("ardupilot", square, 12.0, (0.0, 5.0), geo)
    assert [i.command for i in plan.items] == [MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION] * 4
    assert all(i.params[0] == 4.0 for i in plan.items)
    # The drone stands 5 m east in the fleet frame: the fence's (-10, -5) is 10 m west of it.
    lat, lon, _ = geo.to_lla(-10.0, -10.0, 0.0)
    assert (plan.items[0].x, plan.items[0].y) == (round(lat * 1e7), round(lon * 1e7))
    params = dict(plan.params)
    assert params["FENCE_TYPE"] == FENCE_TYPE_POLYGON | FENCE_TYPE_ALT_MAX
    assert params["FENCE_ALT_MAX"] == 12.0 and params["FENCE_ENABLE"] == 1.0
    assert [n for n, _ in plan.params][-1] == "FENCE_ENABLE"  # turned on last
    px4 = fence_plan("px4", square, None, (0.0, 0.0), geo)
    assert len(px4.items) == 4 and dict(px4.params) == {"GF_ACTION": 2.0}
    ceiling_only = fence_plan("ardupilot", [], 30.0, (0.0, 0.0), geo)
    assert ceiling_only.items == () and dict(ceiling_only.params)["FENCE_TYPE"] == 1.0


def test_fence_and_home_settings_are_validated():
    s = MavlinkSettings.from_mapping(
        {
            "connection": "udpin:127.0.0.1:14540",
            "home_m": [0, 5],
            "home_lla": [-35.36, 149.16],
            "geofence_m": [[0, 0], [0, 10], [10, 10]],
            "max_altitude_m": 30,
        }
    )
    assert s.home_m == (0.0, 5.0) and s.geofence_m[2] == (10.0, 10.0) and s.fence
    for bad in ({"geofence_m": [[0, 0], [1, 1]]}, {"home_m": [1]}, {"geofence_m": "x"}):
        with pytest.raises(Exception, match=r"hal\.(geofence_m|home_m)"):
            MavlinkSettings.from_mapping({"connection": "udpin:127.0.0.1:14540", **bad})
    assert MavlinkSettings.from_mapping(
        {"connection": "udpin:127.0.0.1:14540", "signing": "off"}
    ).signing == ("off")


def test_a_vehicle_home_far_from_the_fleets_home_lla_is_told():
    assert check_home((-35.363261, 149.165230, 584.0), None) == ""
    assert check_home((-35.363261, 149.165230, 584.0), (-35.363262, 149.165231)) == ""
    note = check_home((-35.363261, 149.165230, 584.0), (-35.3632, 149.1652))
    assert "m from the fleet's home_lla" in note


# -- the uniform API's gate ------------------------------------------------------------------------


class PilotsAdapter:
    """An adapter whose vehicle a pilot took: any call that would command it is a failure."""

    drone = "D2"
    family = "mavlink"
    plugins = EMPTY_PLUGINS

    def __init__(self) -> None:
        self.taken_over = TakenOver("LOITER", 1.0, 2.0, 1.5)
        self.calls: list[str] = []
        self._notices = [AdapterNotice("taken_over", "taken over by the pilot in LOITER")]

    def start(self, on_telemetry: Any) -> None: ...

    def run(self, command: Command, done: Any) -> ActionHandle:
        self.calls.append("run")
        raise AssertionError("commanded a vehicle a pilot has")

    def cancel(self, handle: ActionHandle) -> None:
        self.calls.append("cancel")

    def abort(self) -> None:
        self.calls.append("abort")

    def close(self) -> None:
        self.calls.append("close")

    def notices(self) -> list[AdapterNotice]:
        out, self._notices = self._notices, []
        return out

    def facts(self) -> dict[str, Any]:
        return {"signed": True, "taken_over": self.taken_over.to_json()}


class Inbox:
    def __init__(self) -> None:
        self.got: list[ActionFinished] = []

    def tell(self, message: ActionFinished) -> None:
        self.got.append(message)


def test_the_uniform_api_never_commands_a_vehicle_a_pilot_has(tmp_path):
    adapter = PilotsAdapter()
    log = make_logger(tmp_path / "uniform.log")
    space = UniformSpace(adapter, log)
    told: list[AdapterNotice] = []
    space.on_notice = told.append
    inbox = Inbox()
    finished = space.run(RunAction(1, "Land", (), inbox))  # type: ignore[arg-type]
    assert finished is not None
    assert finished.result == ActionResult("failed", "taken over by the pilot (LOITER)")
    space.abort()
    space.cancel(1)
    assert adapter.calls == []  # no run, no abort (no landing), no cancel (no braking)
    assert [n.kind for n in told] == ["taken_over"]
    assert taken_over(adapter) == adapter.taken_over
    assert vehicle_facts(adapter)["signed"] is True and adapter_notices(adapter) == []


# -- what the operator reads ----------------------------------------------------------------------


def report_with(vehicle: dict[str, Any]) -> DroneReport:
    return DroneReport(
        ok=False,
        resolved=True,
        aborted=False,
        abort_reason="",
        triggers_sent=0,
        triggers_received=0,
        external_out=0,
        external_in=0,
        mdg={},
        blocked_nodes=(),
        actions=(),
        final=None,
        vehicle=vehicle,
    )


def test_the_summary_names_the_pilots_mode_and_where_and_whether_the_link_was_signed():
    taken = TakenOver("LOITER", 1.0, 2.0, 1.5)
    report = report_with({"signed": False, "taken_over": taken.to_json()})
    again = DroneReport.from_json(report.to_json())
    assert again.vehicle == report.vehicle
    result = DroneResult(again)
    assert not result.ok and result.signed is False
    assert result.taken_over == taken
    assert taken.describe() == "taken over by the pilot in LOITER at (1.00, 2.00, 1.50)"
    assert "vehicle" not in report_with({}).to_json()  # absent for simulated drones


def test_the_display_prints_a_takeover_and_a_warning():
    taken = wire.Progress(
        mission="m",
        sender="D2",
        state="taken_over",
        node="",
        action="the pilot has the vehicle",
        detail={"detail": "taken over by the pilot in LOITER at (1.00, 2.00, 1.50)"},
    )
    line = format_event("D2", taken, 0.0)
    assert line is not None and "TAKEN OVER: taken over by the pilot in LOITER" in line
    warning = wire.Progress(
        mission="m",
        sender="D2",
        state="warning",
        node="",
        action="adapter warning",
        detail={"detail": "LOCAL_POSITION_NED arrives at 1 Hz"},
    )
    shown = format_event("D2", warning, 0.0)
    assert shown is not None and "warning" in shown and "1 Hz" in shown


def test_the_failsafe_grace_is_never_shorter_than_its_wall_floor():
    # At a speed-up of 10 the 1.5 vehicle seconds are 0.15 s of wall time: a loaded
    # machine's SITL sent the fence breach's STATUSTEXT later than that.
    fast = takeover_watch(
        MavlinkSettings.from_mapping({"connection": "udpin:0.0.0.0:1", "speedup": 10})
    )
    assert fast.grace_s == FAILSAFE_GRACE_MIN_S
    real = takeover_watch(MavlinkSettings.from_mapping({"connection": "udpin:0.0.0.0:1"}))
    assert real.grace_s == FAILSAFE_GRACE_S
