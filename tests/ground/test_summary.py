"""``summary.json`` as a typed ``RunSummary``: one shape for every ground station and the reader."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from eamos.ground import DroneReport, DroneResult, RunSummary

REPORT = {
    "ok": True,
    "resolved": True,
    "aborted": False,
    "abort_reason": "",
    "triggers_sent": 3,
    "triggers_received": 2,
    "external_out": 3,
    "external_in": 2,
    "mdg": {"nodes": 5, "internal_arcs": 4, "external_in": 2, "external_out": 3},
    "blocked_nodes": [],
    "actions": [
        {
            "node": "n1",
            "action": "Arm",
            "args": [],
            "iteration": [],
            "start": 10.0,
            "end": 11.0,
            "result": "ok",
        }
    ],
    "final": {"x": 0.0, "y": 0.0, "z": 0.0, "armed": False, "battery": 90.0},
    "adapter_error": "",
    "retransmissions": 0,
    "duplicates_dropped": 0,
    "net": {},
}


def summary(**changes: object) -> RunSummary:
    fields: dict[str, object] = {
        "mission": "experiment_b",
        "mission_id": "sha256:abc",
        "outcome": "ok",
        "started": 1000.0,
        "duration_s": 12.5,
        "run_dir": "/runs/b",
        "drones": {
            "Drone1": DroneResult(DroneReport.from_json(REPORT), exit_code=0),
            "Drone2": DroneResult(None, exit_code=3),
        },
        "ground_station": DroneReport.from_json(REPORT),
        "failures": ("Drone2: process exited with code 3",),
        "links": {"Drone1": "left", "Drone2": "up"},
    }
    fields.update(changes)
    return RunSummary(**fields)  # type: ignore[arg-type]


def test_json_round_trip(tmp_path: Path) -> None:
    for original in (
        summary(),
        summary(rollout={"durations": {"ready": 1.5}, "table": {}, "drones": {}}),
        summary(ground_station=None, outcome="not ready: waiting for Drone2"),
    ):
        assert RunSummary.from_json(json.loads(json.dumps(original.to_json()))) == original
        original.write(tmp_path / "s" / "summary.json")
        assert RunSummary.read(tmp_path / "s" / "summary.json") == original


def test_every_key_users_rely_on_is_written() -> None:
    data = summary().to_json()
    assert set(data) == {
        "ok",
        "result",  # the one outcome word: finished, failed, aborted, timed out
        "mission",
        "mission_id",
        "outcome",
        "duration_s",
        "started",
        "run_dir",
        "failures",
        "links",
        "drones",
        "ground_station",
        "operator_commands",  # the operator's pause, hold, land ... in order
    }
    assert data["operator_commands"] == []
    assert "rollout" in summary(rollout={}).to_json()
    assert data["drones"]["Drone1"] == {**REPORT, "exit_code": 0}
    assert data["drones"]["Drone2"] == {
        "ok": False,
        "error": "no report",
        "link": "up",
        "exit_code": 3,
    }


def test_ok_needs_the_outcome_every_drone_and_the_ground_station() -> None:
    ok = {"Drone1": DroneResult(DroneReport.from_json(REPORT))}
    assert summary(drones=ok).ok and summary(drones=ok).to_json()["ok"] is True
    assert not summary().ok  # Drone2 sent no report
    assert not summary(drones=ok, outcome="aborted by the operator").ok
    assert not summary(drones=ok, ground_station=None).ok
    failed = DroneReport.from_json({**REPORT, "ok": False})
    assert not summary(drones={"Drone1": DroneResult(failed)}).ok


def test_a_summary_from_before_failures_and_links_reads() -> None:
    old = summary().to_json()
    del old["failures"], old["links"]
    read = RunSummary.from_json(old)
    assert read.failures == () and read.links == {}
    assert read.drones["Drone2"].report is None and read.drones["Drone1"].host is None


def test_a_report_with_a_missing_key_is_refused() -> None:
    data = summary().to_json()
    del data["drones"]["Drone1"]["triggers_sent"]
    with pytest.raises(ValueError, match="triggers_sent"):
        RunSummary.from_json(data)


def _with_final(**final: object) -> DroneResult:
    base = REPORT["final"]
    assert isinstance(base, dict)
    return DroneResult(DroneReport.from_json({**REPORT, "final": {**base, **final}}))


def test_a_drone_left_armed_did_not_finish_and_the_summary_says_where() -> None:
    hovering = _with_final(armed=True, landed=False, x=1.0, z=2.0)
    on_ground = _with_final(armed=True, landed=True, y=5.0)
    down = _with_final(armed=False, landed=True)
    # Its own report says ok (every action ok); the run does not.
    assert hovering.report is not None and hovering.report.ok and not hovering.ok
    assert hovering.left_armed == "in the air, armed, at (1.00, 0.00, 2.00) m from its home"
    assert on_ground.left_armed == "armed on the ground at (0.00, 5.00, 0.00) m from its home"
    assert down.ok and down.left_armed == ""
    run = summary(
        drones={"Drone1": hovering, "Drone2": on_ground, "Drone3": down},
        failures=(),
        links={},
    )
    assert not run.ok and run.word == "failed"
    assert run.detail == (
        "Drone1 left in the air, armed, at (1.00, 0.00, 2.00) m from its home; "
        "Drone2 left armed on the ground at (0.00, 5.00, 0.00) m from its home"
    )
    # A report from before `landed` was written still reads, and armed is still not finished.
    old = _with_final(armed=True)
    assert old.report is not None and old.report.final is not None
    assert old.report.final.landed is None and old.left_armed.startswith("armed at (")
