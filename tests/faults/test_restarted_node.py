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
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest

from eamos.actors.rejoin import (
    PROGRESS_FILE,
    RECORD_FILE,
    NodeRecord,
    acknowledged_in,
    read_progress,
    rejoin_decision,
)
from eamos.logs import read_log
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


@dataclass(frozen=True)
class Restarted:
    """How a run with Drone1's node killed and started again ended."""

    code: int  # the run's exit code
    again_code: int  # the restarted node's
    out: str  # the restarted node's output
    text: str  # the run's output
    summary: dict[str, Any]
    reported: list[dict[str, Any]]  # what the killed node had reported (its journal)


def kill_and_restart(
    run: LiveRun, tmp_path: Path, line: str, phase: str, count: int = 1
) -> Restarted:
    """kill -9 Drone1's node at the ``count``-th output line with ``line`` (its record
    then says ``phase``), start it again with its config, wait for the run's end."""
    again = None
    try:
        run.wait_for(line, within_s=180, count=count)
        pid = node_pid(run.run_dir, "Drone1")
        os.kill(pid, signal.SIGKILL)
        assert wait_gone(pid, 15)
        run.wait_for("Drone1 FAILED: process exited with code -9", within_s=15)
        logs = run.run_dir / "logs" / "Drone1"
        record = read_json(logs / RECORD_FILE)
        assert record["phase"] == phase, record
        reported = read_progress(logs / PROGRESS_FILE)
        again = restart(run.run_dir, "Drone1", tmp_path / "again.out")
        code = run.finish(RUN_TIMEOUT_S)
        again_code = again.wait(60)
    finally:
        run.kill()
        if again is not None and again.poll() is None:
            again.kill()
    out = (tmp_path / "again.out").read_text()
    return Restarted(
        code, again_code, out, run.text(), read_json(tmp_path / "summary.json"), reported
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
        (record("running"), False, True, "cannot resume: nothing records what it did"),
        (record("ended"), False, True, "already ended on this drone"),
    ],
)
def test_rejoin_decision(
    previous: NodeRecord | None, join: bool, restarted: bool, words: str
) -> None:
    got = rejoin_decision(previous, "Drone1", "m", "sha256:p", "d1")
    assert (got.join, got.restarted) == (join, restarted) and words in got.reason, got


def test_a_node_that_ran_resumes_when_nothing_stops_it() -> None:
    got = rejoin_decision(record("running"), "Drone1", "m", "sha256:p", "d1", cannot_resume="")
    assert got.join and got.restarted and got.resume, got
    assert "it resumes from what it reported (node-progress.jsonl)" in got.reason, got
    got = rejoin_decision(record("running"), "Drone1", "m", "sha256:p", "d1", "its vehicle died")
    assert not got.join and not got.resume and "cannot resume: its vehicle died" in got.reason


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
    # "ready": no trigger had reached Drone1.
    ended = kill_and_restart(run, tmp_path, "Drone2 running   FlyByX(6)", "ready")
    out, summary = ended.out, ended.summary
    assert "Drone1 restarted: its node before (pid" in out and "it rejoins the mission" in out, out
    assert ended.again_code == 0, out
    assert summary["outcome"] == "ok" and summary["ok"], (summary["outcome"], ended.text)
    assert summary["result"] == "finished" and summary["failures"] == []
    assert ended.code == 0, ended.text
    d1 = summary["drones"]["Drone1"]
    assert [(a["action"], a["result"]) for a in d1["actions"]] == [
        ("Arm", "ok"),
        ("Takeoff", "ok"),
        ("Land", "ok"),
        ("Disarm", "ok"),
    ]
    for name, report in summary["drones"].items():
        assert landed_disarmed(report), (name, report["final"])


