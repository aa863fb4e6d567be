"""A drone with 20 000 actions delivers its whole report through ``eamos run``'s fleet.

The report (about 1.7 MB in MessagePack) is larger than one wire message: it
crosses the CURVE link in ReportParts (:mod:`eamos.net.reports`) and reaches the
ground station whole, every action listed; ``summary.json`` folds the oldest
as before (docs/logs.md "Long missions").
"""

from __future__ import annotations

import json
import threading
from pathlib import Path

import pytest

from eamos.actors.report import LISTED_ACTIONS_MAX_BYTES
from eamos.compiler import compile_mission, write_artifacts
from eamos.config import FleetConfig
from eamos.ground import Limits, LocalMission, fly_local, make_display

# The same 20 000-action mission as the report's folding tests.
from .test_local_long_missions import ACTIONS, LONG

pytestmark = [pytest.mark.e2e, pytest.mark.timeout(900)]


def test_a_report_of_20000_actions_reaches_the_ground_station_whole(tmp_path: Path) -> None:
    run_dir = tmp_path / "run"
    run_dir.mkdir()
    compiled = compile_mission(LONG, "long.go")
    write_artifacts(compiled, run_dir, svg=False)
    summary = fly_local(
        LocalMission(compiled.mission.name, compiled.mission_id, compiled.programs),
        run_dir,
        FleetConfig.empty(),
        Limits(120.0, 800.0),
        threading.Event(),
        speedup=1000.0,
        display=make_display(False, ["Drone1"]),
    )
    assert summary.ok, summary.outcome
    report = summary.drones["Drone1"].report
    assert report is not None
    # Every action arrived, none folded: the report travelled in parts.
    assert len(report.actions) == ACTIONS and report.folded is None
    assert all(a.result == "ok" for a in report.actions)
    assert [a.action for a in report.actions[:2]] == ["Arm", "PauseFor"]
    # The summary file stays bounded: its copy folds the oldest actions.
    written = json.loads((run_dir / "summary.json").read_text())["drones"]["Drone1"]
    assert written["actions_folded"]["count"] + len(written["actions"]) == ACTIONS
    assert len(json.dumps(written["actions"])) <= LISTED_ACTIONS_MAX_BYTES + 2 * ACTIONS
    mission_log = (run_dir / "logs" / "GCS" / "mission.log").read_text()
    assert "net.report.parts_dropped" not in mission_log
