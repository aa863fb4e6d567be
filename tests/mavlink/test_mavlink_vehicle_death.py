"""A vehicle dies mid-flight in experiment B (issue 16, items 4 and 7).

Both drones fly over MAVLink against ``eamos-sim-vehicle`` processes started here
(so the test holds them); Drone1's autopilot dies in the air (``--die-after``).
The other drone must end landed and disarmed, and the dead one must be named.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from tests.support.runs import MISSIONS, run_mission

from .mavlink_helpers import connections

pytestmark = [pytest.mark.e2e, pytest.mark.timeout(400)]


def vehicle(autopilot: str, sysid: int, log: Path, *extra: str) -> tuple[subprocess.Popen, str]:
    vehicle_conn, client_conn = connections(autopilot)
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "eamos.cli.sim_vehicle",
            "--autopilot",
            autopilot,
            "--connection",
            vehicle_conn,
            "--sysid",
            str(sysid),
            "--speedup",
            "5",
            "--prearm-delay",
            "1",
            "--log",
            str(log),
            *extra,
        ],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
    )
    return proc, client_conn


def test_a_vehicle_dying_mid_flight_leaves_the_other_landed(tmp_path):
    dead, dead_conn = vehicle("ardupilot", 1, tmp_path / "v1.log", "--die-after", "4")
    alive, alive_conn = vehicle("ardupilot", 2, tmp_path / "v2.log")
    try:
        fleet = tmp_path / "fleet.toml"
        fleet.write_text(
            "[defaults.hal]\n"
            'adapter = "mavlink"\nspeedup = 5\nheartbeat_timeout_s = 2.5\n'
            f'[drones.Drone1.hal]\nconnection = "{dead_conn}"\n'
            f'[drones.Drone2.hal]\nconnection = "{alive_conn}"\n'
        )
        proc, summary = run_mission(
            tmp_path,
            MISSIONS / "experiment_b.go",
            "--fleet",
            str(fleet),
            speedup=5,
            timeout_s=200,
            process_timeout_s=300,
        )
        assert dead.wait(60) == 1  # the simulated crash
        assert proc.returncode == 1, proc.stdout + proc.stderr
        events = [json.loads(x) for x in (tmp_path / "v2.log").read_text().splitlines()]
        armed = [e for e in events if e["event"] == "vehicle.armed"]
        assert armed and armed[-1]["armed"] is False, armed  # Drone2 ends disarmed...
        positions = [e for e in events if e["event"] == "vehicle.position"]
        assert positions[-1]["z_m"] == 0.0  # ...on the ground
        run = Path(summary["run_dir"])
        d1 = (run / "logs" / "Drone1" / "adapter.log").read_text()
        assert "heartbeat lost" in d1
        assert '"event": "adapter.stranded"' in d1  # the dead one is named, loudly
        d2 = (run / "logs" / "Drone2" / "adapter.log").read_text()
        # Landed by its end policy (stranded in the air: issue 28), not left to land-on-close.
        assert '"event": "adapter.abort.done"' in d2 or '"Land"' in d2
        assert '"event": "adapter.close_land' not in d2
    finally:
        for proc_ in (dead, alive):
            if proc_.poll() is None:
                proc_.terminate()
                proc_.wait(15)
