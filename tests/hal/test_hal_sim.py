"""SimAdapter: flights, rules, cancel/abort, pilot, telemetry, settings and logs.

Most tests run at speedup 20 (a 5 m takeoff takes ~0.3 s of wall time).
"""

from __future__ import annotations

import itertools
import math
import time
from pathlib import Path
from typing import Any

import pytest

from eamos.hal import ADAPTERS, AdapterError, make_adapter
from eamos.hal.api import POSITION_LOG_HZ
from eamos.hal.fake import FakeAdapter
from eamos.hal.kinematics import GeoFrame
from eamos.hal.sim.adapter import SimAdapter, SimSettings, Waypoint
from eamos.hal.station_adapter import GroundAdapter
from eamos.logs import make_logger, read_log
from tests.support.sim_fixtures import SimFactory

from .hal_helpers import WAIT_S, Done, TelemetrySink, cmd, do

# Generous for a loaded 2-core machine; a healthy run takes seconds.
pytestmark = pytest.mark.timeout(180)


def near(adapter: SimAdapter, x: float, y: float, z: float, tol: float) -> bool:
    s = adapter.state
    return math.dist((s.x_m, s.y_m, s.z_m), (x, y, z)) <= tol


def airborne(make_sim: SimFactory, height: float = 5.0, **settings: Any) -> SimAdapter:
    sim = make_sim(**settings)
    sim.start(TelemetrySink())
    assert do(sim, "Arm").ok
    assert do(sim, "Takeoff", height).ok
    return sim


# -- flights ---------------------------------------------------------------


def test_square_mission_ends_where_it_started(make_sim: SimFactory) -> None:
    sim = make_sim()
    sink = TelemetrySink()
    sim.start(sink)
    tol = sim.settings.tolerance_m
    assert do(sim, "Arm").ok
    assert sim.state.armed
    assert do(sim, "Takeoff", 5.0).ok
    assert near(sim, 0, 0, 5, tol)
    corners = [(10, 0), (10, 10), (0, 10), (0, 0)]
    legs = [("FlyByX", 10.0), ("FlyByY", 10.0), ("FlyByX", -10.0), ("FlyByY", -10.0)]
    for (action, dist), (x, y) in zip(legs, corners, strict=True):
        assert do(sim, action, dist).ok, action
        assert near(sim, x, y, 5, tol), (action, sim.state)
    assert do(sim, "Land").ok
    s = sim.state
    assert s.landed and s.z_m == 0.0 and math.hypot(s.x_m, s.y_m) <= tol
    assert do(sim, "Disarm").ok
    assert not sim.state.armed
    # The sample showing the disarm may follow the answer (the same step, sent after it).
    assert sink.wait_last(lambda last: last.landed and not last.armed, WAIT_S)
    # Telemetry followed the flight: it went up to 5 m and reached every corner.
    samples = sink.snapshot()
    assert max(t.z_m for t in samples) == pytest.approx(5.0, abs=tol)
    for x, y in corners:
        assert min(math.hypot(t.x_m - x, t.y_m - y) for t in samples) <= 0.15
    assert samples[-1].landed and not samples[-1].armed


def test_fly_to_xyz_and_lla(make_sim: SimFactory) -> None:
    sim = airborne(make_sim, 3.0)
    tol = sim.settings.tolerance_m
    assert do(sim, "FlyToXYZ", 4.0, -3.0, 6.0).ok
    assert near(sim, 4, -3, 6, tol)
    lat, lon, alt = GeoFrame().to_lla(-5.0, 2.0, 4.0)
    assert do(sim, "FlyToLLA", lat, lon, alt).ok
    assert near(sim, -5, 2, 4, tol)
    assert do(sim, "FlyByZ", 2.0).ok
    assert near(sim, -5, 2, 6, tol)


def test_telemetry_carries_lat_lon_of_the_position(make_sim: SimFactory) -> None:
    sim = make_sim(home_lat_deg=47.0, home_lon_deg=15.0, home_alt_m=400.0)
    sink = TelemetrySink()
    sim.start(sink)
    do(sim, "Arm")
    do(sim, "Takeoff", 2.0)
    do(sim, "FlyByX", 5.0)
    last = sink.wait_for(1)[-1]
    frame = GeoFrame(47.0, 15.0, 400.0)
    lat, lon, _ = frame.to_lla(last.x_m, last.y_m, last.z_m)
    assert (last.lat_deg, last.lon_deg) == pytest.approx((lat, lon), abs=2e-7)
    assert last.alt_m == pytest.approx(last.z_m)  # Alt is above home (uniform API)
    assert last.drone == "D1" and abs(last.time_s - time.time()) < WAIT_S


