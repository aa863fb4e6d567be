"""A drone's node killed (``kill -9``) and started again with the same config.

Real ``eamos-node`` processes, each in its own network namespace.  Its peers
see a new incarnation (``mission.peer.restarted``) and resend it the ground
station's Start and everything else it had.  A node restarted before any
trigger reached its nodes rejoins (its record, ``node-state.json``, proves
nothing ran) and the mission completes; one restarted after it ran refuses to
rejoin, at once, with one line and exit code 1 (issue 28: run again from the
start while its peers resend every trigger at once, it flew a ``Takeoff``
before its own ``Arm``), and the others end as for a killed node.
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

NET = {"peer_timeout_s": 1.5, "heartbeat_s": 0.25}


def test_a_drone_restarted_before_it_ran_rejoins_and_the_mission_completes(
    lab_fleet: Any,
) -> None:
    fleet = lab_fleet(DEPENDENT, speedup=2, net=NET)
    fleet.start()
    assert fleet.wait_event("Drone1", "adapter.action.start", count=2, log="adapter")
    fleet.kill("Drone2")  # waiting for Drone1's landing: nothing ran on it
    assert fleet.wait_event(GROUND_STATION, "mission.peer.lost", peer="Drone2", timeout_s=60)
    fleet.start(["Drone2"])  # the same config, a new process
    for peer in (GROUND_STATION, "Drone1"):
        assert fleet.wait_event(peer, "net.peer.restarted", peer="Drone2", timeout_s=60), peer
    summary = fleet.finish()
    assert "it rejoins the mission" in fleet.output("Drone2"), fleet.output("Drone2")
    assert summary["ok"], (summary["outcome"], summary.get("failures"))
    assert summary["drones"]["Drone2"].get("error") is None
    assert summary["drones"]["Drone2"]["triggers_received"] == 1
    restarted = [e for e in fleet.events(GROUND_STATION) if e["event"] == "net.peer.restarted"]
    assert restarted[0]["incarnation"] > restarted[0]["previous"] > 0


def test_a_drone_restarted_after_it_ran_refuses_to_rejoin(lab_fleet: Any) -> None:
    fleet = lab_fleet(DEPENDENT, speedup=2, net=NET, ground_net={"peer_give_up_s": 10})
    fleet.start()
    assert fleet.wait_event("Drone1", "adapter.action.start", count=2, log="adapter")
    fleet.kill("Drone1")  # mid take-off: no goodbye, no report
    fleet.start(["Drone1"])
    assert fleet.procs["Drone1"].wait(60) == 1, fleet.output("Drone1")
    out = fleet.output("Drone1")
    assert "Drone1 restarted mid-mission: its node before (pid" in out, out
    assert "it refuses to rejoin" in out and "remove node-state.json" in out, out
    summary = fleet.finish()
    assert not summary["ok"]
    assert summary["drones"]["Drone1"].get("error") == "no report"
    # Drone2 waited for Drone1 on the ground: stranded, it ends where it stands.
    drone2 = summary["drones"]["Drone2"]
    assert drone2["aborted"] and drone2["abort_reason"].startswith("stranded"), drone2
    assert not drone2["final"]["armed"]


LONG = """
func SEQ_Main() {
    Drone1.Arm()
    Drone1.Takeoff(2)
    Drone1.PauseFor(600)
    Drone1.Land()
    Drone2.Arm()
}
"""


def test_a_rejoined_drone_obeys_the_ground_stations_abort(lab_fleet: Any) -> None:
    """The mission times out after Drone2's restart: the new process lands on the abort."""
    fleet = lab_fleet(LONG, speedup=2, net=NET, mission_timeout_s=25.0)
    fleet.start()
    assert fleet.wait_event("Drone1", "adapter.action.start", count=2, log="adapter")
    fleet.kill("Drone2")
    fleet.start(["Drone2"])
    assert fleet.wait_event(GROUND_STATION, "net.peer.restarted", peer="Drone2", timeout_s=60)
    summary = fleet.finish()
    assert summary["outcome"].startswith("timed out")
    aborts = [e for e in fleet.events("Drone2") if e["event"] == "mission.abort"]
    assert aborts and aborts[0]["reason"].startswith("timed out"), fleet.output("Drone2")
    assert aborts[0]["land"] is True
    drone2 = summary["drones"]["Drone2"]
    assert drone2.get("error") is None and drone2["aborted"]  # the new process reported
