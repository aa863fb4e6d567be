"""A roll-out compares programs by content (issue 31): an insertion into one drone's part
redeploys only that drone, over real SSH to two namespace hosts.

Numbered as written, inserting one statement into Drone1's lane (written first) renumbers
every node after it, Drone2's too, and both drones were redeployed.  Renumbered against
the programs of the earlier roll-out (:func:`eamos.compiler.amendment.rekey`), Drone2's
program is the one it runs, node for node: it is kept, and flies with Drone1's new one.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from .fleet_lab import Lab

pytestmark = [pytest.mark.e2e, pytest.mark.xdist_group("fleet-lab")]
LANES = Path(__file__).with_name("lanes.go")


def test_an_insertion_into_drone1s_lane_redeploys_only_drone1_and_both_fly(
    lab: Lab, fleet_keys: Path, tmp_path: Path
) -> None:
    lab.reset("d1", "d2")
    fleet = lab.fleet_file(
        tmp_path / "fleet.toml", {"Drone1": "d1", "Drone2": "d2"}, keys=fleet_keys
    )
    first = lab.eamos("rollout", str(LANES), str(fleet), "--run-dir", str(tmp_path / "run1"))
    assert first.returncode == 0, first.stdout + first.stderr
    drone2 = lab.hosts["d2"].folder / "Lanes" / "programs" / "Drone2.program.json"
    before = drone2.read_bytes()
    edited = tmp_path / "lanes.go"
    text = LANES.read_text()
    edited.write_text(
        text.replace("\tDrone1.FlyByX(-4)\n", "\tDrone1.FlyByZ(1)\n\tDrone1.FlyByX(-4)\n")
    )
    run2 = tmp_path / "run2"
    second = lab.eamos(
        "rollout", str(edited), str(fleet), "--run-dir", str(run2), "--speedup", "20"
    )
    out = second.stdout
    assert second.returncode == 0, out + second.stderr
    assert re.search(r"  Drone2: unchanged, kept: copy \d+\.\d+ s \(config\)", out), out
    assert re.search(r"  Drone1: changed, redeployed: copy \d+\.\d+ s \(program, config\)", out)
    assert drone2.read_bytes() == before  # its program file untouched
    programs = {
        d: json.loads((run2 / "programs" / f"{d}.program.json").read_text())
        for d in ("Drone1", "Drone2")
    }
    # The inserted climb has a new number, after every node of the first roll-out's.
    climb = next(n for n in programs["Drone1"]["nodes"] if n.get("label") == "FlyByZ(1)")
    first_numbers = [
        n["meg"]
        for d in ("Drone1", "Drone2")
        for n in json.loads((tmp_path / "run1" / "programs" / f"{d}.program.json").read_text())[
            "nodes"
        ]
    ]
    assert climb["meg"] > max(first_numbers)
    # The kept Drone2 and the redeployed Drone1 fly the mission together.
    start = lab.eamos("start", str(run2), "--plain")
    assert start.returncode == 0, start.stdout + start.stderr
    summary = json.loads((run2 / "summary.json").read_text())
    assert summary["ok"], summary["outcome"]
    climbs = {
        name: [a["args"] for a in report["actions"] if a["action"] == "FlyByZ"]
        for name, report in summary["drones"].items()
    }
    assert climbs == {"Drone1": [[1.0]], "Drone2": []}
    lab.reset("d1", "d2")
