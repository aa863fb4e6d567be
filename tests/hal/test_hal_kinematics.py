"""Unit tests of the pure kinematic quadcopter model and the geo frame."""

from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from eamos.hal.kinematics import GeoFrame, Limits, Quadcopter

DT = 0.02
EPS = 1e-9


def fly(q: Quadcopter, max_s: float = 300.0) -> dict[str, float]:
    """Step until the vehicle rests at its target (or landed); return observed extremes."""
    seen = {"t": 0.0, "max_h": 0.0, "max_up": 0.0, "max_down": 0.0, "max_acc": 0.0}
    prev = q.state
    start, target = q.position, q.target
    seen["overshoot"] = 0.0
    while seen["t"] < max_s:
        q.step(DT)
        seen["t"] += DT
        s = q.state
        seen["max_h"] = max(seen["max_h"], s.horizontal_speed_mps)
        seen["max_up"] = max(seen["max_up"], s.vz_mps)
        seen["max_down"] = max(seen["max_down"], -s.vz_mps)
        # Horizontal acceleration is limited as a vector, vertical separately.
        dvh = math.hypot(s.vx_mps - prev.vx_mps, s.vy_mps - prev.vy_mps) / DT
        dvz = abs(s.vz_mps - prev.vz_mps) / DT
        seen["max_acc"] = max(seen["max_acc"], dvh, dvz)
        if target is not None:
            # Overshoot: progress along the start->target line beyond the target.
            line = [t - a for t, a in zip(target, start, strict=True)]
            length = math.sqrt(sum(c * c for c in line))
            if length > 0:
                along = sum((p - a) * c for p, a, c in zip(q.position, start, line, strict=True))
                seen["overshoot"] = max(seen["overshoot"], along / length - length)
        prev = s
        if s.speed_mps == 0.0 and (q.landed or q.target is None or q.distance_to(q.target) < 1e-6):
            break
    return seen


def airborne(z: float = 5.0) -> Quadcopter:
    q = Quadcopter()
    q.arm()
    q.set_target(0.0, 0.0, z)
    fly(q)
    return q


def test_starts_on_the_ground_disarmed_and_full() -> None:
    s = Quadcopter().state
    assert (s.x_m, s.y_m, s.z_m) == (0.0, 0.0, 0.0)
    assert not s.armed and s.landed and s.battery_pct == 100.0


def test_takeoff_respects_climb_speed_and_reaches_height() -> None:
    q = Quadcopter()
    q.arm()
    q.set_target(0.0, 0.0, 10.0)
    seen = fly(q)
    assert q.position == pytest.approx((0.0, 0.0, 10.0), abs=1e-6)
    assert not q.landed
    assert seen["max_up"] <= 1.0 + EPS
    assert seen["max_acc"] <= 2.0 + 1e-6
    assert seen["overshoot"] <= 0.01
    # Trapezoid: 10 m at 1 m/s with 2 m/s^2 ramps takes d/v + v/a = 10.5 s.
    assert seen["t"] == pytest.approx(10.5, abs=0.3)


def test_horizontal_leg_is_trapezoidal_within_limits() -> None:
    q = airborne()
    q.set_target(10.0, 0.0, 5.0)
    seen = fly(q)
    assert q.position == pytest.approx((10.0, 0.0, 5.0), abs=1e-6)
    assert seen["max_h"] == pytest.approx(2.0, abs=1e-6)  # cruises at the limit
    assert seen["max_acc"] <= 2.0 + 1e-6
    assert seen["overshoot"] <= 0.01
    assert seen["t"] == pytest.approx(10.0 / 2.0 + 2.0 / 2.0, abs=0.3)


def test_descent_is_slower_than_climb() -> None:
    q = airborne(10.0)
    q.set_target(0.0, 0.0, 3.0)
    seen = fly(q)
    assert seen["max_down"] == pytest.approx(0.7, abs=1e-6)
    assert seen["max_up"] <= EPS
    assert q.position[2] == pytest.approx(3.0, abs=1e-6)


