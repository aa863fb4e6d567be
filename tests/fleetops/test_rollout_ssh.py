"""Experiment B rolled out over real SSH to two namespace hosts, flown, edited, flown again.

The module's tests share one fleet (hosts d1 and d2) and run in order: the
first roll-out, the mission, the logs; then an edit of Drone2's part only,
which must redeploy Drone2 and keep Drone1; then status and abort during a
slower run.
"""

from __future__ import annotations

import hashlib
import json
import re
import subprocess
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest

from .fleet_lab import REPO, Lab

pytestmark = [pytest.mark.e2e, pytest.mark.xdist_group("fleet-lab")]
MISSION = REPO / "missions" / "experiment_b.go"
ACTION = re.compile(r"  (Arm|Takeoff|FlyBy[XYZ]|Land|Disarm)\(")  # an action in progress
STEP_LINE = re.compile(r"^(compile|probe|deploy|launch) (\d+\.\d+) s$", re.M)


@dataclass
class Fleet:
    lab: Lab
    fleet: Path
    run_dir: Path
    script: subprocess.CompletedProcess[str]

    def remote(self, drone: str, rel: str) -> Path:
        host = {"Drone1": "d1", "Drone2": "d2"}[drone]
        return self.lab.hosts[host].folder / "experiment_b" / rel