def test_payload_actions_complete(make_sim: SimFactory) -> None:
    sim = make_sim()
    sim.start(TelemetrySink())
    for action in ("TurnOn", "PreFlightCheck", "Calibrate", "TurnOnCamera", "AdjustCamera"):
        assert do(sim, action).ok, action


def test_arm_waits_until_armable(make_sim: SimFactory) -> None:
    sim = make_sim(arm_delay_s=3.0)
    sim.start(TelemetrySink())
    done = Done()
    sim.run(cmd("Arm"), done)
    assert done.wait().ok
    assert sim.sim_time_s >= 3.0


def test_arm_times_out_when_never_armable(make_sim: SimFactory) -> None:
    sim = make_sim(arm_delay_s=50.0, action_timeout_s=1.0)
    sim.start(TelemetrySink())
    result = do(sim, "Arm")
    assert result.status == "failed" and "timeout" in result.reason
    assert not sim.state.armed


# -- rules -----------------------------------------------------------------


def test_takeoff_unarmed_fails(make_sim: SimFactory) -> None:
    sim = make_sim()
    sim.start(TelemetrySink())
    assert do(sim, "Takeoff", 5.0) == _failed("not armed")
    assert sim.state.landed


def test_fly_on_the_ground_fails(make_sim: SimFactory) -> None:
    sim = make_sim()
    sim.start(TelemetrySink())
    do(sim, "Arm")
    for action, args in [("FlyByX", (3.0,)), ("FlyByZ", (3.0,)), ("FlyToXYZ", (1.0, 1.0, 2.0))]:
        assert do(sim, action, *args) == _failed("not flying"), action


def test_disarm_in_the_air_fails_and_on_the_ground_succeeds(make_sim: SimFactory) -> None:
    sim = airborne(make_sim)
    assert do(sim, "Disarm") == _failed("in the air")
    assert sim.state.armed
    assert do(sim, "Land").ok
    assert do(sim, "Disarm").ok
    assert do(sim, "Disarm").ok  # already disarmed: fine


def test_land_on_the_ground_is_ok(make_sim: SimFactory) -> None:
    sim = make_sim()
    sim.start(TelemetrySink())
    assert do(sim, "Land").ok


def test_rejected_actions(make_sim: SimFactory) -> None:
    sim = make_sim(reject_actions=["Takeoff", "Calibrate"])
    sim.start(TelemetrySink())
    assert do(sim, "Arm").ok
    assert do(sim, "Takeoff", 5.0) == _failed("rejected by vehicle")
    assert do(sim, "Calibrate") == _failed("rejected by vehicle")
    assert sim.state.landed


def test_second_motion_action_is_busy(make_sim: SimFactory) -> None:
    sim = airborne(make_sim)
    first = Done()
    sim.run(cmd("FlyByX", 10.0), first)
    assert do(sim, "FlyByY", 5.0) == _failed("busy")
    # A non-motion action runs alongside.
    assert do(sim, "PauseFor", 0.5).ok
    assert first.wait().ok
    assert near(sim, 10, 0, 5, sim.settings.tolerance_m)


def test_bad_calls_fail_with_a_reason(make_sim: SimFactory) -> None:
    # Unknown actions and bad argument lists never reach an adapter: the
    # uniform-API actor decodes every call (tests/actors/test_uniform_api.py).
    sim = airborne(make_sim)
    assert "not above ground" in do(sim, "FlyByZ", -10.0).reason
    assert "not above ground" in do(sim, "FlyToXYZ", 0.0, 0.0, 0.0).reason
    assert "duration_s" in do(sim, "PauseFor", -1.0).reason
    assert near(sim, 0, 0, 5, sim.settings.tolerance_m)


def test_motion_times_out(make_sim: SimFactory) -> None:
    sim = airborne(make_sim, 2.0, action_timeout_s=4.0)
    result = do(sim, "FlyByX", 50.0)
    assert result.status == "failed" and "timeout after 4 s" in result.reason
    # It holds where the timeout caught it (~7 m) instead of flying on to 50 m.
    assert sim.wait_until(lambda s: s.speed_mps == 0.0, WAIT_S)
    assert 3.0 < sim.state.x_m < 12.0


def _failed(reason: str) -> Any:
    from eamos.hal.api import ActionResult

    return ActionResult("failed", reason)


