"""One home per drone everywhere (issue 27, item 7): simulated MAVLink vehicles stand at their
fleet homes, and a MAVLink node gets its fleet home, home_lla and the [safety] fence."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from eamos.config import FleetConfig
from eamos.ground.vehicles import (
    SIM_VEHICLE_HOME,
    fleet_lla_homes,
    mavlink_fleet_settings,
    start_sim_vehicles,
)
from eamos.hal.kinematics import GeoFrame

from .mavlink_helpers import RawClient

pytestmark = pytest.mark.timeout(180)

FLEET = """
[drones.D1.hal]
adapter = "mavlink"
sim_vehicle = { autopilot = "px4", prearm_delay_s = 1 }
[drones.D2.hal]
adapter = "mavlink"
sim_vehicle = { autopilot = "px4", prearm_delay_s = 1, sysid = 2 }
[drones.D2]
home_m = [3.0, 4.0]
[safety]
max_altitude_m = 25
geofence_m = [[-20, -20], [-20, 20], [20, 20], [20, -20]]
"""


def fleet(tmp_path: Path, text: str = FLEET) -> FleetConfig:
    path = tmp_path / "fleet.toml"
    path.write_text(text)
    return FleetConfig.load(path)


def test_a_mavlink_node_gets_its_fleet_home_and_the_fence(tmp_path):
    f = fleet(tmp_path)
    d1 = mavlink_fleet_settings(f, "D1", ["D1", "D2"])
    d2 = mavlink_fleet_settings(f, "D2", ["D1", "D2"])
    assert d1["home_m"] == [0.0, 0.0] and d2["home_m"] == [3.0, 4.0]
    assert d2["geofence_m"][2] == [20.0, 20.0] and d2["max_altitude_m"] == 25
    assert "home_lla" not in d1
    homes = fleet_lla_homes(f, ["D1", "D2"])
    assert homes["D1"] == SIM_VEHICLE_HOME  # the fleet's origin: no drone has a home_lla
    north, east, _ = GeoFrame(*SIM_VEHICLE_HOME).from_lla(homes["D2"][0], homes["D2"][1], 0)
    assert (round(north, 2), round(east, 2)) == (3.0, 4.0)
    with_lla = fleet(tmp_path, FLEET.replace("home_m = [3.0, 4.0]", "home_lla = [46.61, 14.264]"))
    assert fleet_lla_homes(with_lla, ["D1", "D2"])["D2"][:2] == (46.61, 14.264)
    assert mavlink_fleet_settings(with_lla, "D2", ["D1", "D2"])["home_lla"] == [46.61, 14.264]


def test_simulated_vehicles_stand_at_their_fleet_homes(tmp_path):
    """Before: every eamos-sim-vehicle had the same default home, so two "real" vehicles
    reported one position while the check placed them apart."""
    f = fleet(tmp_path)
    drones = ["D1", "D2"]
    vehicles = start_sim_vehicles(
        {n: f.hal_for(n) for n in drones}, tmp_path / "logs", 5.0, fleet_lla_homes(f, drones)
    )
    clients: list[RawClient] = []
    try:
        fixes = []
        for n in drones:
            client = RawClient(vehicles.hal_for(n)["connection"])
            clients.append(client)
            beat = client.wait("HEARTBEAT", lambda m: m.autopilot == 12)
            # Ask for GLOBAL_POSITION_INT (33) at 10 Hz, as the adapter does.
            client.mav.command_long_send(beat.get_srcSystem(), 1, 511, 0, 33, 1e5, 0, 0, 0, 0, 0)
            fix = client.wait("GLOBAL_POSITION_INT", lambda m: m.lat != 0)
            fixes.append((fix.lat / 1e7, fix.lon / 1e7))
        north, east, _ = GeoFrame(fixes[0][0], fixes[0][1]).from_lla(*fixes[1], 0.0)
        assert math.hypot(north - 3.0, east - 4.0) < 0.5, (north, east)
    finally:
        for client in clients:
            client.close()
        vehicles.stop()
