"""``eamos start RUN_DIR --monitor`` on a real fleet: sshd hosts in network namespaces.

The lab of tests/fleetops (:mod:`tests.fleetops.fleet_lab`): an operator
namespace and two drone hosts, each with its own OpenSSH sshd; ``eamos
rollout`` deploys experiment B over SSH and starts eamos-node on each host,
then ``eamos start --monitor`` is the ground station with the page.  The
page is watched over its websocket from inside the operator's namespace
(where the monitor's 127.0.0.1 is); its final node states, positions and
link counts must be the summary's.
"""

from __future__ import annotations

import json
import os
import queue
import re
import subprocess
import sys
import threading
from collections.abc import Iterator
from pathlib import Path

import pytest

from eamos.ground.summary import RunSummary
from eamos.report import load_run, table7
from tests.fleetops.fleet_lab import REPO, Lab, missing_tools
from tests.monitor.live import URL
from tests.monitor.test_server import expected_nodes

pytestmark = pytest.mark.e2e
MISSION = REPO / "missions" / "experiment_b.go"


@pytest.fixture(scope="module")
def lab(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Lab]:
    why = missing_tools()
    if why:
        pytest.skip(f"fleet lab: {why}")
    # A tag of its own: the fleetops lab may exist at the same time (namespaces are global).
    lab = Lab(tmp_path_factory.mktemp("lab"), f"emo{os.getpid() % 100000}")
    try:
        lab.add_host("d1", 1)
        lab.add_host("d2", 2)
        yield lab
    finally:
        lab.close()


def lines_of(proc: subprocess.Popen[str]) -> queue.Queue[str | None]:
    out: queue.Queue[str | None] = queue.Queue()

    def pump() -> None:
        assert proc.stdout is not None
        for line in proc.stdout:
            out.put(line.rstrip("\n"))
        out.put(None)

    threading.Thread(target=pump, daemon=True).start()
    return out


def test_start_with_the_monitor_on_a_rolled_out_fleet(lab: Lab, tmp_path: Path):
    keys = tmp_path / "keys"
    made = lab.eamos("keys", str(keys), "--fleet", "GCS", "Drone1", "Drone2")
    assert made.returncode == 0, made.stderr
    fleet = lab.fleet_file(
        tmp_path / "fleet.toml",
        {"Drone1": "d1", "Drone2": "d2"},
        keys=keys,
        drone_extra={"Drone2": "home_m = [3.0, 7.0]"},  # the map places it from the fleet file
    )
    run_dir = tmp_path / "run"
    rolled = lab.eamos(
        "rollout", str(MISSION), str(fleet), "--run-dir", str(run_dir), "--speedup", "5"
    )
    assert rolled.returncode == 0, rolled.stdout + rolled.stderr
    # The watcher starts first and waits for the port on stdin: started once the port is
    # known, its interpreter came up on a loaded machine after this short run had ended.
    watcher = subprocess.Popen(
        ["ip", "netns", "exec", lab.operator_ns, sys.executable, "-m",
         "tests.monitor.watch_page", "-"],
        stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        cwd=REPO,
    )  # fmt: skip
    start = lab.popen_eamos("start", str(run_dir), "--monitor", "--plain")
    lines = lines_of(start)
    seen: list[str] = []
    try:
        port = None
        while port is None:
            line = lines.get(timeout=120)
            assert line is not None, "\n".join(seen) + (start.stderr.read() if start.stderr else "")
            seen.append(line)
            if found := URL.search(line):
                port = found.group(2)
        watched, why = watcher.communicate(f"{port}\n", timeout=240)
        assert watcher.returncode == 0, why
        code = start.wait(timeout=240)
        while (line := lines.get(timeout=30)) is not None:
            seen.append(line)
        assert code == 0, "\n".join(seen) + (start.stderr.read() if start.stderr else "")
    finally:
        for proc in (start, watcher):
            if proc.poll() is None:
                proc.kill()
                proc.communicate()
    got = json.loads(watched)
    page = got["page"]
    summary = RunSummary.read(run_dir / "summary.json")
    assert summary.ok and page["mission"]["state"] == summary.word == "finished"
    # Every node's final state is the summary's (the drones' reports over the real link).
    expected = expected_nodes(run_dir, summary)
    assert set(expected.values()) == {"done"}
    assert {k: v["state"] for k, v in page["nodes"].items()} == expected
    # The drones flew on their hosts: the page ends where their reports say they are.
    homes = {p["name"]: p["home"] for p in page["setup"]["participants"]}
    assert homes["Drone1"] == [0.0, 0.0] and homes["Drone2"] == [3.0, 7.0]
    for name, result in summary.drones.items():
        final = result.report.final if result.report is not None else None
        assert final is not None
        assert (result.host or "").startswith("root@198.18.0."), result.host  # over SSH
        shown = page["drones"][name]
        assert shown["x"] == pytest.approx(homes[name][0] + final.x, abs=1e-6)
        assert shown["y"] == pytest.approx(homes[name][1] + final.y, abs=1e-6)
        assert shown["trail"], f"{name}: no live telemetry reached the page"
    # The live link counts are the reports' Table 7, each external arc once.
    assert got["link_patches_running"] > 0
    table = {row["drone"]: row for row in table7(load_run(run_dir)).records()}
    for name in summary.drones:
        sent = sum(v["sent"] for v in page["links"].values() if v["src"] == name)
        received = sum(v["received"] for v in page["links"].values() if v["dst"] == name)
        assert f"{sent} / {received}" == table[name]["triggers sent / received"]
    assert all(v["sent"] == v["received"] == v["arcs"] for v in page["links"].values())
    assert re.search(r"monitor: http://127\.0\.0\.1:\d+/\?token=", "\n".join(seen))
