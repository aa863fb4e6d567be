"""An amendment applied to a rolled-out fleet in flight (issue 31), over real SSH and CURVE.

``tests/fleetops/lanes.go`` with a long first leg, rolled out to two namespace hosts and
started with ``eamos start``; while both fly their first leg, ``eamos amend RUN_DIR NEW.go
--apply`` on the operator's machine splits Drone1's way back in two.  The ground station
sends Drone1 its new program over the fleet's encrypted links; Drone1 switches, keeps the
amended program in its deploy folder (a restart of its node would resume it), and flies
its new part; Drone2, not touched, is told nothing and flies its lane as written.
"""

from __future__ import annotations

import json
import threading
from pathlib import Path

import pytest

from .fleet_lab import Lab

pytestmark = [pytest.mark.e2e, pytest.mark.xdist_group("fleet-lab")]
LANES = Path(__file__).with_name("lanes.go")
#: A first leg long enough for the amendment to be checked and applied while it flies.
LONG = LANES.read_text().replace("FlyByX(4)", "FlyByX(16)").replace("FlyByX(-4)", "FlyByX(-16)")


def test_an_amendment_reaches_a_rolled_out_drone_over_its_link(
    lab: Lab, fleet_keys: Path, tmp_path: Path
) -> None:
    lab.reset("d1", "d2")
    mission = tmp_path / "lanes.go"
    mission.write_text(LONG)
    fleet = lab.fleet_file(
        tmp_path / "fleet.toml", {"Drone1": "d1", "Drone2": "d2"}, keys=fleet_keys
    )
    run = tmp_path / "run"
    rolled = lab.eamos("rollout", str(mission), str(fleet), "--run-dir", str(run))
    assert rolled.returncode == 0, rolled.stdout + rolled.stderr
    start = lab.popen_eamos("start", str(run), "--plain")
    lines: list[str] = []
    seen = threading.Condition()

    def read() -> None:
        assert start.stdout is not None
        for line in start.stdout:
            with seen:
                lines.append(line)
                seen.notify_all()

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    try:
        with seen:
            assert seen.wait_for(
                lambda: sum("running   FlyByX(16)" in line for line in lines) >= 2, 180
            ), "".join(lines)
        amended = tmp_path / "split.go"
        amended.write_text(
            LONG.replace("\tDrone1.FlyByX(-16)\n", "\tDrone1.FlyByX(-8)\n\tDrone1.FlyByX(-8)\n")
        )
        out = lab.eamos("amend", str(run), str(amended), "--apply", "--json", timeout=180)
        assert out.returncode == 0, out.stdout + out.stderr
        doc = json.loads(out.stdout)
        assert doc["applied"] is True and doc["touched"] == ["Drone1"], doc
        assert start.wait(240) == 0, "".join(lines) + (start.stderr.read() if start.stderr else "")
    finally:
        if start.poll() is None:
            start.kill()
            start.wait(30)
    summary = json.loads((run / "summary.json").read_text())
    assert summary["ok"], summary["outcome"]
    legs = {
        name: [a["args"] for a in report["actions"] if a["action"] == "FlyByX"]
        for name, report in summary["drones"].items()
    }
    assert legs == {"Drone1": [[16.0], [-8.0], [-8.0]], "Drone2": [[16.0], [-16.0]]}, legs
    # Drone1 keeps the amended program where its node reads it; Drone2's is untouched.
    staged = json.loads((run / "amendments" / "1" / "programs" / "Drone1.program.json").read_text())
    deployed = lab.hosts["d1"].folder / "Lanes" / "programs" / "Drone1.program.json"
    assert json.loads(deployed.read_text())["checksum"] == staged["checksum"]
    lab.reset("d1", "d2")