# -- cancel and abort --------------------------------------------------------


def test_cancel_holds_position(make_sim: SimFactory, tmp_path: Path) -> None:
    sim = airborne(make_sim)
    done = Done()
    handle = sim.run(cmd("FlyByX", 30.0), done)
    assert sim.wait_until(lambda s: s.x_m >= 4.0, WAIT_S)
    sim.cancel(handle)
    assert done.wait().status == "cancelled"
    # Where the vehicle was when the simulator processed the cancel.
    end = [e for e in read_log(tmp_path / "D1-adapter.log") if e["event"] == "adapter.action.end"]
    assert end[-1]["action"] == "FlyByX" and end[-1]["status"] == "cancelled"
    x_cancel = end[-1]["x_m"]
    assert 4.0 <= x_cancel < 25.0
    # It brakes (overshooting by up to v^2 / 2a = 1 m), comes back there and stays.
    assert sim.wait_until(lambda s: s.speed_mps == 0.0 and abs(s.x_m - x_cancel) < 0.01, WAIT_S)
    assert do(sim, "PauseFor", 2.0).ok
    s = sim.state
    assert abs(s.x_m - x_cancel) < 0.01 and s.speed_mps == 0.0
    assert s.z_m == pytest.approx(5.0, abs=0.1) and not s.landed
    sim.cancel(handle)  # cancelling a finished action does nothing
    assert done.calls == 1
    assert do(sim, "FlyByY", 2.0).ok  # and the motion slot is free again


def test_cancel_pause(make_sim: SimFactory) -> None:
    sim = make_sim()
    sim.start(TelemetrySink())
    done = Done()
    handle = sim.run(cmd("PauseFor", 10_000.0), done)
    sim.cancel(handle)
    assert done.wait().status == "cancelled"


def test_abort_lands_and_disarms(make_sim: SimFactory) -> None:
    sim = airborne(make_sim, 8.0)
    fly, pause = Done(), Done()
    sim.run(cmd("FlyByX", 30.0), fly)
    sim.run(cmd("PauseFor", 10_000.0), pause)
    assert sim.wait_until(lambda s: s.x_m >= 2.0, WAIT_S)
    sim.abort()
    assert fly.wait().status == "cancelled"
    assert pause.wait().status == "cancelled"
    assert sim.wait_until(lambda s: s.landed and not s.armed, WAIT_S)
    assert 2.0 <= sim.state.x_m < 25.0  # landed on the way, not at 30 m
    # After the abort the vehicle can fly again.
    assert do(sim, "Arm").ok
    assert do(sim, "Takeoff", 2.0).ok


def test_abort_on_the_ground_disarms(make_sim: SimFactory) -> None:
    sim = make_sim()
    sim.start(TelemetrySink())
    do(sim, "Arm")
    sim.abort()
    assert sim.wait_until(lambda s: not s.armed, WAIT_S)


def test_close_cancels_running_actions_and_is_idempotent(make_sim: SimFactory) -> None:
    sim = make_sim()
    sim.start(TelemetrySink())
    done = Done()
    sim.run(cmd("PauseFor", 10_000.0), done)
    sim.close()
    assert done.wait().status == "cancelled"
    sim.close()
    with pytest.raises(AdapterError):
        sim.run(cmd("Arm"), Done())
    with pytest.raises(AdapterError):
        sim.start(TelemetrySink())


# -- time ------------------------------------------------------------------


def _pause_wall_s(make_sim: SimFactory, speedup: float, duration: float) -> float:
    sim = make_sim(drone=f"P{int(speedup)}", speedup=speedup)
    sim.start(TelemetrySink())
    t0 = time.monotonic()
    sim_t0 = sim.sim_time_s
    done = Done()
    sim.run(cmd("PauseFor", duration), done)
    assert done.wait().ok
    assert done.at is not None
    # Counted in simulated steps: the simulated duration is exact up to a tick.
    assert sim.sim_time_s - sim_t0 >= duration - 1e-6
    return done.at - t0


def test_pause_duration_scales_with_speedup(make_sim: SimFactory) -> None:
    fast = _pause_wall_s(make_sim, 40.0, 20.0)  # 0.5 s of wall time
    slow = _pause_wall_s(make_sim, 10.0, 20.0)  # 2.0 s of wall time
    # Loose bounds: the machine may be loaded, which only ever slows the sim.
    assert 0.5 * 0.8 <= fast < 0.5 + 5.0
    assert 2.0 * 0.9 <= slow < 2.0 + 5.0
    assert slow > fast


