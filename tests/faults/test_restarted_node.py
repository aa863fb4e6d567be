"""Issue 28, item 4: a node restarted mid-mission refuses to rejoin, unless nothing had run.

A drone's node killed and started again with the same config remembers
nothing, while its peers and the ground station resend it every trigger and
the Start at once: run from the start, its ``Takeoff`` fired before its own
``Arm``.  Now the restarted node reads its record (``node-state.json``): if a
trigger had reached its nodes it refuses, at once and before touching the
vehicle or the network, with one clear line and exit code 1; if nothing had
run it rejoins, and a mission that then completes says so (not ``failed``).
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest

from eamos.actors.rejoin import RECORD_FILE, NodeRecord, rejoin_decision
from tests.faults.runs import LiveRun, node_pid, read_json, wait_gone
from tests.support.runs import MISSIONS, REPO, RUN_TIMEOUT_S

#: The restarted node decides before it opens a socket: it ends within this.
REFUSED_WITHIN_S = 60

#: Drone1 waits, idle on the ground, until Drone2 has flown its part.
DRONE1_WAITS = """
func SEQ_M() {
    Drone2.Arm()
    Drone2.Takeoff(2)
    Drone2.FlyByX(6)
    Drone2.FlyByY(6)
    Drone2.Land()
    Drone2.Disarm()
    Drone1.Arm()
    Drone1.Takeoff(1)
    Drone1.Land()
    Drone1.Disarm()
}
"""


def landed_disarmed(report: dict[str, Any]) -> bool:
    final = report["final"]
    return abs(final["z"]) < 0.15 and not final["armed"] and final.get("landed") is not False


def restart(run_dir: Path, drone: str, out: Path) -> subprocess.Popen[bytes]:
    """``eamos-node --config run/configs/<drone>.toml`` again, as an operator would."""
    with out.open("wb") as stream:
        return subprocess.Popen(
            [
                sys.executable,
                "-m",
                "eamos.cli.node",
                "--config",
                str(run_dir / "configs" / f"{drone}.toml"),
            ],
            stdout=stream,
            stderr=subprocess.STDOUT,
            stdin=subprocess.DEVNULL,
            cwd=REPO,
            start_new_session=True,
        )


# -- the decision, pure ---------------------------------------------------------------------


def record(phase: str, deployment: str = "d1") -> NodeRecord:
    return NodeRecord("Drone1", "m", "sha256:p", deployment, phase, 42, 1.0e9)


@pytest.mark.parametrize(
    ("previous", "join", "restarted", "words"),
    [
        (None, True, False, "a fresh start"),
        (record("running", deployment="other"), True, False, "a fresh start"),
        (record("ready"), True, True, "nothing had run"),
        (record("running"), False, True, "its peers would resend their triggers"),
        (record("ended"), False, True, "already ended on this drone"),
    ],
)
def test_rejoin_decision(
    previous: NodeRecord | None, join: bool, restarted: bool, words: str
) -> None:
    got = rejoin_decision(previous, "Drone1", "m", "sha256:p", "d1")
    assert (got.join, got.restarted) == (join, restarted) and words in got.reason, got


def test_without_a_deployment_an_ended_record_is_the_run_before() -> None:
    got = rejoin_decision(record("ended", deployment=""), "Drone1", "m", "sha256:p", "")
    assert got.join and not got.restarted
    got = rejoin_decision(record("running", deployment=""), "Drone1", "m", "sha256:p", "")
    assert not got.join and got.restarted
    assert f"remove {RECORD_FILE}" in got.reason, got


# -- real runs -----------------------------------------------------------------------------


@pytest.mark.e2e
def test_a_node_restarted_after_it_ran_refuses_to_rejoin(tmp_path: Path) -> None:
    run = LiveRun.start(tmp_path, MISSIONS / "experiment_c.go", speedup=2, timeout_s=300)
    again = None
    try:
        run.wait_for("Drone1 running   Takeoff(1.5)", within_s=120)
        os.kill(node_pid(run.run_dir, "Drone1"), signal.SIGKILL)
        run.wait_for("Drone1 FAILED: process exited with code -9", within_s=15)
        logs = run.run_dir / "logs" / "Drone1"
        before = {p.name: p.read_bytes() for p in logs.iterdir() if p.suffix == ".log"}
        assert read_json(logs / RECORD_FILE)["phase"] == "running"
        started = time.monotonic()
        again = restart(run.run_dir, "Drone1", tmp_path / "again.out")
        code = again.wait(REFUSED_WITHIN_S)
        refused_s = time.monotonic() - started
        run.finish(RUN_TIMEOUT_S)
    finally:
        run.kill()
        if again is not None and again.poll() is None:
            again.kill()
    out = (tmp_path / "again.out").read_text()
    assert code == 1 and refused_s < REFUSED_WITHIN_S, out
    assert "eamos-node Drone1: Drone1 restarted mid-mission: its node before (pid" in out, out
    assert "it refuses to rejoin" in out and "Traceback" not in out, out
    # Nothing was commanded, nothing logged: the logs are the killed node's, unchanged.
    after = {p.name: p.read_bytes() for p in logs.iterdir() if p.suffix == ".log"}
    assert after == before
    summary = read_json(tmp_path / "summary.json")
    assert summary["outcome"].startswith("failed: Drone1: process exited with code -9")
    assert summary["drones"]["Drone1"]["error"] == "no report"
    for name in ("Drone2", "Drone3"):
        assert landed_disarmed(summary["drones"][name]), (name, summary["drones"][name])


@pytest.mark.e2e
def test_a_node_restarted_before_anything_ran_rejoins_and_the_mission_finishes(
    tmp_path: Path,
) -> None:
    mission = tmp_path / "waits.go"
    mission.write_text(DRONE1_WAITS)
    run = LiveRun.start(tmp_path, mission, speedup=1, timeout_s=300)
    again = None
    try:
        run.wait_for("Drone2 running   FlyByX(6)", within_s=120)
        pid = node_pid(run.run_dir, "Drone1")
        os.kill(pid, signal.SIGKILL)
        assert wait_gone(pid, 15)
        run.wait_for("Drone1 FAILED: process exited with code -9", within_s=15)
        record = read_json(run.run_dir / "logs" / "Drone1" / RECORD_FILE)
        assert record["phase"] == "ready", record  # no trigger had reached Drone1
        again = restart(run.run_dir, "Drone1", tmp_path / "again.out")
        code = run.finish(RUN_TIMEOUT_S)
        again_code = again.wait(60)
    finally:
        run.kill()
        if again is not None and again.poll() is None:
            again.kill()
    text = run.text()
    out = (tmp_path / "again.out").read_text()
    assert "Drone1 restarted: its node before (pid" in out and "it rejoins the mission" in out, out
    assert again_code == 0, out
    summary = read_json(tmp_path / "summary.json")
    assert summary["outcome"] == "ok" and summary["ok"], (summary["outcome"], text)
    assert summary["result"] == "finished" and summary["failures"] == []
    assert code == 0, text
    d1 = summary["drones"]["Drone1"]
    assert [(a["action"], a["result"]) for a in d1["actions"]] == [
        ("Arm", "ok"),
        ("Takeoff", "ok"),
        ("Land", "ok"),
        ("Disarm", "ok"),
    ]
    for name, report in summary["drones"].items():
        assert landed_disarmed(report), (name, report["final"])
