"""A Try catches a lost peer (issue 13): a real run, one drone killed inside the Try's Body.

missions/try_lost_peer.go: Drone2 hops, then waits for Drone1's 20 m leg.  Drone1's
process is killed during that leg.  Without a Try, Drone2 would be stranded after
``peer_wait_limit_s`` and land where it is (tests/faults/test_fault_runs.py); here the wait
fails inside the Try's Body, the Try catches it, and Drone2 flies OnFailure (back above
home) before landing: its FlyToXYZ runs, and it is not aborted.
"""

from __future__ import annotations

import os
import signal
from pathlib import Path

import pytest

from eamos.actors.stranded import DEFAULT_PEER_WAIT_LIMIT_S
from eamos.logs import read_log
from tests.faults.runs import LiveRun, node_pid, read_json
from tests.support.runs import MISSIONS

pytestmark = pytest.mark.e2e

WITHIN_S = 3 + DEFAULT_PEER_WAIT_LIMIT_S + 120


def test_a_try_catches_a_peer_lost_inside_its_body(tmp_path: Path) -> None:
    run = LiveRun.start(
        tmp_path,
        MISSIONS / "try_lost_peer.go",
        "--drones-per-process",
        "1",
        speedup=2,
        timeout_s=600,
    )
    try:
        run.wait_for("Drone1 running   FlyByX")
        os.kill(node_pid(run.run_dir, "Drone1"), signal.SIGKILL)
        run.finish(WITHIN_S)
    finally:
        run.kill()
    summary = read_json(tmp_path / "summary.json")
    d2 = summary["drones"]["Drone2"]
    results = [(a["action"], a["result"]) for a in d2["actions"]]
    assert ("FlyToXYZ", "ok") in results, (results, run.text())  # OnFailure ran
    assert ("FlyByY", "ok") not in results  # the rest of Body never ran
    assert not d2.get("aborted"), d2  # caught, not stranded
    assert d2["final"]["z"] == pytest.approx(0.0, abs=0.15) and not d2["final"]["armed"]
    assert abs(d2["final"]["x"]) < 0.5 and abs(d2["final"]["y"]) < 0.5  # back home, then down
    events = [e["event"] for e in read_log(run.run_dir / "logs" / "Drone2" / "mission.log")]
    assert "mission.try.peer_lost" in events
