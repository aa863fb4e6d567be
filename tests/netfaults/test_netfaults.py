"""Fault tests on separate hosts: every participant an ``eamos-node`` in its own namespace.

Loss is random packet loss by iptables (``-m statistic``) on every host, delay
and jitter come from a TCP proxy in the hub namespace (this kernel has no
``netem``), a partition takes one host's link down for 5 s, ``kill -9`` ends a
drone nobody depends on, and an intruder with its own keys tries to listen in
and to trigger.  The Table 7 check holds throughout: triggers sent and received
equal the MDGs' external arcs, so every trigger took effect exactly once.
"""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest

from eamos.net.keys import create_fleet_keys
from eamos.program.uniform import GROUND_STATION

from .netfault_helpers import REPO, check_table7, not_ok

pytestmark = [pytest.mark.e2e, pytest.mark.timeout(600)]

EXPERIMENT_C = REPO / "missions" / "experiment_c.go"


@pytest.mark.parametrize("loss", [0.1, 0.3], ids=["10%", "30%"])
def test_mission_completes_exactly_once_under_random_loss(lab_fleet: Any, loss: float) -> None:
    fleet = lab_fleet(EXPERIMENT_C, speedup=5, net={"peer_timeout_s": 5})
    for name in fleet.names:
        fleet.lab.loss(name, loss)  # incoming packets of every host, both directions covered
    fleet.start()
    summary = fleet.finish()
    assert summary["ok"], not_ok(summary)
    check_table7(summary, fleet.names)
    # Experiment C's Table 7 row for Drone3: 15 triggers in, 12 out.
    assert summary["drones"]["Drone3"]["triggers_received"] == 15
    assert summary["drones"]["Drone3"]["triggers_sent"] == 12


def test_mission_completes_with_delay_and_jitter(lab_fleet: Any) -> None:
    """Every connection through a proxy adding 40 +- 30 ms each way."""
    fleet = lab_fleet(EXPERIMENT_C, speedup=5, delay_ms=40, jitter_ms=30)
    fleet.start()
    summary = fleet.finish()
    assert summary["ok"], not_ok(summary)
    check_table7(summary, fleet.names)
    rtts = [
        p["rtt_ms"]
        for p in summary["ground_station"]["net"]["peers"].values()
        if p["rtt_ms"] is not None
    ]
    assert rtts and max(rtts) >= 40  # the proxy really was in the path


def test_partitioned_drone_is_reported_lost_then_back_and_the_mission_completes(
    lab_fleet: Any,
) -> None:
    """Drone3, on which both others depend, is cut off for 5 s in the middle of the mission."""
    fleet = lab_fleet(EXPERIMENT_C, speedup=3, net={"peer_timeout_s": 2, "heartbeat_s": 0.25})
    fleet.start()
    assert fleet.wait_event("Drone3", "mission.outbridge.sent", count=4), fleet.output("Drone3")
    fleet.lab.partition("Drone3")
    cut = time.monotonic()
    assert fleet.wait_event(GROUND_STATION, "mission.peer.lost", peer="Drone3", timeout_s=30)
    time.sleep(max(0.0, 5.0 - (time.monotonic() - cut)))  # the fault lasts 5 s
    fleet.lab.heal("Drone3")
    assert fleet.wait_event(GROUND_STATION, "mission.peer.back", peer="Drone3", timeout_s=60)
    summary = fleet.finish()
    assert summary["ok"], not_ok(summary)
    check_table7(summary, fleet.names)
    # Drone3 saw the others go and come back too, and caught up by retransmission.
    lost = {e["peer"] for e in fleet.events("Drone3") if e["event"] == "mission.peer.lost"}
    assert {"GCS", "Drone1", "Drone2"} <= lost
    retransmitted = (
        sum(summary["drones"][d]["retransmissions"] for d in fleet.drones)
        + summary["ground_station"]["retransmissions"]
    )
    assert retransmitted > 0
    states = [
        e["state"] for e in summary["ground_station"]["net"]["peer_events"] if e["peer"] == "Drone3"
    ]
    assert states[:2] == ["lost", "back"]


