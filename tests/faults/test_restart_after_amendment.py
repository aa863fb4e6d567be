"""A node restarted after an amendment resumes the amended program (issue 31).

Drone1 flies a MAVLink vehicle in a process of its own (it outlives the node); Drone2
waits for it before both land.  While Drone1 flies its first leg, ``eamos amend --apply``
splits its way back in two (Drone2's landing now waits for the second half); during its
second leg its node is killed with ``kill -9`` and started again with its config.  The node had
kept the amended program as its program file and record (``node-state.json``), so the new
node resumes it from its progress journal: what had ended is not flown again, the second
leg flies its rest, and the way back is the amended one.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tests.faults.runs import LiveRun
from tests.faults.test_restarted_node import LOOP_FLEET, kill_and_restart, landed_disarmed
from tests.support.runs import eamos

MISSION = """
var Drone1 Quadcopter
var Drone2 Quadcopter

func SEQ_M() {
    PAR_Out()
    PAR_Down()
}
func PAR_Out() {
    SEQ_One()
    SEQ_Two()
}
func SEQ_One() {
    Drone1.Arm()
    Drone1.Takeoff(2)
    Drone1.FlyByX(4)
    Drone1.FlyByX(4)
    Drone1.FlyByX(-8)
}
func SEQ_Two() {
    Drone2.Arm()
    Drone2.Takeoff(3)
    Drone2.FlyByY(4)
}
func PAR_Down() {
    SEQ_Down1()
    Drone2.Land()
}
func SEQ_Down1() {
    Drone1.Land()
    Drone1.Disarm()
}
"""
#: Drone1's vehicle, as in the restart test: a MAVLink vehicle in a process of its own.
FLEET = LOOP_FLEET


@pytest.mark.e2e
def test_a_node_restarted_after_an_amendment_resumes_the_amended_program(
    tmp_path: Path,
) -> None:
    mission = tmp_path / "legs.go"
    mission.write_text(MISSION)
    fleet = tmp_path / "fleet.toml"
    fleet.write_text(FLEET)
    split = tmp_path / "split.go"
    split.write_text(MISSION.replace("    Drone1.FlyByX(-8)\n", "    Drone1.FlyByX(-4)\n" * 2))
    run = LiveRun.start(tmp_path, mission, "--fleet", str(fleet), speedup=1, timeout_s=300)
    try:
        run.wait_for("Drone1 running   FlyByX(4)", within_s=180)
        proc = eamos("amend", str(run.run_dir), str(split), "--apply", timeout=120)
        assert proc.returncode == 0, proc.stdout + proc.stderr
        assert "applied: Drone1, Drone2 switched" in proc.stdout, proc.stdout
    except BaseException:
        run.kill()
        raise
    restarted = kill_and_restart(run, tmp_path, "Drone1 running   FlyByX(4)", "running", count=2)
    out, summary = restarted.out, restarted.summary
    assert "Drone1 restarted: its node before (pid" in out and "it resumes from" in out, out
    assert restarted.again_code == 0, out
    assert summary["ok"], (summary["outcome"], restarted.text)
    d1 = summary["drones"]["Drone1"]
    legs = [a["args"] for a in d1["actions"] if a["action"] == "FlyByX"]
    # Each leg once (none flown again after the restart), the way back as amended.
    assert legs == [[4.0], [4.0], [-4.0], [-4.0]], d1["actions"]
    assert abs(d1["final"]["x"]) < 0.5 and landed_disarmed(d1), d1["final"]
    staged = run.run_dir / "amendments" / "1" / "programs" / "Drone1.program.json"
    record = json.loads((run.run_dir / "logs" / "Drone1" / "node-state.json").read_text())
    assert record["program"] == json.loads(staged.read_text())["checksum"], record
