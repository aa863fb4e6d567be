"""Issue 28, item 13: a second roll-out while a mission flies.

``eamos rollout M --run-dir run1; eamos start run1 &`` then ``eamos rollout``
of an edited M to ``run2``: the roll-out used to stop the old nodes but not the
old ground station, which then started the new nodes (the unchanged drone flew
the whole mission with no ``eamos start run2``, and ``eamos start run2`` failed:
"eamos-node is not running").  Now the roll-out stops the earlier roll-out's
ground station first (its drones land, it writes its summary), the new nodes
start on nothing but their own deployment's Start, and ``eamos start run2``
flies them.
"""

from __future__ import annotations

import json
import subprocess
import threading
import time
from pathlib import Path

import pytest

from .fleet_lab import REPO, Lab

pytestmark = pytest.mark.e2e
MISSION = REPO / "missions" / "experiment_b.go"


class Lines:
    """A process's stdout read line by line on a thread."""

    def __init__(self, proc: subprocess.Popen[str]) -> None:
        self.proc = proc
        self.lines: list[str] = []
        self.cond = threading.Condition()
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            with self.cond:
                self.lines.append(line.rstrip("\n"))
                self.cond.notify_all()

    def wait_for(self, text: str, within_s: float) -> str:
        deadline = time.monotonic() + within_s
        with self.cond:
            while True:
                found = [ln for ln in self.lines if text in ln]
                if found:
                    return found[0]
                left = deadline - time.monotonic()
                assert left > 0, f"no {text!r} within {within_s} s:\n" + "\n".join(self.lines)
                self.cond.wait(left)


def test_a_second_rollout_stops_the_first_ground_station_and_starts_nothing(
    lab: Lab, fleet_keys: Path, tmp_path: Path
) -> None:
    lab.reset("d1", "d2")
    fleet = lab.fleet_file(
        tmp_path / "fleet.toml", {"Drone1": "d1", "Drone2": "d2"}, keys=fleet_keys
    )
    run1, run2 = tmp_path / "run1", tmp_path / "run2"
    # Slow (about a minute of flight): still flying when the second roll-out launches.
    first = lab.eamos(
        "rollout", str(MISSION), str(fleet), "--run-dir", str(run1), "--speedup", "0.25"
    )
    assert first.returncode == 0, first.stdout + first.stderr
    start1 = lab.popen_eamos("start", str(run1), "--plain")
    start2 = None
    try:
        Lines(start1).wait_for("running   FlyByX", within_s=120)
        edited = tmp_path / "experiment_b.go"  # Drone2's part changed, Drone1's kept
        edited.write_text(MISSION.read_text().replace("Drone2.FlyByZ(0.5)", "Drone2.FlyByZ(0.6)"))
        second = lab.eamos(
            "rollout", str(edited), str(fleet), "--run-dir", str(run2), "--speedup", "5"
        )
        out = second.stdout + second.stderr
        assert second.returncode == 0, out
        assert f"stopping the ground station of the earlier roll-out {run1.resolve()}" in out
        assert "  Drone1: unchanged, kept" in out, out
        # The earlier ground station ended within the roll-out: it aborted, its drones landed.
        assert start1.wait(5) == 1, "the first ground station still runs"
        summary1 = json.loads((run1 / "summary.json").read_text())
        assert summary1["outcome"] == "aborted by the operator", summary1["outcome"]
        for name, report in summary1["drones"].items():
            assert report["final"]["z"] == pytest.approx(0, abs=0.3), name
        started = time.time()
        start2 = lab.popen_eamos("start", str(run2), "--plain")
        out2, err2 = start2.communicate(timeout=240)
    finally:
        for proc in (start1, start2):
            if proc is not None and proc.poll() is None:
                proc.kill()
                proc.communicate()
    assert start2.returncode == 0, out2 + err2
    summary2 = json.loads((run2 / "summary.json").read_text())
    assert summary2["ok"], summary2["outcome"]
    for name, report in summary2["drones"].items():
        # The whole mission, commanded only after run2's own start.
        assert report["actions"][0]["action"] == "Arm", name
        assert report["actions"][0]["start"] >= started - 1, (name, report["actions"][0])
        assert report["final"]["z"] == pytest.approx(0, abs=0.3) and not report["final"]["armed"]
    climbs = {
        name: [a["args"] for a in report["actions"] if a["action"] == "FlyByZ"]
        for name, report in summary2["drones"].items()
    }
    assert climbs == {"Drone1": [[0.5]], "Drone2": [[0.6]]}
    lab.reset("d1", "d2")
