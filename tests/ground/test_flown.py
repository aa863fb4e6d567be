"""What a drone was seen to fly, from its telemetry (the live look-ahead's battery measure).

Pure: telemetry samples in, the tally out (``eamos.ground.flown.Flown``), and the ground
station's view of a drone adding it up sample by sample.
"""

from __future__ import annotations

import pytest

from eamos.ground.flown import Flown
from eamos.ground.station import DroneView
from eamos.net import wire


def sample(
    t: float, x: float, z: float, battery: float, *, airborne: bool = True
) -> wire.TelemetrySample:
    return wire.TelemetrySample(
        mission="m1",
        sender="Drone1",
        time_s=t,
        x_m=x,
        y_m=0.0,
        z_m=z,
        lat_deg=0.0,
        lon_deg=0.0,
        alt_m=z,
        battery_pct=battery,
        armed=airborne,
        landed=not airborne,
    )


def test_an_airborne_stretch_adds_its_seconds_metres_climb_and_battery() -> None:
    tally = Flown().after(sample(10.0, 0.0, 1.0, 99.0), sample(12.0, 4.0, 3.0, 98.5))
    assert tally == Flown(seconds=2.0, metres=4.0, climbed_m=2.0, battery_used_pct=0.5)
    # Descending climbs nothing; a battery reading that rose uses nothing.
    later = tally.after(sample(12.0, 4.0, 3.0, 98.5), sample(13.0, 4.0, 2.0, 98.7))
    assert later.climbed_m == 2.0 and later.battery_used_pct == 0.5 and later.seconds == 3.0


def test_the_ground_and_time_that_did_not_pass_add_nothing() -> None:
    on_ground = sample(0.0, 0.0, 0.0, 100.0, airborne=False)
    assert Flown().after(on_ground, sample(1.0, 0.0, 0.5, 99.9)) == Flown()
    assert Flown().after(sample(5.0, 0.0, 1.0, 99.0), sample(5.0, 1.0, 1.0, 98.0)) == Flown()
    assert Flown().after(sample(6.0, 0.0, 1.0, 99.0), sample(5.0, 1.0, 1.0, 98.0)) == Flown()


def test_the_view_of_a_drone_adds_up_every_sample_it_takes() -> None:
    view = DroneView("Drone1")
    for i in range(11):  # 10 s at 1 m/s, 0.1 % a second
        view.take_sample(sample(float(i), float(i), 2.0, 100.0 - 0.1 * i))
    assert view.flown.seconds == pytest.approx(10.0)
    assert view.flown.metres == pytest.approx(10.0)
    assert view.flown.battery_used_pct == pytest.approx(1.0)
    assert view.flown.to_json() == {"s": 10.0, "m": 10.0, "climbed_m": 0.0, "battery_used_pct": 1.0}
