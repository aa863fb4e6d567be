"""``eamos rollout`` checks the mission before it contacts any drone (``--no-check`` skips it)."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from tests.support.runs import REPO

# Drone2 waits for Drone1's FlyByX, which the simulated model rejects: the check finds the
# failed action and the drone left in the air.
MISSION = """\
var Drone1 Quadcopter
var Drone2 Quadcopter

func SEQ_Main() {
    PAR_Arm()
    PAR_Up()
    Drone1.FlyByX(2)
    Drone2.FlyByX(2)
    PAR_Land()
    PAR_Disarm()
}
func PAR_Arm()    { Drone1.Arm(); Drone2.Arm() }
func PAR_Up()     { Drone1.Takeoff(2); Drone2.Takeoff(3) }
func PAR_Land()   { Drone1.Land(); Drone2.Land() }
func PAR_Disarm() { Drone1.Disarm(); Drone2.Disarm() }
"""

# Hosts on a closed loopback port: a roll-out that got as far as SSH would fail to connect.
FLEET = """\
[ground]
bind = "tcp://127.0.0.1:6000"

[defaults.ssh]
user = "nobody"
port = 1
connect_timeout_s = 2

[defaults.hal]
adapter = "sim"

[drones.Drone1.ssh]
host = "127.0.0.1"

[drones.Drone1.hal]
adapter = "sim"
reject_actions = ["FlyByX"]

[drones.Drone2.ssh]
host = "127.0.0.1"
"""


def rollout(tmp_path: Path, *extra: str) -> subprocess.CompletedProcess[str]:
    mission = tmp_path / "up.go"
    mission.write_text(MISSION)
    fleet = tmp_path / "fleet.toml"
    fleet.write_text(FLEET)
    return subprocess.run(
        [
            *(sys.executable, "-m", "eamos.cli", "rollout", str(mission), str(fleet)),
            *("--run-dir", str(tmp_path / "run"), *extra),
        ],
        capture_output=True,
        text=True,
        timeout=180,
        cwd=REPO,
    )


def test_rollout_refuses_before_contacting_any_drone(tmp_path: Path) -> None:
    proc = rollout(tmp_path)
    assert proc.returncode == 1, proc.stdout + proc.stderr  # not 3: no drone was contacted
    assert f"{tmp_path / 'up.go'}:7:" in proc.stdout  # Drone1.FlyByX(2), the failing action
    assert "--no-check" in proc.stderr and "Traceback" not in proc.stderr
    report = json.loads((tmp_path / "run" / "check.json").read_text())
    assert any(f["severity"] == "error" for f in report["findings"])


def test_no_check_goes_on_to_the_drones(tmp_path: Path) -> None:
    if shutil.which("ssh") is None:
        pytest.skip("the OpenSSH client is not installed (apt-get install openssh-client)")
    proc = rollout(tmp_path, "--no-check")
    # Past the check, the roll-out reaches SSH, which cannot connect to port 1.
    assert proc.returncode == 3, proc.stdout + proc.stderr
    assert "pre-flight check" not in proc.stdout