def test_real_time_pause(make_sim: SimFactory) -> None:
    wall = _pause_wall_s(make_sim, 1.0, 0.5)
    assert 0.4 <= wall < 5.0


# -- scripted pilot --------------------------------------------------------

PILOT = [
    # The long first hold keeps the pilot flying while the test checks deferral.
    {"x_m": 6.0, "y_m": 0.0, "z_m": 5.0, "hold_s": 10.0},
    {"x_m": 6.0, "y_m": 6.0, "z_m": 7.0, "hold_s": 2.0},
    {"x_m": 0.0, "y_m": 6.0, "z_m": 4.0},
]


def test_pilot_flies_its_path_then_mission_motion_runs(
    make_sim: SimFactory, tmp_path: Path
) -> None:
    sim = make_sim(drone="D3", pilot=PILOT)
    sink = TelemetrySink()
    sim.start(sink)
    assert do(sim, "Arm").ok
    assert not sim.pilot_flying
    assert do(sim, "Takeoff", 3.0).ok
    assert sim.pilot_flying
    fly, pause = Done(), Done()
    sim.run(cmd("FlyToXYZ", 1.0, 1.0, 2.0), fly)
    sim.run(cmd("PauseFor", 0.5), pause)
    # Non-motion actions run while the pilot flies; motion waits for the path.
    assert pause.wait().ok
    assert not fly.is_done and sim.pilot_flying
    assert do(sim, "FlyByX", 1.0) == _failed("busy")  # the slot is taken by the deferred one
    assert fly.wait().ok
    assert not sim.pilot_flying
    assert near(sim, 1, 1, 2, sim.settings.tolerance_m)

    # The telemetry visited every waypoint, in order, before the mission's target.
    samples = sink.snapshot()

    def first_visit(x: float, y: float, z: float, after: int = 0) -> int:
        for i, t in enumerate(samples[after:], start=after):
            if math.dist((t.x_m, t.y_m, t.z_m), (x, y, z)) <= 0.15:
                return i
        raise AssertionError(f"({x}, {y}, {z}) never visited")

    i = 0
    for wp in PILOT:
        i = first_visit(wp["x_m"], wp["y_m"], wp["z_m"], i)
    first_visit(1.0, 1.0, 2.0, i)

    log = read_log(tmp_path / "D3-adapter.log")
    events = [(e["event"], e.get("action"), e.get("index")) for e in log]
    order = [
        ("adapter.pilot.start", None, None),
        ("adapter.pilot.waypoint", None, 0),
        ("adapter.pilot.waypoint", None, 1),
        ("adapter.pilot.waypoint", None, 2),
        ("adapter.pilot.end", None, None),
        ("adapter.action.end", "FlyToXYZ", None),
    ]
    positions = [events.index(e) for e in order]
    assert positions == sorted(positions)
    assert ("adapter.action.deferred", "FlyToXYZ", None) in events
    # The pilot holds at each waypoint for hold_s (simulated seconds).
    waypoints = [e for e in log if e["event"] == "adapter.pilot.waypoint"]
    assert waypoints[1]["t_sim"] - waypoints[0]["t_sim"] >= 10.0
    assert waypoints[2]["t_sim"] - waypoints[1]["t_sim"] >= 2.0


def test_abort_takes_control_from_the_pilot(make_sim: SimFactory) -> None:
    sim = make_sim(drone="D3", pilot=PILOT)
    sim.start(TelemetrySink())
    do(sim, "Arm")
    do(sim, "Takeoff", 3.0)
    land = Done()
    sim.run(cmd("Land"), land)
    sim.abort()
    assert land.wait().status == "cancelled"
    assert not sim.pilot_flying
    assert sim.wait_until(lambda s: s.landed and not s.armed, WAIT_S)


# -- telemetry -------------------------------------------------------------