#: Drone1 (a MAVLink vehicle in a process of its own: it outlives the node) flies five
#: 2 m legs in a loop, Drone2 pausing after each (a trigger each way per leg); Drone2 then
#: flies a leg of its own, and both land.
LOOP_LEGS = """
func SEQ_M() {
    PAR_Up()
    RepeatFor(5, SEQ_Leg)
    Drone2.FlyByY(2)
    PAR_Down()
}
func PAR_Up() {
    SEQ_Up1()
    SEQ_Up2()
}
func SEQ_Up1() {
    Drone1.Arm()
    Drone1.Takeoff(2)
}
func SEQ_Up2() {
    Drone2.Arm()
    Drone2.Takeoff(3)
}
func SEQ_Leg() {
    Drone1.FlyByX(2)
    Drone2.PauseFor(1)
}
func PAR_Down() {
    SEQ_Down1()
    SEQ_Down2()
}
func SEQ_Down1() {
    Drone1.Land()
    Drone1.Disarm()
}
func SEQ_Down2() {
    Drone2.Land()
    Drone2.Disarm()
}
"""
LOOP_FLEET = """
[drones.Drone1.hal]
adapter = "mavlink"
sim_vehicle = { autopilot = "ardupilot", prearm_delay_s = 2 }
connect_timeout_s = 20
armable_timeout_s = 90
"""


@pytest.mark.e2e
def test_a_node_killed_in_a_loops_third_iteration_resumes_and_runs_no_action_again(
    tmp_path: Path,
) -> None:
    """kill -9 of Drone1's node during its third leg, restarted: it replays what it had
    reported (no action again, no trigger Drone2 had acknowledged sent again), flies the
    rest of the third leg and the fourth and fifth, the mission finishes ok, and Drone1
    ends 10 m out (a leg flown twice: 12 m)."""
    mission = tmp_path / "legs.go"
    mission.write_text(LOOP_LEGS)
    fleet = tmp_path / "fleet.toml"
    fleet.write_text(LOOP_FLEET)
    run = LiveRun.start(tmp_path, mission, "--fleet", str(fleet), speedup=1, timeout_s=300)
    restarted = kill_and_restart(run, tmp_path, "Drone1 running   FlyByX(2)", "running", count=3)
    out, summary = restarted.out, restarted.summary
    assert "Drone1 restarted: its node before (pid" in out and "it resumes from" in out, out
    assert restarted.again_code == 0, out
    assert summary["ok"], (summary["outcome"], restarted.text)
    assert restarted.code == 0, restarted.text
    ended = {
        (e["node"], tuple(e["iteration"]))
        for e in restarted.reported
        if e.get("state") in ("ok", "failed", "cancelled")
    }
    logs = run.run_dir / "logs" / "Drone1"
    d1 = summary["drones"]["Drone1"]
    done = [(a["action"], tuple(a["iteration"]), a["result"]) for a in d1["actions"]]
    legs = [(a, it) for a, it, _ in done if a == "FlyByX"]
    # Each action once, in order, every leg of the loop: none again, none lost.
    assert legs == [("FlyByX", (i,)) for i in range(5)], done
    pauses = summary["drones"]["Drone2"]["actions"]
    assert [tuple(a["iteration"]) for a in pauses if a["action"] == "PauseFor"] == [
        (i,) for i in range(5)
    ], pauses
    assert [a for a, it, _ in done if not it] == ["Arm", "Takeoff", "Land", "Disarm"], done
    assert all(r == "ok" for _, _, r in done), done
    assert abs(d1["final"]["x"] - 10.0) < 0.5 and landed_disarmed(d1), d1["final"]
    # The restarted node commanded nothing that had ended (its uniform log: the calls
    # after its start).
    calls = [
        e for e in read_log(logs / "uniform.log") if e["event"] in ("uniform.start", "uniform.call")
    ]
    starts = [i for i, e in enumerate(calls) if e["event"] == "uniform.start"]
    assert len(starts) == 2, calls
    again_calls = {e["token"] for e in calls[starts[1] :] if e["event"] == "uniform.call"}
    assert again_calls, calls
    assert not again_calls & {str((node, it)) for node, it in ended}, (again_calls, ended)
    assert len(ended) >= 4  # Arm, Takeoff, two legs had ended
    # The triggers Drone2 had acknowledged (the killed node journaled them) went out once,
    # from the killed node: the restarted one replayed them without sending them again.
    acknowledged = acknowledged_in(restarted.reported)
    assert any(src_dst_it[2] == (1,) for src_dst_it in acknowledged), acknowledged
    logged = list(read_log(logs / "mission.log"))

    def keys(event: str) -> list[tuple[str, str, tuple[int, ...]]]:
        return [(e["src"], e["dst"], tuple(e["iteration"])) for e in logged if e["event"] == event]

    sent = keys("mission.outbridge.sent")
    assert all(sent.count(key) == 1 for key in acknowledged), (sent, acknowledged)
    assert set(keys("mission.outbridge.acknowledged")) == acknowledged
