"""Try through real processes (``eamos run``): one drone's vehicle rejects an action inside
Body, the other drone's leg is cancelled mid-flight, OnFailure runs, the run finishes ok."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.support.runs import MISSIONS, REPO, run_mission

pytestmark = pytest.mark.e2e

REJECT = REPO / "tests" / "virtual" / "try_reject.toml"


def test_try_catches_a_rejected_action_and_cancels_the_other_drone(tmp_path: Path) -> None:
    proc, summary = run_mission(tmp_path, MISSIONS / "try_rescue.go", "--fleet", str(REJECT))
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert summary["ok"] and summary["result"] == "finished"
    d2 = summary["drones"]["Drone2"]
    assert [(a["action"], a["result"]) for a in d2["actions"]] == [
        ("Arm", "ok"),
        ("Takeoff", "ok"),
        ("FlyByY", "ok"),
        ("FlyByZ", "caught"),
        ("FlyToXYZ", "ok"),
        ("Land", "ok"),
        ("Disarm", "ok"),
    ]
    assert d2["actions"][3]["reason"] == "rejected by vehicle; caught by the Try at line 16"
    assert d2["ok"] and not d2["blocked_nodes"]
    d1 = summary["drones"]["Drone1"]
    assert [(a["action"], a["result"]) for a in d1["actions"]] == [
        ("Arm", "ok"),
        ("Takeoff", "ok"),
        ("FlyByX", "cancelled"),
        ("FlyToXYZ", "ok"),
        ("Land", "ok"),
        ("Disarm", "ok"),
    ]
    # Cancelled mid-flight: it had not flown its 30 m (the recovery brought it back home).
    assert d1["ok"] and d1["final"]["z"] == pytest.approx(0.0, abs=0.2)
    assert "Body failed: the failure is caught, OnFailure runs" in proc.stdout
    assert "FlyByZ caught: rejected by vehicle; caught by the Try at line 16" in proc.stdout
    # Every external arc carried one trigger, as for a mission without handlers.
    for name in ("Drone1", "Drone2"):
        d = summary["drones"][name]
        assert (d["triggers_sent"], d["triggers_received"]) == (d["external_out"], d["external_in"])


FAST_DRAIN = REPO / "tests" / "virtual" / "fast_drain.toml"


def test_whenever_on_battery_fires_twice_through_real_processes(tmp_path: Path) -> None:
    proc, summary = run_mission(
        tmp_path, MISSIONS / "whenever_battery.go", "--fleet", str(FAST_DRAIN)
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert summary["ok"]
    d1 = summary["drones"]["Drone1"]["actions"]
    assert [a["iteration"] for a in d1 if a["action"] == "FlyByZ"] == [[0], [0], [1], [1]]
    suspended = [a for a in d1 if a["result"] == "cancelled"]
    assert [a["reason"] for a in suspended] == ["suspended: a Whenever handler runs"] * 2
    resumed = [a for a in d1 if a["action"] == "FlyByX" and 0 < a["args"][0] < 20]
    assert len(resumed) == 2  # each leg re-issued for what was left of it
    assert summary["drones"]["Drone1"]["final"]["x"] == pytest.approx(0.0, abs=0.3)
    assert proc.stdout.count("became true: Handler runs") == 2


def test_abandon_through_real_processes(tmp_path: Path) -> None:
    # Drone1's battery (in its process) and Drone2's legs (in another) run on two
    # simulation clocks: at a speed-up of 5 the Abandon() comes about 1.6 s of wall time
    # before Drone2's last leg would end (8.2 s of mission time in the virtual run).
    proc, summary = run_mission(
        tmp_path, MISSIONS / "whenever_abandon.go", "--fleet", str(FAST_DRAIN), speedup=5
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
    d2 = summary["drones"]["Drone2"]["actions"]
    assert [(a["action"], a["result"]) for a in d2][-3:] == [
        ("FlyByY", "cancelled"),
        ("Land", "ok"),
        ("Disarm", "ok"),
    ]
    d1 = summary["drones"]["Drone1"]["actions"]
    assert [a["action"] for a in d1][-3:] == ["FlyToXYZ", "Land", "Disarm"]
    assert "Abandon(): the rest of the block is skipped" in proc.stdout