INDEPENDENT = """
func PAR_Main() {
    SEQ_One()
    SEQ_Two()
}
func SEQ_One() {
    Drone1.Arm()
    Drone1.Takeoff(2)
    Drone1.FlyByX(4)
    Drone1.Land()
}
func SEQ_Two() {
    Drone2.Arm()
    Drone2.Takeoff(2)
    Drone2.FlyByY(4)
    Drone2.Land()
    Drone2.Disarm()
}
"""


def test_killed_drone_is_reported_lost_and_the_others_complete(lab_fleet: Any) -> None:
    fleet = lab_fleet(
        INDEPENDENT,
        speedup=2,
        net={"peer_timeout_s": 1.5, "heartbeat_s": 0.25},
        ground_net={"peer_give_up_s": 3},
    )
    fleet.start()
    assert fleet.wait_event("Drone1", "adapter.action.start", count=2, log="adapter")
    fleet.kill("Drone1")  # kill -9: no goodbye, no report
    summary = fleet.finish()
    assert summary["outcome"] == "ok"  # every participant still up resolved
    assert not summary["ok"]  # ... but Drone1's part is missing
    assert summary["drones"]["Drone1"]["error"] == "no report"
    assert summary["links"]["Drone1"] == "lost"
    assert any("Drone1: silent" in f for f in summary["failures"])
    check_table7(summary, ["Drone2", GROUND_STATION])
    lost = [e for e in fleet.events(GROUND_STATION) if e["event"] == "mission.peer.lost"]
    assert [e["peer"] for e in lost] == ["Drone1"]
    assert "Drone1 link lost" in fleet.output(GROUND_STATION)


def test_intruder_with_its_own_keys_triggers_nothing(lab_fleet: Any, tmp_path: Path) -> None:
    """The intruder listens everywhere and, via a redirect, poses as Drone1 to Drone2."""
    fleet = lab_fleet(INDEPENDENT, speedup=4, extra_hosts=["intruder"])
    evil = create_fleet_keys(tmp_path / "evil", fleet.names)
    me = fleet.lab.addr["intruder"]
    # An attacker controlling the route: Drone2's connections to Drone1 land on the intruder.
    fleet.lab.run(
        "Drone2",
        "iptables",
        "-t",
        "nat",
        "-A",
        "OUTPUT",
        "-p",
        "tcp",
        "-d",
        fleet.lab.addr["Drone1"],
        "--dport",
        "6000",
        "-j",
        "DNAT",
        "--to-destination",
        f"{me}:6000",
    )
    nodes = [n.key for n in fleet.compiled.programs["Drone2"].native_nodes()]
    result = tmp_path / "intruder.json"
    intruder = fleet.lab.popen(
        "intruder",
        [
            sys.executable,
            str(Path(__file__).parent / "intruder.py"),
            "--keys",
            str(evil / "Drone1"),
            "--fleet-public",
            str(fleet.files.keys_dir / "public"),
            "--bind",
            f"tcp://{me}:6000",
            "--pose",
            "Drone1",
            "--target",
            "Drone2",
            "--nodes",
            ",".join(nodes),
            "--mission",
            fleet.compiled.mission_id,
            "--seconds",
            "200",
            "--stop-file",
            str(tmp_path / "stop"),
            "--out",
            str(result),
            *(f"--peer={n}=tcp://{fleet.lab.addr[n]}:6000" for n in fleet.names),
        ],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.STDOUT,
        cwd=REPO,
    )
    fleet.start()
    summary = fleet.finish()
    (tmp_path / "stop").touch()
    intruder.wait(60)
    assert summary["ok"], not_ok(summary)
    check_table7(summary, fleet.names)
    d2 = summary["drones"]["Drone2"]
    assert not d2["aborted"] and [a["result"] for a in d2["actions"]] == ["ok"] * 5
    seen = json.loads(result.read_text())
    assert seen["published"] > 0
    assert seen["received"] == 0  # nothing of the fleet's traffic reached it
    assert seen["subscriptions"] == 0  # Drone2 never accepted it as Drone1
    evil_key = (evil / "public" / "Drone1.key").read_text()
    for name in fleet.names:
        denied = [e for e in fleet.events(name) if e["event"] == "net.auth.denied"]
        assert denied and denied[0]["key"] in evil_key, name  # its key, logged and refused
    failed = [e for e in fleet.events("Drone2") if e["event"] == "net.auth.failed"]
    assert any(e["peer"] == "Drone1" for e in failed)  # the impostor failed the handshake
