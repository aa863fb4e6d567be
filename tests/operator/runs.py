"""What the operator tests share: a live ``eamos run``, the operator's command, the logs."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from eamos.logs import read_log
from tests.faults.runs import LiveRun
from tests.support.runs import eamos

HERE = Path(__file__).resolve().parent
#: A few processes, not one per drone: the tests need no drone alone.
GROUPED = ("--drones-per-process", "4")


def start(
    tmp_path: Path,
    mission: Path,
    speedup: float,
    timeout_s: float = 300,
    extra: tuple[str, ...] = (),
) -> LiveRun:
    """``eamos run MISSION`` with plain output, read as it comes (``extra``: more options)."""
    return LiveRun.start(tmp_path, mission, *GROUPED, *extra, speedup=speedup, timeout_s=timeout_s)


def operator(*args: str) -> str:
    """``eamos ARGS`` (pause, resume, drone): its output; the test fails on a non-zero exit."""
    proc = eamos(*args, timeout=60)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    return proc.stdout


def log_lines(run_dir: Path, drone: str, name: str, event: str) -> list[dict[str, Any]]:
    """The lines of ``logs/<drone>/<name>.log`` with ``event``."""
    return [e for e in read_log(run_dir / "logs" / drone / f"{name}.log") if e["event"] == event]


def positions(run_dir: Path, drone: str) -> list[tuple[float, float, float, float]]:
    """``(ts, x, y, z)`` of every ``adapter.position`` line of ``drone``."""
    return [
        (e["ts"], e["x_m"], e["y_m"], e["z_m"])
        for e in log_lines(run_dir, drone, "adapter", "adapter.position")
    ]


def distance(a: tuple[float, ...], b: tuple[float, ...]) -> float:
    return math.dist(a[1:], b[1:])


def resume_to_the_end(run: LiveRun, tmp_path: Path) -> dict[str, Any]:
    """``eamos resume`` a paused run, wait for its end: its summary (the run must end ok)."""
    operator("resume", str(run.run_dir))
    assert run.finish(240) == 0, run.text()
    summary: dict[str, Any] = json.loads((tmp_path / "summary.json").read_text())
    assert summary["ok"], summary
    return summary
