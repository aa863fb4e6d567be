"""The paper's experiments A, B and C on the real autopilots, through ``eamos run``.

A: one drone flies a 1 m square at 1.5 m; B: two drones side by side, waiting for each
other at every corner, then one climbs 0.5 m after the other; C (hybrid): a PX4 and an
ArduCopter fly B's square, each move after the built-in simulator's Drone3 finished its
own.  Every action must succeed, end where the mission says (within the autopilot's
tolerance, tests/sitl/flights.py), and the vehicles end landed and disarmed with their
parameters restored.
"""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from tests.support.runs import MISSIONS

from .flights import SPEEDUP, Flown, SitlFleet, assert_safe_end, fly

pytestmark = [pytest.mark.sitl, pytest.mark.timeout(900)]

#: Where each action of the square leaves the drone (mission frame), in order.
SQUARE = [
    ("Takeoff", (0.0, 0.0, 1.5)),
    ("FlyByX", (1.0, 0.0, 1.5)),
    ("FlyByY", (1.0, 1.0, 1.5)),
    ("FlyByX", (0.0, 1.0, 1.5)),
    ("FlyByY", (0.0, 0.0, 1.5)),
]
#: The adapter's tolerance for a 1 m move (m).
CORNER_M = {"arducopter": 0.2, "px4": 0.25}


def assert_square(flown: Flown, drone: str, autopilot: str, climb: float = 0.0) -> None:
    """Every action ok; each move of the square was judged done at its corner: the settle
    window's mean (``adapter.arrived``; PX4 SIH's estimate wanders, one sample proves
    nothing) within a tolerance no larger than the autopilot's."""
    results = flown.results(drone)
    assert all(result == "ok" for _, _, result in results), results
    arrivals = [e for e in flown.events(drone, "adapter.arrived") if e["action"] != "FlyByZ"]
    assert [e["action"] for e in arrivals] == [name for name, _ in SQUARE]
    # The square is flown from where the drone took off (home is where it stood at start).
    x0, y0, _ = arrivals[0]["target"]
    for arrival, (name, (cx, cy, cz)) in zip(arrivals, SQUARE, strict=True):
        assert arrival["tolerance_m"] <= CORNER_M[autopilot], arrival
        assert arrival["error_m"] <= arrival["tolerance_m"], arrival
        corner = (x0 + cx, y0 + cy, cz)
        assert math.dist(arrival["target"], corner) < 0.01, (name, arrival, corner)
    if climb:
        (up,) = [e for e in flown.events(drone, "adapter.arrived") if e["action"] == "FlyByZ"]
        assert up["target"][2] == 1.5 + climb and up["error_m"] <= 0.4 * climb, (drone, up)


@pytest.mark.parametrize("autopilot", ["arducopter", "px4"])
def test_experiment_a(sitl_fleet, tmp_path: Path, autopilot: str) -> None:
    fleet: SitlFleet = sitl_fleet({"Drone1": autopilot}, SPEEDUP[autopilot])
    flown = fly(tmp_path, fleet, MISSIONS / "experiment_a.go")
    assert flown.returncode == 0, flown.output
    assert_square(flown, "Drone1", autopilot)
    assert_safe_end(flown, fleet)
    print(f"{autopilot}: experiment A in {flown.wall_s:.1f} s wall")


@pytest.mark.parametrize("autopilot", ["arducopter", "px4"])
def test_experiment_b(sitl_fleet, tmp_path: Path, autopilot: str) -> None:
    fleet: SitlFleet = sitl_fleet({"Drone1": autopilot, "Drone2": autopilot}, SPEEDUP[autopilot])
    flown = fly(tmp_path, fleet, MISSIONS / "experiment_b.go")
    assert flown.returncode == 0, flown.output
    for drone in ("Drone1", "Drone2"):
        assert_square(flown, drone, autopilot, climb=0.5)
    # Drone2 climbs only after Drone1's climb is done (the mission's order).
    one = flown.report("Drone1")["actions"]
    two = flown.report("Drone2")["actions"]
    (up1,) = [a for a in one if a["action"] == "FlyByZ"]
    (up2,) = [a for a in two if a["action"] == "FlyByZ"]
    assert up2["start"] >= up1["end"]
    assert_safe_end(flown, fleet)
    print(f"{autopilot}: experiment B in {flown.wall_s:.1f} s wall")


def test_experiment_c_hybrid(sitl_fleet, tmp_path: Path) -> None:
    # One clock for the whole fleet: the simulated Drone3 runs at the run's speed-up.
    fleet: SitlFleet = sitl_fleet(
        {"Drone1": "px4", "Drone2": "arducopter", "Drone3": "sim"}, SPEEDUP["px4"]
    )
    flown = fly(tmp_path, fleet, MISSIONS / "experiment_c.go")
    assert flown.returncode == 0, flown.output
    assert_square(flown, "Drone1", "px4")
    assert_square(flown, "Drone2", "arducopter")
    assert all(result == "ok" for _, _, result in flown.results("Drone3"))
    assert_safe_end(flown, fleet)
    print(f"experiment C in {flown.wall_s:.1f} s wall")
