"""Issue 28, item 1 (issue 27's "a vehicle dies"): the surviving drone applies its end policy.

Experiment B over MAVLink against two ``eamos-sim-vehicle`` processes: Drone1's
autopilot dies in the air (``--die-after``), its action fails ("heartbeat
lost").  Drone2, blocked at its next corner, has resolved in the air, and the
ground station's Complete follows at once: Drone2 must say it is stranded and
apply its end policy then (the line on the terminal and in its ``node.out``),
land and disarm through its program's end, and send its report after that --
never be left to the adapter's land-on-close, silently, with a report saying
it hovers armed.  Drone1's own node, stranded too, stops waiting for a landing
its silent vehicle cannot make (``VEHICLE_SILENT_S``), and says so.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from tests.faults.runs import LiveRun, read_json
from tests.mavlink.mavlink_helpers import connections
from tests.support.runs import MISSIONS, RUN_TIMEOUT_S

pytestmark = [pytest.mark.e2e, pytest.mark.timeout(500)]

#: From Drone1's failure to Drone2's stranded line (it checks when it resolves, or at
#: Complete); generous for a loaded 2-core machine.
STRANDED_WITHIN_S = 30


def vehicle(sysid: int, log: Path, *extra: str) -> tuple[subprocess.Popen[bytes], str]:
    vehicle_conn, client_conn = connections("ardupilot")
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "eamos.cli.sim_vehicle",
            "--autopilot",
            "ardupilot",
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
        stderr=subprocess.DEVNULL,
    )
    return proc, client_conn


def test_the_survivor_of_a_dead_vehicle_says_stranded_and_lands_before_its_report(
    tmp_path: Path,
) -> None:
    dead, dead_conn = vehicle(1, tmp_path / "v1.log", "--die-after", "4")
    alive, alive_conn = vehicle(2, tmp_path / "v2.log")
    fleet = tmp_path / "fleet.toml"
    fleet.write_text(
        "[defaults.hal]\n"
        'adapter = "mavlink"\nspeedup = 5\nheartbeat_timeout_s = 2.5\n'
        f'[drones.Drone1.hal]\nconnection = "{dead_conn}"\n'
        f'[drones.Drone2.hal]\nconnection = "{alive_conn}"\n'
    )
    run = LiveRun.start(
        tmp_path,
        MISSIONS / "experiment_b.go",
        "--fleet",
        str(fleet),
        "--no-check",
        speedup=5,
        timeout_s=200,
    )
    try:
        run.wait_for("Drone1 failed", within_s=200)
        line = run.wait_for("Drone2 stranded  end policy: land", within_s=STRANDED_WITHIN_S)
        run.finish(RUN_TIMEOUT_S)
    finally:
        run.kill()
        for proc in (dead, alive):
            if proc.poll() is None:
                proc.terminate()
                proc.wait(15)
    text = run.text()
    assert "its part ended with" in line and "the vehicle in the air" in line, text
    assert run.returncode == 1, text
    d2 = read_json(tmp_path / "summary.json")["drones"]["Drone2"]
    assert d2["aborted"] and d2["abort_reason"].startswith("stranded: its part ended"), d2
    final = d2["final"]
    assert abs(final["z"]) < 0.3 and not final["armed"], final  # the report followed the landing
    logs = run.run_dir / "logs" / "Drone2"
    assert "stranded: its part ended" in (logs / "node.out").read_text()
    # Landed by its end policy, not by the adapter closing.
    assert '"event": "adapter.close_land' not in (logs / "adapter.log").read_text()
    # The dead vehicle's drone stops waiting for a landing that cannot come, and says so.
    dead_logs = run.run_dir / "logs" / "Drone1"
    assert "its vehicle has sent nothing for 10 s" in (dead_logs / "node.out").read_text()
    assert '"event": "adapter.stranded"' in (dead_logs / "adapter.log").read_text()
