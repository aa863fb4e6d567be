"""A fleet of ``eamos-node`` processes from configs alone, ground station included.

On loopback, so no root is needed (``tests/netfaults`` runs the same on separate
network namespaces with faults).  Checks the keys and configs path end to end:
CURVE between processes, the ground station mode of ``eamos-node`` and its
``summary.json``, and that a node holding another fleet's keys is refused.
"""

from __future__ import annotations

import os
import subprocess
from pathlib import Path

import pytest

from eamos.compiler import compile_file
from eamos.net.keys import create_fleet_keys
from eamos.program.uniform import GROUND_STATION
from tests.support.netlab import node_argv, write_fleet

from .link_helpers import free_port

pytestmark = [pytest.mark.timeout(300), pytest.mark.e2e]
REPO = Path(__file__).resolve().parents[2]


def run_fleet(tmp: Path, secure: bool) -> tuple[dict, dict[str, str]]:
    compiled = compile_file(REPO / "missions" / "experiment_b.go")
    names = list(compiled.programs)
    bind = {n: f"tcp://127.0.0.1:{free_port()}" for n in names}
    hal = {n: {"adapter": "sim", "speedup": 20} for n in names if n != GROUND_STATION}
    hal[GROUND_STATION] = {"adapter": "ground", "speedup": 20}
    files = write_fleet(compiled.programs, tmp, bind, hal=hal, secure=secure)
    procs = {
        n: subprocess.Popen(
            node_argv(files.configs[n]),
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
            cwd=REPO,
            env={**os.environ, "PYTHONUNBUFFERED": "1"},
        )
        for n in names
    }
    outputs = {}
    try:
        for name, proc in procs.items():
            outputs[name], _ = proc.communicate(timeout=240)
    finally:
        for proc in procs.values():
            if proc.poll() is None:
                proc.kill()
    summary = files.summary()
    assert summary is not None, outputs[GROUND_STATION]
    return summary, outputs


@pytest.mark.parametrize("secure", [True, False], ids=["curve", "plain"])
def test_fleet_from_configs_on_loopback(tmp_path: Path, secure: bool) -> None:
    summary, outputs = run_fleet(tmp_path, secure)
    assert summary["ok"], (summary["outcome"], outputs)
    for name in ("Drone1", "Drone2"):
        report = summary["drones"][name]
        assert report["triggers_sent"] == report["external_out"], name
        assert report["triggers_received"] == report["external_in"], name
        assert report["net"]["secure"] is secure
        log = (tmp_path / "logs" / name / "mission.log").read_text()
        assert "mission.report.unacknowledged" not in log  # the ground station acked it
    assert summary["ground_station"]["net"]["secure"] is secure
    assert "all drones ready: start" in outputs[GROUND_STATION]
    assert set(summary["links"].values()) <= {"up", "left"}  # nobody was lost


def test_a_node_with_another_fleets_keys_is_refused(tmp_path: Path) -> None:
    compiled = compile_file(REPO / "missions" / "experiment_b.go")
    names = list(compiled.programs)
    bind = {n: f"tcp://127.0.0.1:{free_port()}" for n in names}
    files = write_fleet(compiled.programs, tmp_path, bind)
    other = create_fleet_keys(tmp_path / "other", ["Drone1"])
    config = files.configs["Drone1"]
    config.write_text(config.read_text().replace('"../keys/Drone1"', f'"{other / "Drone1"}"'))
    proc = subprocess.run(node_argv(config), capture_output=True, text=True, timeout=60, cwd=REPO)
    assert proc.returncode == 2
    assert "net.keys" in proc.stderr and "no public key for peer" in proc.stderr
    assert "Traceback" not in proc.stderr


def test_a_node_says_whom_it_waits_for_and_exits_3(tmp_path: Path) -> None:
    """Alone (its peers never start), Drone1 says every 5 s whom it waits for, then gives up."""
    compiled = compile_file(REPO / "missions" / "experiment_b.go")
    names = list(compiled.programs)
    bind = {n: f"tcp://127.0.0.1:{free_port()}" for n in names}
    files = write_fleet(compiled.programs, tmp_path, bind, ready_timeout_s=12.0)
    config = files.configs["Drone1"]
    proc = subprocess.run(node_argv(config), capture_output=True, text=True, timeout=120, cwd=REPO)
    assert proc.returncode == 3, proc.stderr
    notes = [line for line in proc.stderr.splitlines() if "waiting for" in line]
    assert notes, proc.stderr
    assert all("Drone2" in n and "GCS" in n and "to listen" in n for n in notes), notes
    assert "peers never subscribed: " in proc.stderr and "Traceback" not in proc.stderr
