"""A drone's node killed (``kill -9``) and started again with the same config rejoins.

Real ``eamos-node`` processes, each in its own network namespace.  Drone2
waits for Drone1's landing.  Drone1 is killed during its take-off and started
again: its peers see a new incarnation (``mission.peer.restarted``), resend it
the ground station's Start and everything else it had, take its new messages
as new, and the mission completes with Drone1's report.
"""

from __future__ import annotations

from typing import Any

import pytest

from eamos.program.uniform import GROUND_STATION

pytestmark = [pytest.mark.e2e, pytest.mark.timeout(600)]

DEPENDENT = """
func SEQ_Main() {
    Drone1.Arm()
    Drone1.Takeoff(2)
    Drone1.Land()
    Drone2.Arm()
    Drone2.Disarm()
}
"""


def test_a_restarted_drone_rejoins_and_the_mission_completes(lab_fleet: Any) -> None:
    fleet = lab_fleet(DEPENDENT, speedup=2, net={"peer_timeout_s": 1.5, "heartbeat_s": 0.25})
    fleet.start()
    assert fleet.wait_event("Drone1", "adapter.action.start", count=2, log="adapter")
    fleet.kill("Drone1")  # mid take-off: no goodbye, no report
    assert fleet.wait_event(GROUND_STATION, "mission.peer.lost", peer="Drone1", timeout_s=60)
    fleet.start(["Drone1"])  # the same config, a new process
    for peer in (GROUND_STATION, "Drone2"):
        assert fleet.wait_event(peer, "net.peer.restarted", peer="Drone1", timeout_s=60), peer
    summary = fleet.finish()
    assert summary["ok"], (summary["outcome"], summary.get("failures"))
    assert summary["drones"]["Drone1"].get("error") is None
    assert summary["drones"]["Drone2"]["triggers_received"] == 1
    restarted = [e for e in fleet.events(GROUND_STATION) if e["event"] == "net.peer.restarted"]
    assert restarted[0]["incarnation"] > restarted[0]["previous"] > 0


LONG = """
func PAR_Main() {
    SEQ_One()
    Drone2.Arm()
}
func SEQ_One() {
    Drone1.Arm()
    Drone1.Takeoff(2)
    Drone1.PauseFor(600)
    Drone1.Land()
}
"""


def test_a_restarted_drone_obeys_the_ground_stations_abort(lab_fleet: Any) -> None:
    """The mission times out after Drone1's restart: the new process lands on the abort."""
    fleet = lab_fleet(
        LONG,
        speedup=2,
        net={"peer_timeout_s": 1.5, "heartbeat_s": 0.25},
        mission_timeout_s=25.0,
    )
    fleet.start()
    assert fleet.wait_event("Drone1", "adapter.action.start", count=2, log="adapter")
    fleet.kill("Drone1")
    fleet.start(["Drone1"])
    assert fleet.wait_event(GROUND_STATION, "net.peer.restarted", peer="Drone1", timeout_s=60)
    summary = fleet.finish()
    assert summary["outcome"].startswith("timed out")
    aborts = [e for e in fleet.events("Drone1") if e["event"] == "mission.abort"]
    assert aborts and aborts[0]["reason"].startswith("timed out"), fleet.output("Drone1")
    assert aborts[0]["land"] is True
    drone1 = summary["drones"]["Drone1"]
    assert drone1.get("error") is None and drone1["aborted"]  # the new process reported
