"""A live ``eamos run`` for fault tests: its output read as it comes, its drones found by pid.

Fault tests kill, stop or signal one drone's process and read its own
``logs/<Drone>/node.out``, so :class:`LiveRun` asks for one process per drone
(``--drones-per-process 1``) unless the test says otherwise; ``eamos run``
groups drones about one process per core by default.
"""

from __future__ import annotations

import json
import subprocess
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from eamos.ops.start import wait_pid_exit
from tests.support.runs import REPO, run_argv

#: ``eamos run`` options for a process of its own per drone (one can be killed alone).
ONE_PER_PROCESS = ("--drones-per-process", "1")


@dataclass
class LiveRun:
    """``eamos run`` started with plain output, read line by line on a thread."""

    proc: subprocess.Popen[str]
    run_dir: Path
    lines: list[str] = field(default_factory=list)
    cond: threading.Condition = field(default_factory=threading.Condition)

    @classmethod
    def start(
        cls,
        tmp_path: Path,
        mission: Path,
        *extra: str,
        speedup: float,
        timeout_s: float,
        run_dir: Path | None = None,
    ) -> LiveRun:
        """Start ``eamos run MISSION`` (run folder ``run_dir`` or ``tmp_path/run``).

        One process per drone unless ``extra`` gives ``--drones-per-process``.
        """
        if "--drones-per-process" not in extra:
            extra = (*extra, *ONE_PER_PROCESS)
        args = run_argv(mission, tmp_path, *extra, speedup=speedup, timeout_s=timeout_s)
        if run_dir is not None:
            args[args.index("--run-dir") + 1] = str(run_dir)
        proc = subprocess.Popen(
            [sys.executable, "-m", "eamos.cli", *args],
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
            cwd=REPO,
        )
        run = cls(proc, run_dir or tmp_path / "run")
        threading.Thread(target=run._read, daemon=True).start()
        return run

    def _read(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            with self.cond:
                self.lines.append(line.rstrip("\n"))
                self.cond.notify_all()
        with self.cond:
            self.lines.append("")  # end of output
            self.cond.notify_all()

    def wait_for(self, text: str, within_s: float = 180, count: int = 1) -> str:
        """The ``count``-th line containing ``text`` (AssertionError after ``within_s``)."""
        deadline = time.monotonic() + within_s
        with self.cond:
            while True:
                found = [line for line in self.lines if text in line]
                if len(found) >= count:
                    return found[count - 1]
                remaining = deadline - time.monotonic()
                assert remaining > 0, f"no line with {text!r} in {within_s} s:\n" + self.text()
                self.cond.wait(remaining)

    def finish(self, timeout_s: float) -> int:
        """Wait until the run ends; its exit code."""
        return self.proc.wait(timeout_s)

    def kill(self) -> None:
        """kill -9 the run (not its drones) if it still runs."""
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait(30)

    @property
    def returncode(self) -> int | None:
        return self.proc.returncode

    def text(self) -> str:
        with self.cond:
            return "\n".join(self.lines)


def node_pid(run_dir: Path, drone: str) -> int:
    """The pid of ``drone``'s ``eamos-node`` in this run."""
    found = subprocess.run(
        ["pgrep", "-f", str(run_dir / "configs" / f"{drone}.toml")],
        capture_output=True,
        text=True,
    )
    return int(found.stdout.split()[0])


def wait_gone(pid: int, timeout_s: float) -> bool:
    """Wait until process ``pid`` ended (not necessarily our child)."""
    return wait_pid_exit(pid, timeout_s)


def read_json(path: Path) -> Any:
    """A JSON file's content."""
    return json.loads(path.read_text())