def test_short_hop_never_reaches_cruise_speed() -> None:
    q = airborne()
    q.set_target(0.5, 0.0, 5.0)
    seen = fly(q)
    # Triangle profile: peak speed sqrt(a d) = 1 m/s for 0.5 m at 2 m/s^2.
    assert seen["max_h"] <= 1.0 + 0.05
    assert q.position[0] == pytest.approx(0.5, abs=1e-6)


def test_landing_clamps_to_the_ground() -> None:
    q = airborne(3.0)
    q.set_target(4.0, -2.0, 3.0)
    fly(q)
    q.land()
    seen = fly(q)
    s = q.state
    assert s.landed and s.z_m == 0.0 and s.speed_mps == 0.0
    assert (s.x_m, s.y_m) == pytest.approx((4.0, -2.0), abs=1e-6)
    assert seen["max_down"] <= 0.7 + EPS
    assert q.target is None and s.armed  # landing does not disarm


def test_target_below_ground_is_clamped_and_lands() -> None:
    q = airborne(2.0)
    q.set_target(0.0, 0.0, -5.0)
    assert q.target == (0.0, 0.0, 0.0)
    fly(q)
    assert q.landed and q.position[2] == 0.0


def test_does_not_move_unarmed_or_without_a_climb_target() -> None:
    q = Quadcopter()
    q.set_target(0.0, 0.0, 5.0)
    for _ in range(100):
        q.step(DT)
    assert q.position == (0.0, 0.0, 0.0) and q.landed
    q.arm()
    q.set_target(5.0, 0.0, 0.0)  # sliding along the ground is not flying
    for _ in range(100):
        q.step(DT)
    assert q.position == (0.0, 0.0, 0.0) and q.landed


def test_disarm_in_the_air_is_refused() -> None:
    q = airborne()
    with pytest.raises(ValueError, match="in the air"):
        q.disarm()
    q.land()
    fly(q)
    q.disarm()
    assert not q.armed


def test_hold_brakes_and_returns_to_where_it_was_told() -> None:
    q = airborne()
    q.set_target(20.0, 0.0, 5.0)
    for _ in range(200):  # 4 s: cruising at 2 m/s
        q.step(DT)
    here = q.position
    q.hold()
    seen = fly(q)
    assert q.position == pytest.approx(here, abs=1e-6)
    assert seen["max_acc"] <= 2.0 + 1e-6


def test_battery_drains_airborne_and_idle() -> None:
    q = Quadcopter()
    for _ in range(int(60 / DT)):
        q.step(DT)
    assert q.battery_pct == pytest.approx(100.0 - 0.1, abs=1e-6)
    q = airborne(2.0)
    before = q.battery_pct
    for _ in range(int(60 / DT)):
        q.step(DT)
    # A hover: the hover rate alone (no speed, no climb).
    assert before - q.battery_pct == pytest.approx(Limits().drain_airborne_pct_per_min, abs=1e-6)


def test_battery_drains_more_with_speed_and_climb() -> None:
    """The load model: cruising at 2 m/s and climbing cost more than hovering."""
    lim = Limits()
    hover = airborne(2.0)
    cruise = airborne(2.0)
    cruise.set_target(1000.0, 0.0, 2.0)
    for _ in range(int(10 / DT)):  # reach cruise speed
        cruise.step(DT)
    h0, c0 = hover.battery_pct, cruise.battery_pct
    for _ in range(int(60 / DT)):
        hover.step(DT)
        cruise.step(DT)
    assert c0 - cruise.battery_pct == pytest.approx(
        lim.drain_airborne_pct_per_min + 2.0 * lim.drain_per_mps_pct_per_min, abs=1e-6
    )
    assert h0 - hover.battery_pct < c0 - cruise.battery_pct
    climb = airborne(2.0)
    climb.set_target(0.0, 0.0, 500.0)
    for _ in range(int(5 / DT)):  # at climb speed (1 m/s)
        climb.step(DT)
    assert climb.drain_pct_per_min() == pytest.approx(
        lim.drain_airborne_pct_per_min
        + 1.0 * lim.drain_per_mps_pct_per_min
        + 1.0 * lim.drain_climb_per_mps_pct_per_min
    )