def test_telemetry_only_on_change(make_sim: SimFactory) -> None:
    sim = make_sim(drain_airborne_pct_per_min=0, drain_idle_pct_per_min=0, telemetry_hz=10)
    sink = TelemetrySink()
    sim.start(sink)
    assert sink.count() == 1  # one sample right at start, synchronously
    assert do(sim, "PauseFor", 3.0).ok
    assert sink.count() == 1  # standing still: nothing new
    assert do(sim, "Arm").ok
    assert sink.wait_for(2)[-1].armed
    assert do(sim, "PauseFor", 2.0).ok
    assert sink.count() == 2
    t0 = sim.sim_time_s
    assert do(sim, "Takeoff", 5.0).ok
    assert do(sim, "PauseFor", 2.0).ok  # let it settle exactly
    climbing = sink.count() - 2
    # Climbing changes every sample, but never faster than telemetry_hz.
    assert 10 <= climbing <= (sim.sim_time_s - t0) * 10 + 1
    hovering = sink.count()
    assert do(sim, "PauseFor", 3.0).ok
    assert sink.count() == hovering  # hovering at rest: nothing new
    zs = [t.z_m for t in sink.snapshot()]
    assert zs == sorted(zs)


def test_battery_drain_shows_in_telemetry(make_sim: SimFactory) -> None:
    sim = make_sim(drain_idle_pct_per_min=30.0, battery_pct=50)
    sink = TelemetrySink()
    sim.start(sink)
    assert sink.snapshot()[0].battery_pct == 50.0
    assert do(sim, "PauseFor", 4.0).ok
    assert sink.snapshot()[-1].battery_pct == pytest.approx(48.0, abs=0.2)


# -- settings ----------------------------------------------------------------


def test_defaults() -> None:
    s = SimSettings.from_mapping({"adapter": "sim"})
    assert s == SimSettings()
    assert (s.speedup, s.horizontal_speed_mps, s.climb_speed_mps, s.descent_speed_mps) == (
        1.0,
        2.0,
        1.0,
        0.7,
    )
    assert (s.accel_mps2, s.tolerance_m, s.settle_speed_mps, s.arm_delay_s) == (2.0, 0.1, 0.2, 2.0)
    assert (s.telemetry_hz, s.battery_pct, s.action_timeout_s) == (10.0, 100.0, 120.0)
    assert (s.home_lat_deg, s.home_lon_deg, s.home_alt_m) == (46.6103, 14.2640, 0.0)


def test_settings_are_parsed() -> None:
    s = SimSettings.from_mapping(
        {"speedup": 5, "reject_actions": ["Land"], "pilot": [{"x_m": 1, "y_m": 2, "z_m": 3}]}
    )
    assert s.speedup == 5.0 and isinstance(s.speedup, float)
    assert s.reject_actions == ("Land",)
    assert s.pilot == (Waypoint(1.0, 2.0, 3.0, 0.0),)


@pytest.mark.parametrize(
    ("mapping", "field", "fragment"),
    [
        ({"speedup": 0}, "hal.speedup", "> 0"),
        ({"speedup": -2.5}, "hal.speedup", "> 0"),
        ({"speedup": "fast"}, "hal.speedup", "number"),
        ({"speedup": True}, "hal.speedup", "number"),
        ({"speedup": math.inf}, "hal.speedup", "finite"),
        ({"spedup": 2}, "hal.spedup", "did you mean 'speedup'"),
        ({"tolerance": 0.2}, "hal.tolerance", "did you mean 'tolerance_m'"),
        ({"battery_pct": 150}, "hal.battery_pct", "<= 100"),
        ({"home_lat_deg": 91}, "hal.home_lat_deg", "<= 90"),
        ({"arm_delay_s": -1}, "hal.arm_delay_s", ">= 0"),
        ({"telemetry_hz": 0}, "hal.telemetry_hz", ">= 0.1"),
        ({"telemetry_hz": 1e308}, "hal.telemetry_hz", "<= 50"),
        ({"accel_mps2": 1e308}, "hal.accel_mps2", "<= 50"),
        ({"accel_mps2": 1e-9}, "hal.accel_mps2", ">= 0.1"),
        ({"climb_speed_mps": 1e-9}, "hal.climb_speed_mps", ">= 0.05"),
        ({"reject_actions": "Land"}, "hal.reject_actions", "list"),
        ({"reject_actions": ["Lnd"]}, "hal.reject_actions[0]", "did you mean 'Land'"),
        ({"pilot": {"x_m": 1}}, "hal.pilot", "list"),
        ({"pilot": [{"x_m": 1, "y_m": 2}]}, "hal.pilot[0].z_m", "missing"),
        ({"pilot": [{"x_m": 1, "y_m": 2, "z_m": 0}]}, "hal.pilot[0].z_m", "> 0"),
        (
            {"pilot": [{"x_m": 1, "y_m": 1, "z_m": 1, "hold": 1}]},
            "hal.pilot[0].hold",
            "did you mean 'hold_s'",
        ),
        ({"pilot": [{"x_m": 1, "y_m": 1, "z_m": 1}, 5]}, "hal.pilot[1]", "mapping"),
    ],
)
def test_settings_errors_name_the_field(mapping: dict[str, Any], field: str, fragment: str) -> None:
    with pytest.raises(AdapterError) as info:
        SimSettings.from_mapping(mapping)
    message = str(info.value)
    assert message.startswith(f"{field}: "), message
    assert fragment in message


