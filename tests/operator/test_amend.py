"""``eamos amend`` on a real paused run (issue 31): four simulated drones, real processes.

``eamos run tests/operator/four_lanes.go``; ``eamos pause`` while every drone flies its
first leg; then three amendments through the command line, judged against the run
folder's programs and snapshot: a change to Drone3's and Drone4's later legs is accepted
and staged (the other drones untouched); Drone1 and Drone2 sent at each other is refused
with the separation finding at the new lines; a change to Drone1's running leg is refused
with the node named.  Nothing is applied: the run resumes and flies the mission as written.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tests.operator.runs import HERE, operator, resume_to_the_end, start
from tests.support.four_lanes import HEAD_ON, LATER_PARTS, RUNNING_LEG, amended, line_of
from tests.support.runs import eamos

pytestmark = pytest.mark.e2e

LANES = HERE / "four_lanes.go"


def amend(run_dir: Path, tmp_path: Path, name: str, text: str, *extra: str) -> tuple[int, str]:
    """``eamos amend RUN_DIR NAME`` with ``text`` as the new mission: (exit code, output)."""
    mission = tmp_path / name
    mission.write_text(text)
    proc = eamos("amend", str(run_dir), str(mission), *extra, timeout=120)
    assert "Traceback" not in proc.stderr, proc.stderr
    return proc.returncode, proc.stdout + proc.stderr


def test_amendments_to_a_paused_run_are_judged_and_nothing_is_applied(tmp_path: Path) -> None:
    run = start(tmp_path, LANES, speedup=1)
    try:
        for drone in ("Drone1", "Drone2", "Drone3", "Drone4"):
            run.wait_for(f"{drone} running   FlyByX(12)")
        operator("pause", str(run.run_dir))
        # (a) Drone3's and Drone4's later legs: accepted, the others not touched.
        code, out = amend(run.run_dir, tmp_path, "later.go", amended(*LATER_PARTS), "--json")
        assert code == 0, out
        doc = json.loads(out)
        assert doc["accepted"] and doc["touched"] == ["Drone3", "Drone4"], doc
        assert doc["changes"]["Drone4"]["switch"]["label"] == "FlyByZ(1)"
        staged = Path(doc["staged"])
        assert staged == run.run_dir / "amendments" / "1"
        assert (staged / "programs" / "Drone4.program.json").is_file()
        assert json.loads((staged / "amendment.json").read_text())["accepted"]
        # (b) two drones sent at each other: refused, the finding at the new lines.
        text = amended(*HEAD_ON)
        code, out = amend(run.run_dir, tmp_path, "head_on.go", text)
        assert code == 1, out
        assert f"head_on.go:{line_of(text, 'Drone1.FlyByY(5)')}:" in out, out
        assert "separation" in out or "come within" in out, out
        assert "refused: the check of the rest" in out, out
        # (c) the leg Drone1 is flying: refused with the node named, nothing checked.
        code, out = amend(run.run_dir, tmp_path, "running.go", amended(*RUNNING_LEG))
        assert code == 1, out
        assert f"FlyByX(12) (line {line_of(amended(), 'Drone1.FlyByX(12)')}) is running" in out
        assert not (run.run_dir / "amendments" / "2").exists()  # refusals stage nothing
        summary = resume_to_the_end(run, tmp_path)
    finally:
        run.kill()
    # The run flew the mission as written: no amendment reached a drone.
    for drone, report in summary["drones"].items():
        legs = [a["args"] for a in report["actions"] if a["action"].startswith("FlyBy")]
        assert legs == [[12.0], [-12.0]], (drone, legs)
