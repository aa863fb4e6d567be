"""``eamos run`` as a user runs it, from tests: a subprocess with a run folder and a summary."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[2]
MISSIONS = REPO / "missions"
#: Generous for a loaded 2-core machine; a healthy run takes seconds.
RUN_TIMEOUT_S = 240

#: Two drones with nothing in common: Drone1 takes off, flies X and lands (it does
#: not disarm); Drone2 does the same on Y and disarms.  Tests make Drone1's
#: FlyByX fail (``reject_actions``) and check that Drone2 is not affected.
INDEPENDENT = """
func PAR_Main() {
    SEQ_One()
    SEQ_Two()
}
func SEQ_One() {
    Drone1.Arm()
    Drone1.Takeoff(2)
    Drone1.FlyByX(2)
    Drone1.Land()
}
func SEQ_Two() {
    Drone2.Arm()
    Drone2.Takeoff(2)
    Drone2.FlyByY(2)
    Drone2.Land()
    Drone2.Disarm()
}
"""


def eamos(*args: str, timeout: float = RUN_TIMEOUT_S) -> subprocess.CompletedProcess[str]:
    """Run ``eamos ARGS...`` (``python -m eamos.cli``) in the repository; its output captured."""
    return subprocess.run(
        [sys.executable, "-m", "eamos.cli", *args],
        capture_output=True,
        text=True,
        timeout=timeout,
        cwd=REPO,
    )


def run_argv(
    mission: Path, tmp_path: Path, *extra: str, speedup: float = 20, timeout_s: float = 150
) -> list[str]:
    """The arguments of ``eamos run MISSION`` with plain output, no SVG, a run folder and a
    summary under ``tmp_path`` (``tmp_path/run``, ``tmp_path/summary.json``)."""
    return [
        "run",
        str(mission),
        "--speedup",
        f"{speedup:g}",
        "--plain",
        "--no-svg",
        "--timeout",
        f"{timeout_s:g}",
        "--run-dir",
        str(tmp_path / "run"),
        "--summary",
        str(tmp_path / "summary.json"),
        *extra,
    ]


def run_mission(
    tmp_path: Path,
    mission: Path,
    *extra: str,
    speedup: float = 20,
    timeout_s: float = 150,
    process_timeout_s: float = RUN_TIMEOUT_S,
) -> tuple[subprocess.CompletedProcess[str], dict[str, Any]]:
    """``eamos run`` to the end: the process and its summary (``{}`` if none was written).

    ``timeout_s`` is the run's own ``--timeout``; ``process_timeout_s`` bounds the process.
    """
    args = run_argv(mission, tmp_path, *extra, speedup=speedup, timeout_s=timeout_s)
    proc = eamos(*args, timeout=process_timeout_s)
    summary = tmp_path / "summary.json"
    return proc, json.loads(summary.read_text()) if summary.exists() else {}
