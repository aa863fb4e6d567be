"""``eamos run --monitor`` from tests: the process, and the monitor's address once printed."""

from __future__ import annotations

import queue
import re
import subprocess
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

from eamos.ground.summary import RunSummary
from tests.support.runs import REPO, run_argv

URL = re.compile(r"monitor: (http://127\.0\.0\.1:(\d+)/\?token=(\S+))")


@dataclass
class LiveRun:
    """A running ``eamos run --monitor``; its output lines are collected as they come."""

    proc: subprocess.Popen[str]
    lines: list[str] = field(default_factory=list)
    _queue: queue.Queue[str | None] = field(default_factory=queue.Queue)

    def _pump(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            self._queue.put(line.rstrip("\n"))
        self._queue.put(None)

    def wait_for(self, pattern: re.Pattern[str], timeout_s: float = 120) -> re.Match[str]:
        """The first output line matching ``pattern`` (AssertionError after ``timeout_s``)."""
        for line in self.lines:
            if found := pattern.search(line):
                return found
        deadline = time.monotonic() + timeout_s
        while (remaining := deadline - time.monotonic()) > 0:
            try:
                got = self._queue.get(timeout=remaining)
            except queue.Empty:
                break
            if got is None:
                break
            self.lines.append(got)
            if found := pattern.search(got):
                return found
        raise AssertionError(f"no line matching {pattern.pattern!r} in:\n" + "\n".join(self.lines))

    def finish(self, timeout_s: float = 240) -> int:
        """Wait for the process; every output line collected."""
        code = self.proc.wait(timeout=timeout_s)
        while (line := self._queue.get(timeout=30)) is not None:
            self.lines.append(line)
        return code


def start_live_run(
    tmp_path: Path, mission: str | Path, *extra: str, speedup: float = 20, timeout_s: float = 150
) -> LiveRun:
    """Start ``eamos run missions/MISSION.go --monitor`` (or a mission file) under ``tmp_path``."""
    argv = run_argv(
        mission if isinstance(mission, Path) else REPO / "missions" / f"{mission}.go",
        tmp_path,
        "--monitor",
        *extra,
        speedup=speedup,
        timeout_s=timeout_s,
    )
    proc = subprocess.Popen(
        [sys.executable, "-m", "eamos.cli", *argv],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        cwd=REPO,
    )
    run = LiveRun(proc)
    threading.Thread(target=run._pump, daemon=True).start()
    return run


def ended_ok(run: LiveRun, code: int, tmp_path: Path) -> RunSummary:
    """The summary of a run that exited with ``code``: it must have exited 0 and be ok."""
    assert code == 0, "\n".join(run.lines)
    summary = RunSummary.read(tmp_path / "summary.json")
    assert summary.ok
    return summary
