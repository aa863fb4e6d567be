"""A drone taken out of a flying mission by the operator (issue 30), real processes.

``eamos drone RUN_DIR Drone2 land`` while Drone2 flies a long leg:

* inside a Try's Body (try_land.go): Drone2's leg fails "landed by the operator", the Try
  catches it, Drone1's leg is cancelled and OnFailure (Drone1 back above home) runs;
* outside a Try (wait_land.go): Drone1, waiting for Drone2's leg, is blocked at once
  and applies its end policy (it lands) instead of waiting.

Either way nobody is left in the air, and the command is in the summary.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

from tests.operator.runs import HERE, log_lines, operator, start

pytestmark = pytest.mark.e2e


def land_drone2_during_its_leg(tmp_path: Path, mission: str) -> tuple[dict[str, Any], Path]:
    run = start(tmp_path, HERE / mission, speedup=4)
    try:
        run.wait_for("Drone2 running   FlyByY(30)")
        operator("drone", str(run.run_dir), "Drone2", "land")
        run.finish(180)
    finally:
        run.kill()
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert [(c["command"], c["drone"]) for c in summary["operator_commands"]] == [
        ("land", "Drone2")
    ]
    for name, drone in summary["drones"].items():
        final = drone["final"]
        assert final["landed"] and not final["armed"], (name, final)
    # The operator's terminal says who obeyed what, from whom.
    assert "Drone2 OPERATOR: landing (operator): land from cli user " in run.text()
    heard = log_lines(run.run_dir, "Drone2", "mission", "mission.operator")
    assert [(e["command"], e["target"]) for e in heard] == [("land", "Drone2")]
    assert heard[0]["origin"].startswith("cli user ")
    return summary, run.run_dir


def results(summary: dict[str, Any], drone: str) -> list[tuple[str, str, str]]:
    return [
        (a["action"], a["result"], a.get("reason", "")) for a in summary["drones"][drone]["actions"]
    ]


def test_a_drone_landed_inside_a_try_body_is_caught(tmp_path: Path) -> None:
    summary, _ = land_drone2_during_its_leg(tmp_path, "try_land.go")
    two = results(summary, "Drone2")
    leg = [r for r in two if r[0] == "FlyByY"]
    assert leg and leg[0][1] == "caught" and "landed by the operator" in leg[0][2], two
    one = results(summary, "Drone1")
    # Its leg was cancelled by the Try, OnFailure flew it back, then it landed.
    assert [r[0] for r in one] == ["Arm", "Takeoff", "FlyByX", "FlyToXYZ", "Land", "Disarm"], one
    assert one[2][1] == "cancelled" and one[3][1] == "ok" and one[4][1] == "ok", one
    # Drone2's own later actions fail: it is out of the mission.
    assert ("Land", "failed", "landed by the operator") in two, two


def test_drones_waiting_for_a_landed_drone_apply_their_policy(tmp_path: Path) -> None:
    summary, run_dir = land_drone2_during_its_leg(tmp_path, "wait_land.go")
    one = results(summary, "Drone1")
    assert [r[0] for r in one] == ["Arm", "Takeoff"], one  # FlyByX never ran
    assert not summary["drones"]["Drone1"]["ok"]
    stranded = log_lines(run_dir, "Drone1", "mission", "mission.stranded")
    assert stranded and stranded[0]["policy"] == "land", stranded
    landed_at = log_lines(run_dir, "Drone2", "mission", "mission.operator")[0]["ts"]
    # At once, not after peer_wait_limit_s: the failed leg reached it as a trigger.
    assert stranded[0]["ts"] - landed_at < 10


def test_a_drone_sent_home_lands_at_home(tmp_path: Path) -> None:
    run = start(tmp_path, HERE / "wait_land.go", speedup=4)
    try:
        run.wait_for("Drone2 running   FlyByY(30)")
        operator("drone", str(run.run_dir), "Drone2", "return-home")
        run.finish(180)
    finally:
        run.kill()
    summary = json.loads((tmp_path / "summary.json").read_text())
    two = results(summary, "Drone2")
    assert two[2][:2] == ("FlyByY", "failed") and "sent home by the operator" in two[2][2], two
    final = summary["drones"]["Drone2"]["final"]
    # Home (where it took off), not where the command found it; landed and disarmed.
    assert abs(final["x"]) < 0.5 and abs(final["y"]) < 0.5, final
    assert final["landed"] and not final["armed"], final
    left = [e for e in log_lines(run.run_dir, "Drone2", "uniform", "uniform.taken_out")]
    assert [e["how"] for e in left] == ["return-home"]


def test_a_released_drone_is_never_commanded_again(tmp_path: Path) -> None:
    run = start(tmp_path, HERE / "wait_land.go", speedup=4)
    try:
        run.wait_for("Drone2 running   FlyByY(30)")
        operator("drone", str(run.run_dir), "Drone2", "release")
        run.finish(180)
    finally:
        run.kill()
    summary = json.loads((tmp_path / "summary.json").read_text())
    two = results(summary, "Drone2")
    assert two[2] == ("FlyByY", "failed", "released to a pilot by the operator"), two
    # The pilot has it: EAMOS neither landed it nor commanded it after the release ...
    released_at = log_lines(run.run_dir, "Drone2", "uniform", "uniform.taken_out")[0]["ts"]
    later = [
        e
        for e in log_lines(run.run_dir, "Drone2", "adapter", "adapter.abort")
        + log_lines(run.run_dir, "Drone2", "adapter", "adapter.action.start")
        if e["ts"] > released_at
    ]
    assert later == [], later
    # ... and the summary says where it was left, with the pilot.
    drone = summary["drones"]["Drone2"]
    assert not drone["ok"] and drone["vehicle"]["taken_over"]["mode"] == "RELEASED by the operator"
    assert "Drone2: taken over by the pilot in RELEASED by the operator at (" in run.text()
    # Drone1, waiting for it, applied its policy and landed.
    assert summary["drones"]["Drone1"]["final"]["landed"]