def sha(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


@pytest.fixture(scope="module")
def flown(lab: Lab, fleet_keys: Path, tmp_path_factory: pytest.TempPathFactory) -> Iterator[Fleet]:
    """``scripts/rollout.sh missions/experiment_b.go fleet.toml --speedup 20``."""
    lab.reset("d1", "d2")
    tmp = tmp_path_factory.mktemp("fleet")
    fleet = lab.fleet_file(tmp / "fleet.toml", {"Drone1": "d1", "Drone2": "d2"}, keys=fleet_keys)
    run_dir = tmp / "run1"
    script = lab.rollout_sh(run_dir, str(MISSION), str(fleet), "--speedup", "20")
    print(script.stdout)  # the durations, for the record (pytest -s)
    yield Fleet(lab, fleet, run_dir, script)
    lab.reset("d1", "d2")


def test_rollout_reports_each_step_and_drone_with_durations(flown):
    out = flown.script.stdout
    assert [m[0] for m in STEP_LINE.findall(out)] == ["compile", "probe", "deploy", "launch"]
    for drone in ("Drone1", "Drone2"):
        assert re.search(rf"{drone} \(root@198\.18\.0\.\d:22\): eamos \S+, .* free, new", out)
        assert re.search(rf"{drone}: new, deployed: copy \d+\.\d+ s \(program, config, keys\)", out)
        assert re.search(rf"{drone}: eamos-node started \(pid \d+\)", out)
    assert f"next: eamos start {flown.run_dir}" in out
    start = out
    assert re.search(r"^ready \d+\.\d+ s$", start, re.M), start
    for row in ("mission compilation", "mission deployment", "total roll-out"):
        assert re.search(rf"^  {row} +\d+\.\d+ s$", start, re.M), start


def test_experiment_b_flies_end_to_end(flown):
    assert flown.script.returncode == 0, flown.script.stdout + flown.script.stderr
    summary = json.loads((flown.run_dir / "summary.json").read_text())
    assert summary["ok"] and summary["outcome"] == "ok"
    for name, report in summary["drones"].items():
        assert report["ok"], (name, report)
        # Paper Table 7: triggers on the wire equal the MDG's external arcs.
        assert report["triggers_sent"] == report["external_out"] > 0
        assert report["triggers_received"] == report["external_in"] > 0
        assert len(report["actions"]) == 9 and report["host"].startswith("root@198.18.0.")
    table = summary["rollout"]["table"]
    assert set(table) == {"mission compilation", "mission deployment", "total roll-out"}
    assert table["total roll-out"] >= table["mission compilation"] + table["mission deployment"]
    # The nodes exit after the mission (Complete), leaving their report.
    for drone, host in (("Drone1", "d1"), ("Drone2", "d2")):
        assert flown.lab.wait_no_nodes(flown.lab.hosts[host], 30)
        assert json.loads(flown.remote(drone, f"logs/{drone}/report.json").read_text())["ok"]


def test_logs_fetch_collects_every_drone(flown):
    assert "fetching the logs of Drone1, Drone2" in flown.script.stdout  # rollout.sh did
    proc = flown.lab.eamos("logs", "fetch", str(flown.run_dir))
    assert proc.returncode == 0, proc.stdout + proc.stderr
    for drone in ("Drone1", "Drone2"):
        folder = flown.run_dir / "logs" / drone
        for name in ("mission.log", "uniform.log", "adapter.log", "node.out", "report.json"):
            assert (folder / name).is_file(), (drone, name)
        assert sha(folder / "mission.log") == sha(flown.remote(drone, f"logs/{drone}/mission.log"))
    # With the fleet file instead of the run folder, the drones say what they hold.
    other = flown.run_dir.parent / "fetched"
    proc = flown.lab.eamos("logs", "fetch", str(flown.fleet), "-o", str(other))
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert (other / "logs" / "Drone2" / "uniform.log").is_file()


def test_report_of_the_fleet_run(flown):
    assert f"report: {flown.run_dir}/report.html" in flown.script.stdout  # rollout.sh wrote it
    page = (flown.run_dir / "report.html").read_text()
    assert "total roll-out" in page and "root@198.18.0." in page


def test_an_edit_of_drone2_redeploys_only_drone2(flown, tmp_path):
    before = {
        d: (
            flown.remote(d, f"programs/{d}.program.json").stat().st_mtime_ns,
            sha(flown.remote(d, f"programs/{d}.program.json")),
        )
        for d in ("Drone1", "Drone2")
    }
    edited = tmp_path / "experiment_b.go"  # same mission, one drone's part changed
    edited.write_text(MISSION.read_text().replace("Drone2.FlyByZ(0.5)", "Drone2.FlyByZ(0.6)"))
    run_dir = tmp_path / "run2"
    proc = flown.lab.eamos(
        "rollout", str(edited), str(flown.fleet), "--run-dir", str(run_dir), "--speedup", "20"
    )
    out = proc.stdout
    assert proc.returncode == 0, out + proc.stderr
    print(out)
    # Every roll-out copies the configs (each names the roll-out's deployment id).
    assert re.search(r"  Drone1: unchanged, kept: copy \d+\.\d+ s \(config\)", out), out
    assert re.search(r"  Drone2: changed, redeployed: copy \d+\.\d+ s \(program, config\)", out)
    after1 = flown.remote("Drone1", "programs/Drone1.program.json")
    after2 = flown.remote("Drone2", "programs/Drone2.program.json")
    assert (after1.stat().st_mtime_ns, sha(after1)) == before["Drone1"]
    assert after2.stat().st_mtime_ns != before["Drone2"][0] and sha(after2) != before["Drone2"][1]
    assert sha(after2) == sha(run_dir / "programs" / "Drone2.program.json")
    rollout = json.loads((run_dir / "rollout.json").read_text())
    assert rollout["drones"]["Drone1"]["state"] == "unchanged, kept"
    assert rollout["drones"]["Drone1"]["copied"]["program"] is False
    # Both drones take part: the kept one is restarted with the program it has.
    start = flown.lab.eamos("start", str(run_dir), "--plain")
    print(start.stdout)
    assert start.returncode == 0, start.stdout + start.stderr
    summary = json.loads((run_dir / "summary.json").read_text())
    climbs = {
        name: [a["args"] for a in report["actions"] if a["action"] == "FlyByZ"]
        for name, report in summary["drones"].items()
    }
    assert climbs == {"Drone1": [[0.5]], "Drone2": [[0.6]]}
    for report in summary["drones"].values():
        assert report["triggers_sent"] == report["external_out"]
        assert report["triggers_received"] == report["external_in"]


def test_status_during_a_run_then_abort(flown, tmp_path):
    run_dir = tmp_path / "run3"
    # Real time (about 15 s of flight): time to look at the drones in the air.
    proc = flown.lab.eamos(
        "rollout", str(MISSION), str(flown.fleet), "--run-dir", str(run_dir), "--speedup", "1"
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
    start = flown.lab.popen_eamos("start", str(run_dir), "--plain")
    try:
        deadline = time.monotonic() + 60
        rows: dict[str, str] = {}
        status = None
        while time.monotonic() < deadline:
            status = flown.lab.eamos("status", str(run_dir), "--listen", "1")
            rows = {ln.split()[0]: ln for ln in status.stdout.splitlines()[2:] if ln.strip()}
            busy = [r for r in rows.values() if "up (pid" in r and ACTION.search(r)]
            if len(busy) == 2:
                break
        assert status is not None and status.returncode == 0, status and status.stderr
        print(status.stdout)
        for drone in ("Drone1", "Drone2"):
            row = rows[drone]
            assert "up (pid" in row and ACTION.search(row), status.stdout
            assert re.search(r"-?\d+\.\d, -?\d+\.\d, -?\d+\.\d \((live|log)\)", row), row
        abort = flown.lab.eamos("abort", str(run_dir), "--timeout", "90")
        print(abort.stdout, abort.stderr)
        assert abort.returncode == 0, abort.stdout + abort.stderr
        assert "signalling the ground station" in abort.stdout
        assert "Drone1: landed" in abort.stdout and "Drone2: landed" in abort.stdout
        out, err = start.communicate(timeout=120)
    finally:
        if start.poll() is None:
            start.kill()
            start.communicate()
    assert start.returncode == 1, out + err
    summary = json.loads((run_dir / "summary.json").read_text())
    assert summary["outcome"] == "aborted by the operator"
    for report in summary["drones"].values():
        assert report["aborted"] and report["final"]["z"] == pytest.approx(0, abs=0.3)


def test_abort_without_a_ground_station(flown, tmp_path):
    # The nodes are up and waiting; no `eamos start`: abort takes the ground station's place.
    run_dir = tmp_path / "run4"
    proc = flown.lab.eamos("rollout", str(MISSION), str(flown.fleet), "--run-dir", str(run_dir))
    assert proc.returncode == 0, proc.stdout + proc.stderr
    abort = flown.lab.eamos("abort", str(flown.fleet), "--mission", "experiment_b")
    print(abort.stdout, abort.stderr)
    assert abort.returncode == 0, abort.stdout + abort.stderr
    assert "broadcasting abort to Drone1, Drone2" in abort.stdout
    assert "Drone1: landed" in abort.stdout and "Drone2: landed" in abort.stdout
    for drone, host in (("Drone1", "d1"), ("Drone2", "d2")):
        report = json.loads(flown.remote(drone, f"logs/{drone}/report.json").read_text())
        assert report["aborted"] and report["abort_reason"] == "aborted by the operator"
        assert report["actions"] == []
        assert flown.lab.wait_no_nodes(flown.lab.hosts[host], 30)
