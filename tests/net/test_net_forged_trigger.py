"""Issue 28, item 3: a key holder cannot forge another drone's trigger.

Each participant reads a peer's messages on a socket of its own whose CURVE
handshake proved that peer's key, and drops a message whose ``sender`` is not
that peer: the sender is authenticated.  What a sender may *say* is checked
one level up: a trigger counts only for an external arc of this drone's
program whose source node the sender itself hosts.  Here Drone3, with its own
valid key, claims a trigger from a node of Drone2 (whose action still runs):
Drone1 must not move, and must move once Drone2 really finishes.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from eamos.hal.fake import FakeAdapter
from eamos.logs import read_log
from eamos.net import wire

from .link_helpers import WAIT_S, eventually
from .test_net_runtime import fleets, tmp_log

__all__ = ["fleets"]

pytestmark = pytest.mark.timeout(180)

#: Drone1's FlyByX(2) and Drone3's FlyByY(2) wait for Drone2's FlyByX(1).
WAITS_FOR_DRONE2 = """
func SEQ_M() {
    PAR_Arm()
    Drone2.FlyByX(1)
    PAR_Go()
}
func PAR_Arm() {
    Drone1.Arm()
    Drone2.Arm()
    Drone3.Arm()
}
func PAR_Go() {
    Drone1.FlyByX(2)
    Drone3.FlyByY(2)
}
"""


def test_a_drone_cannot_trigger_for_another_drones_node(fleets: Any, tmp_path: Path) -> None:
    d1 = FakeAdapter("Drone1", auto=True)
    d2 = FakeAdapter("Drone2", auto=False)
    fleet = fleets(
        WAITS_FOR_DRONE2, {"Drone1": d1, "Drone2": d2, "Drone3": FakeAdapter("Drone3", auto=True)}
    )
    fleet.start()
    d2.finish(d2.wait_started("Arm", WAIT_S))
    fly2 = d2.wait_started("FlyByX", WAIT_S)  # Drone2's move runs: Drone1 must wait
    program = fleet.compiled.programs["Drone1"]
    hosts = {n.key: n.drone for n in program.nodes}
    # The arc from Drone2's move to Drone1's side of PAR_Go.
    (arc,) = [a for a in program.arcs if a.external and hosts[a.src] == "Drone2"]
    link3 = fleet.runtimes["Drone3"].link
    assert link3 is not None and link3.secure  # Drone3 holds its own, valid key
    forged = wire.Trigger(
        fleet.compiled.mission_id,
        "Drone3",
        dest="Drone1",
        src_node=arc.src,
        dst_node=arc.dst,
        iteration=(),
        status="done",
    )
    link3.send(forged)
    log = tmp_log(fleet, "Drone1")

    def refused() -> list[dict[str, Any]]:
        return [e for e in read_log(log) if e["event"] == "mission.inbridge.forged_trigger"]

    def flew() -> bool:
        return any(c.action == "FlyByX" for c in d1.calls_of("run"))

    assert eventually(lambda: bool(refused()) or flew())
    assert not flew(), "Drone1 moved on a trigger Drone3 forged for Drone2's node"
    assert len(refused()) == 1
    entry = refused()[0]
    assert (entry["sender"], entry["src"], entry["dst"], entry["host"]) == (
        "Drone3",
        arc.src,
        arc.dst,
        "Drone2",
    )
    assert entry["level"] == "warning"
    # Drone1 did not move; nothing on it counted the forged trigger.
    assert [c.action for c in d1.calls_of("run")] == ["Arm"]
    # Drone2's real trigger moves it, once.
    d2.finish(fly2)
    d1.wait_started("FlyByX", WAIT_S)
    assert fleet.station.wait_resolved(WAIT_S), fleet.station.unresolved()
    assert [c.action for c in d1.calls_of("run")] == ["Arm", "FlyByX"]
