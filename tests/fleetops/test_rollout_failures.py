"""Roll-outs that must stop with a clear message: every case against real sshd hosts.

None of these may start a node anywhere ("nothing was copied or started"),
except the drone that never becomes ready, where the ground station must not
send the start trigger and the others must not fly.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from eamos import __version__

from .fleet_lab import REPO, Lab

pytestmark = [pytest.mark.e2e, pytest.mark.xdist_group("fleet-lab")]
MISSION = REPO / "missions" / "experiment_b.go"


@pytest.fixture(autouse=True)
def clean(lab: Lab):
    """Every test starts from empty drones and leaves none running."""
    lab.reset("spare", "d2")
    yield
    lab.reset("spare", "d2")


def rollout(lab: Lab, fleet: Path, run_dir: Path, *extra: str):
    return lab.eamos("rollout", str(MISSION), str(fleet), "--run-dir", str(run_dir), *extra)


def assert_nothing_started(lab: Lab, *hosts: str) -> None:
    for name in hosts:
        host = lab.hosts[name]
        assert lab.node_pids(host) == [], f"a node runs on {name}"
        assert not list(host.folder.glob("*/programs/*.program.json")), f"files on {name}"


def test_unreachable_host_stops_before_anything_is_copied(lab, fleet_keys, tmp_path):
    fleet = lab.fleet_file(
        tmp_path / "fleet.toml", {"Drone1": "spare", "Drone2": "nossh"}, keys=fleet_keys
    )
    proc = rollout(lab, fleet, tmp_path / "run")
    # "Could not connect" in the one exit-code table (it was 1 before the table).
    assert proc.returncode == 3, proc.stdout + proc.stderr
    addr = lab.hosts["nossh"].addr
    assert (
        f"Drone2 (root@{addr}:22): unreachable: ssh: connect to host {addr} port 22" in proc.stderr
    )
    assert "nothing was copied or started" in proc.stderr
    assert "Traceback" not in proc.stderr
    assert_nothing_started(lab, "spare", "nossh")


def test_wrong_key(lab, fleet_keys, tmp_path):
    fleet = lab.fleet_file(
        tmp_path / "fleet.toml",
        {"Drone1": "spare", "Drone2": "d2"},
        keys=fleet_keys,
        key=lab.other_key,
    )
    proc = rollout(lab, fleet, tmp_path / "run")
    assert proc.returncode == 3  # the drones refuse the key: could not connect (was 1)
    for drone, host in (("Drone1", "spare"), ("Drone2", "d2")):
        addr = lab.hosts[host].addr
        assert re.search(
            rf"{drone} \(root@{re.escape(addr)}:22\): wrong key: .*Permission denied \(publickey"
            rf".*the drone does not accept {re.escape(str(lab.other_key))}",
            proc.stderr,
        ), proc.stderr
    assert_nothing_started(lab, "spare")


def test_version_mismatch_says_how_to_fix_it(lab, fleet_keys, tmp_path):
    fleet = lab.fleet_file(
        tmp_path / "fleet.toml", {"Drone1": "spare", "Drone2": "oldver"}, keys=fleet_keys
    )
    proc = rollout(lab, fleet, tmp_path / "run")
    assert proc.returncode == 1
    addr = lab.hosts["oldver"].addr
    assert (
        f"Drone2 (root@{addr}:22): version mismatch: drone has eamos 0.0.9, operator "
        f"{__version__}: run `pip install eamos=={__version__}` on the drone"
    ) in proc.stderr
    assert_nothing_started(lab, "spare", "oldver")


def test_disk_full_is_seen_before_copying(lab, fleet_keys, tmp_path):
    fleet = lab.fleet_file(
        tmp_path / "fleet.toml", {"Drone1": "spare", "Drone2": "tiny"}, keys=fleet_keys
    )
    proc = rollout(lab, fleet, tmp_path / "run")
    assert proc.returncode == 1
    addr = lab.hosts["tiny"].addr
    assert re.search(
        rf"Drone2 \(root@{re.escape(addr)}:22\): disk full: \d+ kB free in .*, the roll-out "
        r"needs \d+ kB",
        proc.stderr,
    ), proc.stderr
    assert_nothing_started(lab, "spare")


def test_disk_full_while_copying(lab, fleet_keys, tmp_path):
    # No free-space margin asked for: the copy itself hits the full disk.
    fleet = lab.fleet_file(
        tmp_path / "fleet.toml",
        {"Drone1": "spare", "Drone2": "tiny16"},
        keys=fleet_keys,
        ssh_extra={"Drone2": "min_free_kb = 0"},
    )
    proc = rollout(lab, fleet, tmp_path / "run")
    assert proc.returncode == 1, proc.stdout + proc.stderr
    addr = lab.hosts["tiny16"].addr
    assert f"Drone2 (root@{addr}:22): disk full:" in proc.stderr, proc.stderr
    assert "no drone was started" in proc.stderr
    assert_nothing_started(lab, "spare")


def test_bad_fleet_file_is_refused_with_exit_2(lab, tmp_path):
    fleet = lab.fleet_file(tmp_path / "fleet.toml", {"Drone1": "spare", "Drone2": "d2"})
    proc = rollout(lab, fleet, tmp_path / "run")  # no keys, drones on the network
    assert proc.returncode == 2
    assert "ground.keys: required" in proc.stderr and "eamos keys" in proc.stderr
    assert_nothing_started(lab, "spare")


def test_a_drone_that_never_becomes_ready_stops_the_start(lab, fleet_keys, tmp_path):
    # Drone2 is told to bind an address its host does not have: its node exits at once.
    fleet = lab.fleet_file(
        tmp_path / "fleet.toml",
        {"Drone1": "spare", "Drone2": "d2"},
        keys=fleet_keys,
        ready_timeout_s=20,
        drone_extra={"Drone2": 'bind = "tcp://198.18.0.99:6002"'},
    )
    run_dir = tmp_path / "run"
    proc = rollout(lab, fleet, run_dir, "--speedup", "20")
    assert proc.returncode == 0, proc.stdout + proc.stderr
    start = lab.eamos("start", str(run_dir), "--plain", timeout=120)
    out = start.stdout + start.stderr
    assert start.returncode == 1, out
    assert "not ready: Drone2: eamos-node is not running on root@" in out
    assert "all drones ready: start" not in out
    summary = json.loads((run_dir / "summary.json").read_text())
    assert summary["outcome"].startswith("not ready") and not summary["ok"]
    # No start trigger went out: Drone1 never ran an action.
    log = lab.hosts["spare"].folder / "experiment_b" / "logs" / "Drone1" / "uniform.log"
    assert '"uniform.call"' not in (log.read_text() if log.exists() else "")
    mission_log = log.with_name("mission.log").read_text()
    assert '"mission.start"' not in mission_log
    # It did not wait for the ready timeout to tell.
    assert summary["duration_s"] < 15
