"""The virtual-time driver and real processes agree: same per-drone action order.

Each mission runs twice: through ``eamos run`` (drone processes, real
sockets, simulated drones at a speed-up) and through :func:`eamos.virtual.run_virtual`.
The missions' conditions have thresholds between the points where drones
stop, so the order of actions does not depend on timing.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from eamos.compiler import compile_file
from eamos.virtual import run_virtual
from tests.support.runs import REPO, run_mission

pytestmark = pytest.mark.e2e

MISSIONS = {
    "every_structure": Path(__file__).with_name("every_structure.go"),
    "experiment_b": REPO / "missions" / "experiment_b.go",
    "inspection_if": REPO / "missions" / "inspection_if.go",
    "survey_repeat": REPO / "missions" / "survey_repeat.go",
}


def run_processes(tmp_path: Path, mission: Path) -> dict:
    # The comparison is of the run as simulated; every_structure's battery If has an Else
    # branch (Drone2 left on the ground armed) that the pre-flight check refuses: not the
    # point of this test.
    proc, summary = run_mission(tmp_path, mission, "--no-check")
    assert proc.returncode == 0, proc.stdout + proc.stderr
    return summary


@pytest.mark.parametrize("name", sorted(MISSIONS))
def test_virtual_driver_and_processes_give_the_same_action_order(tmp_path, name):
    mission = MISSIONS[name]
    virtual = run_virtual(compile_file(mission).programs)
    assert virtual.ok
    summary = run_processes(tmp_path, mission)
    assert summary["ok"]
    assert set(summary["drones"]) <= set(virtual.drones)
    for drone, report in summary["drones"].items():
        real = [
            (a["action"], tuple(a["args"]), a["result"])
            for a in sorted(report["actions"], key=lambda a: a["start"])
        ]
        assert real == virtual.actions(drone), drone
