"""Faults in real runs (issue 17): ``eamos run`` on loopback, one process per drone.

Each test kills or starves something at a known moment and asserts what the
operator sees (and how soon), and where every drone ends.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from eamos.actors.stranded import DEFAULT_PEER_WAIT_LIMIT_S
from eamos.ops.localrun import local_deployment
from eamos.ops.status import local_status
from tests.faults.runs import LiveRun, node_pid, read_json, wait_gone
from tests.support.runs import MISSIONS, REPO, RUN_TIMEOUT_S, eamos

pytestmark = pytest.mark.e2e

#: peer_timeout_s (3 s) + peer_wait_limit_s + landing at speedup 2, with room for a loaded machine.
STRANDED_WITHIN_S = 3 + DEFAULT_PEER_WAIT_LIMIT_S + 60

#: Experiment B's start with a leg of a minute (at speed-up 1): the abort tests' `eamos abort`
#: must find the mission still flying, however long it takes to start on a loaded machine.
LONG_LEG = """
func SEQ_Main() {
    PAR_Arm()
    PAR_Up()
    PAR_Away()
    PAR_Land()
    PAR_Disarm()
}
func PAR_Arm()    { Drone1.Arm(); Drone2.Arm() }
func PAR_Up()     { Drone1.Takeoff(1.5); Drone2.Takeoff(1.5) }
func PAR_Away()   { Drone1.FlyByX(120); Drone2.FlyByX(120) }
func PAR_Land()   { Drone1.Land(); Drone2.Land() }
func PAR_Disarm() { Drone1.Disarm(); Drone2.Disarm() }
"""


def long_leg(tmp_path: Path) -> Path:
    mission = tmp_path / "long_leg.go"
    mission.write_text(LONG_LEG)
    return mission


def test_a_killed_drone_is_told_at_once_and_its_dependent_lands(tmp_path: Path) -> None:
    # experiment_b: Drone2 waits for Drone1 at every corner of the square.
    run = LiveRun.start(tmp_path, MISSIONS / "experiment_b.go", speedup=2, timeout_s=600)
    try:
        run.wait_for("running   FlyByY")
        killed_at = time.monotonic()
        os.kill(node_pid(run.run_dir, "Drone1"), signal.SIGKILL)
        line = run.wait_for("Drone1 FAILED: process exited with code -9", within_s=15)
        told_s = time.monotonic() - killed_at
        run.finish(STRANDED_WITHIN_S + 60)
        ended_s = time.monotonic() - killed_at
    finally:
        run.kill()
    assert told_s < 15, line
    stranded = run.wait_for("Drone2 stranded  end policy: land  (stranded: waited", within_s=0)
    assert "for Drone1, whose link is lost (peer_wait_limit_s = 20)" in stranded
    assert ended_s < STRANDED_WITHIN_S + 60  # not the 600 s mission timeout
    assert run.returncode == 1, run.text()
    summary = read_json(tmp_path / "summary.json")
    assert summary["outcome"].startswith("failed: Drone1: process exited with code -9")
    assert summary["drones"]["Drone1"]["error"] == "no report"
    d2 = summary["drones"]["Drone2"]
    assert d2["aborted"] and d2["abort_reason"].startswith("stranded: waited"), d2
    assert "Drone1" in d2["abort_reason"]
    assert d2["final"]["z"] == pytest.approx(0.0, abs=0.15) and not d2["final"]["armed"]
    assert "stranded" in (run.run_dir / "logs" / "Drone2" / "node.out").read_text()


def test_a_killed_ground_station_leaves_drones_that_land_and_end_on_their_own(
    tmp_path: Path,
) -> None:
    run = LiveRun.start(tmp_path, MISSIONS / "experiment_b.go", speedup=5, timeout_s=600)
    pids = {}
    try:
        run.wait_for("running   FlyByY")
        pids = {d: node_pid(run.run_dir, d) for d in ("Drone1", "Drone2")}
        killed_at = time.monotonic()
        run.kill()  # kill -9 of `eamos run`: the drones run in their own sessions
        flying = local_status(local_deployment(run.run_dir))
        for drone, pid in pids.items():
            assert wait_gone(pid, 120 + DEFAULT_PEER_WAIT_LIMIT_S), f"{drone} still runs"
        ended_s = time.monotonic() - killed_at
        ended = local_status(local_deployment(run.run_dir))
    finally:
        for pid in pids.values():
            with contextlib.suppress(ProcessLookupError):
                os.kill(pid, signal.SIGKILL)
    assert ended_s < 120 + DEFAULT_PEER_WAIT_LIMIT_S
    # What `eamos status` shows for the run folder, from its processes and logs.
    assert [(r.drone, r.up, r.pid) for r in flying] == [(d, True, p) for d, p in pids.items()]
    assert all(r.program != "?" and not r.error for r in flying)
    assert [(r.drone, r.up, r.action) for r in ended] == [(d, False, "finished (ok)") for d in pids]
    assert all(r.landed for r in ended), ended
    for drone in ("Drone1", "Drone2"):
        logs = run.run_dir / "logs" / drone
        assert "no Complete: the ground station has been silent" in (logs / "node.out").read_text()
        report = read_json(logs / "report.json")
        assert report["ok"] and not report["aborted"], (drone, report)
        assert [a["action"] for a in report["actions"]][-2:] == ["Land", "Disarm"]
        assert report["final"]["z"] == pytest.approx(0.0, abs=0.15) and not report["final"]["armed"]


def test_drones_paused_when_the_ground_station_dies_land_on_their_own(tmp_path: Path) -> None:
    """Paused, the drones hold their legs suspended; only the ground station resumes them.
    It is killed: each applies its end policy once it has been silent for the limit."""
    run = LiveRun.start(tmp_path, MISSIONS / "experiment_b.go", speedup=5, timeout_s=600)
    pids = {}
    try:
        run.wait_for("running   FlyByY")
        pids = {d: node_pid(run.run_dir, d) for d in ("Drone1", "Drone2")}
        proc = eamos("pause", str(run.run_dir), timeout=60)
        assert proc.returncode == 0, proc.stdout + proc.stderr
        run.kill()  # kill -9 of `eamos run` while paused
        for drone, pid in pids.items():
            assert wait_gone(pid, 120 + DEFAULT_PEER_WAIT_LIMIT_S), f"{drone} still runs"
    finally:
        for pid in pids.values():
            with contextlib.suppress(ProcessLookupError):
                os.kill(pid, signal.SIGKILL)
    for drone in ("Drone1", "Drone2"):
        logs = run.run_dir / "logs" / drone
        said = (logs / "node.out").read_text()
        assert "stranded: held by the operator, and the ground station" in said, said
        report = read_json(logs / "report.json")
        assert report["aborted"] and report["abort_reason"].startswith("stranded: held"), report
        assert report["final"]["z"] == pytest.approx(0.0, abs=0.15) and not report["final"]["armed"]


def test_eamos_abort_lands_the_drones_of_an_eamos_run_folder(tmp_path: Path) -> None:
    run = LiveRun.start(tmp_path, long_leg(tmp_path), speedup=1, timeout_s=600)
    pids = {}
    try:
        run.wait_for("running   FlyByX")
        pids = {d: node_pid(run.run_dir, d) for d in ("Drone1", "Drone2")}
        run.kill()  # the run's own ground station is gone: eamos abort must be it
        started = time.monotonic()
        proc = eamos("abort", str(run.run_dir), "--timeout", "120", timeout=RUN_TIMEOUT_S)
        abort_s = time.monotonic() - started
        for pid in pids.values():
            assert wait_gone(pid, 60)
    finally:
        for pid in pids.values():
            with contextlib.suppress(ProcessLookupError):
                os.kill(pid, signal.SIGKILL)
    out = proc.stdout + proc.stderr
    assert proc.returncode == 0, out
    assert "not a roll-out folder" not in out and abort_s < 120
    for drone in ("Drone1", "Drone2"):
        report = read_json(run.run_dir / "logs" / drone / "report.json")
        assert report["aborted"] and "aborted by the operator" in report["abort_reason"]
        assert report["final"]["z"] == pytest.approx(0.0, abs=0.15), drone


def test_eamos_abort_signals_a_running_eamos_run(tmp_path: Path) -> None:
    run = LiveRun.start(tmp_path, long_leg(tmp_path), speedup=1, timeout_s=600)
    try:
        run.wait_for("running   FlyByX")
        proc = eamos("abort", str(run.run_dir), "--timeout", "120", timeout=RUN_TIMEOUT_S)
        run.finish(RUN_TIMEOUT_S)
    finally:
        run.kill()
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "signalling the ground station (eamos run" in proc.stdout + proc.stderr
    summary = read_json(tmp_path / "summary.json")
    assert summary["outcome"] == "aborted by the operator"
    for name, report in summary["drones"].items():
        assert report["final"]["z"] == pytest.approx(0.0, abs=0.15), name


FULL_DISK_MB = 32


def _mount_tmpfs(where: Path, size_mb: int) -> bool:
    if os.geteuid() != 0 or shutil.which("mount") is None:
        return False
    where.mkdir(parents=True, exist_ok=True)
    done = subprocess.run(
        ["mount", "-t", "tmpfs", "-o", f"size={size_mb}m", "tmpfs", str(where)],
        capture_output=True,
        text=True,
    )
    return done.returncode == 0


def _fill(where: Path) -> None:
    """Fill the file system under ``where`` until it has no byte left."""
    with contextlib.suppress(OSError), (where / "filler").open("wb", buffering=0) as f:
        for size in (1 << 20, 65536, 4096, 1):
            block = b"\0" * size
            with contextlib.suppress(OSError):
                while True:
                    f.write(block)
    probe = where / "probe"
    with pytest.raises(OSError), probe.open("wb", buffering=0) as p:
        p.write(b"\0" * 4096)  # the disk is full indeed


def test_a_full_disk_under_the_run_folder_never_stops_the_flight(tmp_path: Path) -> None:
    disk = tmp_path / "disk"
    if not _mount_tmpfs(disk, FULL_DISK_MB):
        pytest.skip("needs root and mount -t tmpfs to make a small disk to fill")
    try:
        run = LiveRun.start(
            tmp_path,
            MISSIONS / "experiment_b.go",
            speedup=5,
            timeout_s=300,
            run_dir=disk / "run",
        )
        try:
            run.wait_for("all drones ready: start")
            _fill(disk)
            run.finish(RUN_TIMEOUT_S)
        finally:
            run.kill()
        text = run.text()
        # The --summary copy on a healthy disk is written; the run folder's is named as failed.
        summary = read_json(tmp_path / "summary.json")
        assert f"cannot write {disk / 'run' / 'summary.json'}" in text, text
        assert "internal error" not in text and "Traceback" not in text
        assert run.returncode in (0, 1), text
        for name, report in summary["drones"].items():
            final = report["final"]
            assert final["z"] == pytest.approx(0.0, abs=0.15) and not final["armed"], name
            assert [a["action"] for a in report["actions"]][-1] == "Disarm", name
        assert not (disk / "run" / "summary.json").exists()  # no 0-byte summary left behind
    finally:
        subprocess.run(["umount", "-l", str(disk)], capture_output=True)


def test_the_node_survives_a_log_it_cannot_write(tmp_path: Path) -> None:
    # The full-file trick without root: every log line of one drone goes to /dev/full.
    if not Path("/dev/full").exists():
        pytest.skip("no /dev/full")
    code = (
        "import sys, eamos.logs as L\n"
        "log = L.make_logger(__import__('pathlib').Path('/dev/full'))\n"
        "for i in range(100): log.info('x', i=i)\n"
        "print('written', L.write_errors(log))\n"
    )
    proc = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=60, cwd=REPO
    )
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == "written 100"
    assert proc.stderr.count("cannot write /dev/full") == 1  # told once, not per line


def test_ctrl_c_twice_still_writes_the_summary_and_exits_130(tmp_path: Path) -> None:
    run = LiveRun.start(tmp_path, MISSIONS / "experiment_b.go", speedup=1, timeout_s=600)
    try:
        run.wait_for("running   FlyByX")
        run.proc.send_signal(signal.SIGINT)
        run.wait_for("aborting: aborted by the operator", within_s=30)
        second = time.monotonic()
        run.proc.send_signal(signal.SIGINT)
        run.finish(RUN_TIMEOUT_S)
        ended_s = time.monotonic() - second
    finally:
        run.kill()
    assert run.returncode == 130, run.text()
    assert ended_s < 90  # the drones' processes get SIGTERM, then SIGKILL: bounded
    summary = read_json(tmp_path / "summary.json")
    assert summary["outcome"] == "aborted by the operator" and not summary["ok"]
    assert (tmp_path / "run" / "summary.json").exists()