def test_rest_drains_exactly_as_steps_do() -> None:
    for q, r in ((Quadcopter(), Quadcopter()), (airborne(2.0), airborne(2.0))):
        for _ in range(100):  # settle: the airborne one reaches rest on its setpoint
            q.step(DT)
            r.step(DT)
        assert q.at_rest and r.at_rest
        for _ in range(777):
            q.step(DT)
        r.rest(DT, 777)
        assert q.state == r.state  # bit for bit


def test_rest_refuses_a_moving_vehicle() -> None:
    q = airborne(2.0)
    q.set_target(10.0, 0.0, 2.0)
    q.step(DT)
    assert not q.at_rest
    with pytest.raises(ValueError, match="moving"):
        q.rest(DT, 1)


def test_battery_never_goes_negative() -> None:
    q = Quadcopter(Limits(drain_idle_pct_per_min=600.0), battery_pct=1.0)
    for _ in range(100):
        q.step(DT)
    assert q.battery_pct == 0.0


def test_limits_are_validated() -> None:
    with pytest.raises(ValueError, match="accel_mps2"):
        Limits(accel_mps2=0)
    with pytest.raises(ValueError, match="drain_idle"):
        Limits(drain_idle_pct_per_min=-1)
    with pytest.raises(ValueError):
        Quadcopter().step(0.0)


@settings(max_examples=40, deadline=None)
@given(
    x=st.floats(-40, 40),
    y=st.floats(-40, 40),
    z=st.floats(0.5, 30),
    speed=st.floats(0.5, 8),
    accel=st.floats(0.5, 6),
)
def test_any_target_is_reached_within_limits(
    x: float, y: float, z: float, speed: float, accel: float
) -> None:
    q = Quadcopter(Limits(horizontal_speed_mps=speed, accel_mps2=accel))
    q.arm()
    q.set_target(0.0, 0.0, 2.0)
    fly(q)
    q.set_target(x, y, z)
    seen = fly(q, max_s=600.0)
    assert q.position == pytest.approx((x, y, z), abs=1e-3)
    assert seen["max_h"] <= speed + 1e-6
    assert seen["max_up"] <= 1.0 + 1e-6
    assert seen["max_down"] <= 0.7 + 1e-6
    assert seen["max_acc"] <= accel + 1e-6
    assert seen["overshoot"] <= 0.1


def test_geo_frame_scale_near_klagenfurt() -> None:
    frame = GeoFrame()
    lat, lon, alt = frame.to_lla(1000.0, 0.0, 7.0)
    assert lat - frame.home_lat_deg == pytest.approx(1000 / 111_319.49, rel=1e-4)
    assert lon == frame.home_lon_deg and alt == 7.0
    _, lon, _ = frame.to_lla(0.0, 1000.0, 0.0)
    # A degree of longitude is shorter by cos(latitude).
    expected = 1000 / (111_319.49 * math.cos(math.radians(46.6103)))
    assert lon - frame.home_lon_deg == pytest.approx(expected, rel=1e-4)
    assert GeoFrame(home_alt_m=440.0).amsl_m(10.0) == 450.0


@given(
    x=st.floats(-2000, 2000),
    y=st.floats(-2000, 2000),
    z=st.floats(0, 500),
    lat=st.floats(-80, 80),
    lon=st.floats(-179, 179),
)
def test_lla_round_trip(x: float, y: float, z: float, lat: float, lon: float) -> None:
    frame = GeoFrame(lat, lon, 100.0)
    back = frame.from_lla(*frame.to_lla(x, y, z))
    assert back == pytest.approx((x, y, z), abs=1e-6)
