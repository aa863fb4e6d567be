"""Issue 28, items 5 and 14: every node exit is counted at once, and says where the drone was.

* SIGTERM to one drone's node: it says so at once (to the ground station and
  in its ``node.out``, naming the signal), lands, reports and exits 1; the
  ground station counts that end at once as a failure (not at the mission
  timeout), and the drones waiting for it are released and land.
* ``kill -9`` of a drone's node: no report can come; the terminal line and the
  summary say where the ground station last saw the drone (in the air, armed,
  at x, y, z), from its last telemetry.
"""

from __future__ import annotations

import os
import re
import signal
import time
from pathlib import Path
from typing import Any

import pytest

from tests.faults.runs import LiveRun, node_pid, read_json, wait_gone
from tests.support.runs import MISSIONS, RUN_TIMEOUT_S

pytestmark = pytest.mark.e2e

#: From the signal to the drone's own line about it (at once, before it lands).
STOPPED_WITHIN_S = 15
#: From the signal to the ground station's line about it: the node lands (at speedup
#: 2, from at most 5 m), reports and exits; generous for a loaded 2-core machine.
TOLD_WITHIN_S = 45
#: From the signal to the end of `eamos run` (the drones waiting for the stopped one
#: are released at once and land): far below the run's 300 s timeout.
ENDED_WITHIN_S = 90


def landed_disarmed(report: dict[str, Any]) -> bool:
    final = report["final"]
    return abs(final["z"]) < 0.15 and not final["armed"] and final.get("landed") is not False


def test_sigterm_to_one_node_is_counted_at_once_and_its_dependents_land(tmp_path: Path) -> None:
    # Experiment C: every move of Drone1 and Drone2 waits for Drone3's move before it.
    run = LiveRun.start(tmp_path, MISSIONS / "experiment_c.go", speedup=2, timeout_s=300)
    pid = 0
    try:
        run.wait_for("Drone3 running   FlyByX(5)", within_s=120)
        pid = node_pid(run.run_dir, "Drone3")
        signalled = time.monotonic()
        os.kill(pid, signal.SIGTERM)
        stopped = run.wait_for("Drone3 stopped   stopped by SIGTERM", within_s=STOPPED_WITHIN_S)
        stopped_s = time.monotonic() - signalled
        line = run.wait_for(
            "Drone3 FAILED: its node stopped before the mission ended", TOLD_WITHIN_S
        )
        told_s = time.monotonic() - signalled
        run.finish(ENDED_WITHIN_S)
        ended_s = time.monotonic() - signalled
    finally:
        run.kill()
        if pid:
            wait_gone(pid, 30)
    text = run.text()
    assert stopped_s < STOPPED_WITHIN_S and told_s < TOLD_WITHIN_S, text
    assert ended_s < ENDED_WITHIN_S, text
    assert "the mission is aborted on this drone" in stopped, stopped
    assert "(stopped by signal)" in line, line
    assert run.returncode == 1, text
    summary = read_json(tmp_path / "summary.json")
    assert summary["outcome"].startswith("failed: Drone3: its node stopped before"), summary
    d3 = summary["drones"]["Drone3"]
    assert d3["aborted"] and d3["abort_reason"] == "stopped by signal", d3
    assert d3["exit_code"] == 1
    for name, report in summary["drones"].items():
        assert landed_disarmed(report), (name, report["final"])
    node_out = (run.run_dir / "logs" / "Drone3" / "node.out").read_text()
    assert "eamos-node Drone3: stopped by SIGTERM" in node_out, node_out


def test_a_killed_node_is_reported_where_it_was_last_seen(tmp_path: Path) -> None:
    run = LiveRun.start(tmp_path, MISSIONS / "experiment_b.go", speedup=2, timeout_s=300)
    try:
        run.wait_for("Drone1 ok        FlyByX(1)", within_s=120)
        os.kill(node_pid(run.run_dir, "Drone1"), signal.SIGKILL)
        killed = time.monotonic()
        line = run.wait_for("Drone1 FAILED: process exited with code -9", within_s=15)
        told_s = time.monotonic() - killed
        run.finish(RUN_TIMEOUT_S)
    finally:
        run.kill()
    text = run.text()
    assert told_s < 15
    # Its last telemetry at the ground station: on the first side of the square, or, when
    # the ground station's line trailed the node on a loaded machine, on the second (the
    # kill follows the line, and Drone1 goes on to FlyByY(1) once Drone2 ends its side).
    seen_at = re.search(
        r"last seen in the air, armed, at \((.+), (.+), (.+)\) m from its home", line
    )
    assert seen_at, line
    x, y, z = (float(v) for v in seen_at.groups())
    first_side = 0.0 <= x <= 1.2 and abs(y) < 0.2
    second_side = abs(x - 1.0) < 0.2 and -0.2 <= y <= 1.2
    assert (first_side or second_side) and z == pytest.approx(1.5, abs=0.3), line
    summary = read_json(tmp_path / "summary.json")
    d1 = summary["drones"]["Drone1"]
    assert d1["error"] == "no report" and d1["exit_code"] == -9
    seen = d1["last_seen"]
    assert seen["armed"] is True and seen["landed"] is False, seen
    # The summary says the point of the line (or a sample that was in flight at the kill).
    assert (seen["x"], seen["y"], seen["z"]) == pytest.approx((x, y, z), abs=0.3), (seen, line)
    assert isinstance(seen["t"], float) and seen["t"] <= time.time()
    # The closing lines say it too, not only "no report".
    closing = [ln for ln in text.splitlines() if ln.startswith("  Drone1:")]
    assert closing and "no report (exit code -9); last seen in the air, armed, at (" in closing[0]
    assert landed_disarmed(summary["drones"]["Drone2"]), summary["drones"]["Drone2"]
