"""``eamos run``'s real processes fly each drone type's battery model (issue 14, per type).

The fleet file gives DroneType1 a 60 % battery at start; bound to the mission
(:meth:`FleetConfig.for_mission`), every DroneType1 drone, and the custom type
that embeds it, take a battery ``If``'s Else branch while the Quadcopter takes
Then, in drone processes over the CURVE links.
"""

from __future__ import annotations

import threading
from pathlib import Path

import pytest

from eamos.compiler import compile_mission, write_artifacts
from eamos.config import FleetConfig
from eamos.ground import Limits, LocalMission, fly_local, make_display
from tests.config.test_drone_types import FLEET, MISSION

pytestmark = [pytest.mark.e2e, pytest.mark.timeout(600)]


def test_each_drone_process_flies_its_types_battery(tmp_path: Path) -> None:
    run_dir = tmp_path / "run"
    run_dir.mkdir()
    compiled = compile_mission(MISSION, str(tmp_path / "types.go"))
    write_artifacts(compiled, run_dir, svg=False)
    path = tmp_path / "fleet.toml"
    path.write_text(FLEET)
    fleet = FleetConfig.load(path).for_mission(compiled.programs, compiled.mission.types)
    drones = ["D1", "D2", "D3"]
    summary = fly_local(
        LocalMission(compiled.mission.name, compiled.mission_id, compiled.programs),
        run_dir,
        fleet,
        Limits(120.0, 300.0),
        threading.Event(),
        speedup=20.0,
        display=make_display(False, drones),
    )
    assert summary.ok, summary.outcome
    # The node configs eamos run wrote carry each type's battery.
    for drone, battery in (("D1", None), ("D2", 60), ("D3", 60)):
        text = (run_dir / "configs" / f"{drone}.toml").read_text()
        assert ("battery_pct = 60" in text) == (battery is not None), text
    taken = {}
    for drone in drones:
        report = summary.drones[drone].report
        assert report is not None
        moves = [a.args[0] for a in report.actions if a.action == "FlyByZ"]
        taken[drone] = moves
    assert taken == {"D1": [1.0], "D2": [-1.0], "D3": [-1.0]}
