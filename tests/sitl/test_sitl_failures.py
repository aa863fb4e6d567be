"""A mission that fails in the air on a real autopilot: the node's close lands the drone,
disarms it, puts every parameter back, and the summary says where it really ended.

``Gimbal(-45)`` on an ArduCopter without a mount is answered MAV_RESULT_FAILED; the
mission cannot go on, so the node closes with the drone in the air.  Before (issue 27)
land-on-close sent LAND to a vehicle already on the ground (ArduCopter then never
reports landed and stays armed), parameters stayed changed, and summaries said
``armed: true`` of vehicles that had disarmed.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from .flights import SPEEDUP, SitlFleet, assert_vehicles_safe, fly

pytestmark = [pytest.mark.sitl, pytest.mark.timeout(900)]

MISSION = """\
package Fails

type Inspector interface {
	Quadcopter
	Gimbal(pitch_deg float64)
}

var Drone1 Inspector

func SEQ_Main() {
	Drone1.Arm()
	Drone1.Takeoff(2)
	Drone1.SetSpeed(1.5)
	Drone1.FlyByX(1)
	Drone1.Gimbal(-45)
	Drone1.Land()
	Drone1.Disarm()
}
"""


def test_a_failure_in_the_air_lands_disarms_and_restores(sitl_fleet, tmp_path: Path) -> None:
    fleet: SitlFleet = sitl_fleet({"Drone1": "arducopter"}, SPEEDUP["arducopter"])
    flown = fly(tmp_path, fleet, MISSION)
    assert flown.returncode != 0, flown.output
    results = {a: r for a, _, r in flown.results("Drone1")}
    assert results["Gimbal"] == "failed", results
    assert "MAV_RESULT_FAILED" in flown.output
    # Landed before the node closed: by the drone's end policy (stranded: its part ended
    # with a failure in the air, so it lands through the adapter's abort before its report)
    # or else by the node's close; never LAND on the ground.
    names = [e["event"] for e in flown.events("Drone1")]
    landed_by = [n for n in ("adapter.abort.done", "adapter.close_land.done") if n in names]
    assert landed_by, names[-8:]
    # Landed and disarmed (the vehicle's word), SetSpeed's and the drone type's
    # parameters back, nothing stranded, no hit on the ground.
    assert_vehicles_safe(flown, fleet)
    # The adapter saw the disarm in a HEARTBEAT before its link closed, and the summary
    # says what the vehicle ended as: the report follows the landing and the disarm.
    armed = flown.events("Drone1", "adapter.armed")
    assert armed and armed[-1]["armed"] is False, armed
    assert names.index(landed_by[0]) < names.index("adapter.close"), names[-8:]
    final = flown.report("Drone1")["final"]
    assert not final["armed"] and final["landed"], final