# -- make_adapter ------------------------------------------------------------


def test_make_adapter_picks_by_name(tmp_path: Path) -> None:
    log = make_logger(None)
    assert set(ADAPTERS) >= {"sim", "ground", "fake"}
    sim = make_adapter("D1", {"adapter": "sim", "speedup": 3}, log)
    assert isinstance(sim, SimAdapter) and sim.settings.speedup == 3.0 and sim.drone == "D1"
    assert isinstance(make_adapter("GCS", {"adapter": "ground"}, log), GroundAdapter)
    fake = make_adapter("D2", {"adapter": "fake"}, log)
    assert isinstance(fake, FakeAdapter) and fake.auto
    for adapter in (sim, fake):
        adapter.close()


@pytest.mark.parametrize(
    ("settings", "fragment"),
    [
        ({"adapter": "simulator"}, "unknown adapter 'simulator'"),
        ({"adapter": "sin"}, "did you mean 'sim'"),
        ({}, "missing"),
        ({"adapter": 3}, "unknown adapter 3"),
    ],
)
def test_make_adapter_rejects_unknown_kinds(settings: dict[str, Any], fragment: str) -> None:
    with pytest.raises(AdapterError) as info:
        make_adapter("D1", settings, make_logger(None))
    message = str(info.value)
    assert message.startswith("hal.adapter: ") and fragment in message
    assert "fake, ground, mavlink, sim" in message


def test_make_adapter_validates_adapter_settings() -> None:
    with pytest.raises(AdapterError, match=r"^hal\.speedup: "):
        make_adapter("D1", {"adapter": "sim", "speedup": 0}, make_logger(None))
    with pytest.raises(AdapterError, match=r"^hal\.pilot: "):
        make_adapter("GCS", {"adapter": "ground", "pilot": []}, make_logger(None))


# -- logs ------------------------------------------------------------------


def test_adapter_log_is_json_lines(make_sim: SimFactory, tmp_path: Path) -> None:
    sim = airborne(make_sim)
    do(sim, "FlyByX", 3.0)
    do(sim, "Takeoff", -1.0)
    sim.close()
    path = tmp_path / "D1-adapter.log"
    lines = path.read_text(encoding="utf-8").splitlines()
    log = read_log(path)
    assert len(log) == len(lines) > 0
    assert all(e["drone"] == "D1" and "ts" in e for e in log)
    names = [e["event"] for e in log]
    assert names[0] == "adapter.start" and names[-1] == "adapter.close"
    starts = [e for e in log if e["event"] == "adapter.action.start"]
    ends = [e for e in log if e["event"] == "adapter.action.end"]
    assert [e["action"] for e in starts] == ["Arm", "Takeoff", "FlyByX", "Takeoff"]
    assert [e["action"] for e in ends] == ["Arm", "Takeoff", "FlyByX", "Takeoff"]
    assert ends[2]["status"] == "ok" and ends[2]["args"] == [3.0]
    assert ends[3]["status"] == "failed" and ends[3]["reason"]
    positions = [e for e in log if e["event"] == "adapter.position"]
    assert len(positions) >= 3
    assert max(p["z_m"] for p in positions) == pytest.approx(5.0, abs=0.1)
    # POSITION_LOG_HZ (5 Hz) of simulated time, and only while something changes.
    t_sims = [p["t_sim"] for p in positions]
    period = 1.0 / POSITION_LOG_HZ
    assert all(b - a >= period - 0.01 for a, b in itertools.pairwise(t_sims))
    assert any(b - a == pytest.approx(period, abs=0.01) for a, b in itertools.pairwise(t_sims))


def test_the_telemetry_rate_bound_is_one_sample_per_simulator_step() -> None:
    from eamos.hal.sim.actions import SIM_DT_S
    from eamos.hal.sim.settings import SIM_STEP_S

    assert SIM_STEP_S == SIM_DT_S
    assert SimSettings.from_mapping({"telemetry_hz": 1 / SIM_DT_S}).telemetry_hz == 50
