"""Control messages (Start, Abort, Complete) count only from the ground station.

A fleet member holds valid keys, so the network lets it in; what it may say is
the runtime's business: ``InRouter`` drops a control message whose (authenticated)
sender is not the ground station and logs ``mission.control.refused``.
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

TWO_DRONES = """
func PAR_M() {
    Drone1.Arm()
    Drone2.Arm()
}
"""


def test_a_drone_cannot_complete_abort_or_start_another(fleets: Any, tmp_path: Path) -> None:
    d1 = FakeAdapter("Drone1", auto=False)
    fleet = fleets(TWO_DRONES, {"Drone1": d1, "Drone2": FakeAdapter("Drone2", auto=True)})
    fleet.start()
    arm = d1.wait_started("Arm", timeout=WAIT_S)  # Drone1 is mid-action
    drone1 = fleet.runtimes["Drone1"]
    link2 = fleet.runtimes["Drone2"].link
    assert link2 is not None and link2.secure  # Drone2 holds the fleet's keys
    mission = fleet.compiled.mission_id
    for msg in (
        wire.Complete(mission, "Drone2"),
        wire.Abort(mission, "Drone2", "forged by Drone2"),
        wire.Start(mission, "Drone2"),
    ):
        link2.send(msg)
    log = tmp_log(fleet, "Drone1")

    def refused() -> list[dict[str, Any]]:
        return [e for e in read_log(log) if e["event"] == "mission.control.refused"]

    assert eventually(lambda: len(refused()) == 3)
    assert sorted(e["message"] for e in refused()) == ["Abort", "Complete", "Start"]
    assert {e["sender"] for e in refused()} == {"Drone2"}
    assert refused()[0]["level"] == "warning"
    # Drone1 flies on: not completed, not aborted, its action still running.
    assert not drone1.completed.is_set() and not drone1.aborted.is_set()
    assert d1.calls_of("abort") == [] and d1.running != []
    d1.finish(arm)
    assert fleet.station.wait_resolved(WAIT_S), fleet.station.unresolved()
    # The ground station's own Complete is still obeyed.
    fleet.station.complete()
    assert drone1.completed.wait(WAIT_S)
    assert not any(e["event"] == "mission.complete" and e["sender"] != "GCS" for e in read_log(log))
