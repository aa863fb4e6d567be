"""Broken plugins in real processes: ``eamos check`` ends with a located finding, ``eamos run``
lands and disarms, a node answers SIGTERM while a plugin hangs.

The lab package's broken plugins (``tests/plugins/lab_package/eamos_labspray/faults.py``)
are installed into a temporary folder as pip would (``tests/plugins/lab.py``): ``Quit``
calls ``sys.exit(3)``, ``CtrlC`` raises ``KeyboardInterrupt``, ``Stall`` sleeps forever,
``Spin`` spins forever.
"""

from __future__ import annotations

import contextlib
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest

from tests.faults.runs import LiveRun, node_pid, wait_gone

from .lab import FAULTY_ENTRY_POINTS, env_with, install_lab

pytestmark = pytest.mark.timeout(600)

#: Generous for a loaded 2-core machine.
PROCESS_TIMEOUT_S = 300

JAM = """\
package Jam

type Jammer interface {
	Quadcopter
	ACTION()
}

var D1 Jammer

func SEQ_Main() {
	D1.Arm()
	D1.Takeoff(2)
	D1.ACTION()
	D1.Land()
	D1.Disarm()
}
"""

#: The same, the plugin action in a Try: the mission itself lands and disarms after it.
JAM_IN_A_TRY = """\
package Jam

type Jammer interface {
	Quadcopter
	ACTION()
}

var D1 Jammer

func SEQ_Main() {
	D1.Arm()
	D1.Takeoff(2)
	Try(SEQ_Work, SEQ_Recover)
	D1.Land()
	D1.Disarm()
}

func SEQ_Work() {
	D1.ACTION()
}

func SEQ_Recover() {
	D1.PauseFor(1)
}
"""


@pytest.fixture
def lab(tmp_path: Path) -> dict[str, str]:
    """The environment of a process that sees the lab's broken plugins installed."""
    return env_with(install_lab(tmp_path / "site", FAULTY_ENTRY_POINTS))


def mission(tmp_path: Path, source: str, action: str) -> Path:
    path = tmp_path / f"{action.lower()}.go"
    path.write_text(source.replace("ACTION", action), encoding="utf-8")
    return path


def fleet(tmp_path: Path, deadline_s: float) -> Path:
    path = tmp_path / "fleet.toml"
    path.write_text(f"[defaults.hal]\nplugin_deadline_s = {deadline_s:g}\n", encoding="utf-8")
    return path


def eamos(env: dict[str, str], cwd: Path, *args: str | Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "eamos.cli", *map(str, args)],
        cwd=cwd,
        env=env,
        capture_output=True,
        text=True,
        timeout=PROCESS_TIMEOUT_S,
    )


@pytest.mark.parametrize(
    ("action", "raised"), [("Quit", "SystemExit(3)"), ("CtrlC", "KeyboardInterrupt()")]
)
def test_eamos_check_reports_a_plugin_that_exits_as_a_failed_action_at_its_call(
    tmp_path: Path, lab: dict[str, str], action: str, raised: str
) -> None:
    path = mission(tmp_path, JAM, action)
    done = eamos(lab, tmp_path, "check", path)
    out = done.stdout + done.stderr
    # Not the plugin's exit code 3 (nor Ctrl-C's 130): the check's own "mission failed".
    assert done.returncode == 1, out
    assert (
        f"{path}:13:2: error: D1.{action}() fails at 4.42 s: plugin action {action!r} "
        f"failed in its sim implementation: {raised}"
    ) in done.stdout, out


@pytest.mark.parametrize("action", ["Stall", "Spin"])
def test_eamos_check_ends_when_a_plugin_hangs(
    tmp_path: Path, lab: dict[str, str], action: str
) -> None:
    path = mission(tmp_path, JAM_IN_A_TRY, action)
    started = time.monotonic()
    done = eamos(lab, tmp_path, "check", path, "--fleet", fleet(tmp_path, 1), "--json")
    took_s = time.monotonic() - started
    assert done.returncode == 0, done.stdout + done.stderr  # the Try catches it
    report = json.loads(done.stdout)
    # Both runs (Body fails / Body completes) meet the plugin: it hangs once, for its
    # deadline; the second call fails at once (its thread may still run).
    assert [r["branch"] for r in report["runs"]] == ["as simulated", report["runs"][1]["branch"]]
    assert took_s < 60, took_s  # one deadline (1 s) plus start-up, not forever


@pytest.mark.parametrize("action", ["Quit", "Spin"])
def test_eamos_run_lands_and_disarms_after_a_plugin_that_exits_or_hangs(
    tmp_path: Path, lab: dict[str, str], action: str
) -> None:
    path = mission(tmp_path, JAM_IN_A_TRY, action)
    run = tmp_path / "run"
    # A deadline of 2 s for the plugin that spins (Quit fails at once: no fleet file).
    fleet_args = () if action == "Quit" else ("--fleet", fleet(tmp_path, 2))
    done = eamos(
        lab,
        tmp_path,
        "run",
        path,
        *fleet_args,
        "--timeout",
        "120",
        "--no-check",
        "--speedup",
        "10",
        "--plain",
        "--no-svg",
        "--run-dir",
        run,
    )
    out = done.stdout + done.stderr
    assert done.returncode == 0, out
    summary = json.loads((run / "summary.json").read_text(encoding="utf-8"))
    d1 = summary["drones"]["D1"]
    results = [(a["action"], a["result"]) for a in d1["actions"]]
    assert results == [
        ("Arm", "ok"),
        ("Takeoff", "ok"),
        (action, "caught"),
        ("PauseFor", "ok"),
        ("Land", "ok"),
        ("Disarm", "ok"),
    ], out
    reason = d1["actions"][2]["reason"]
    if action == "Quit":
        assert "failed in its sim implementation: SystemExit(3)" in reason
    else:
        assert f"plugin action {action!r} did not finish within 2 s" in reason
    assert d1["final"]["z"] == pytest.approx(0.0, abs=0.15) and not d1["final"]["armed"]


def test_a_node_answers_sigterm_while_a_plugin_hangs_and_lands(
    tmp_path: Path, lab: dict[str, str], monkeypatch: pytest.MonkeyPatch
) -> None:
    path = mission(tmp_path, JAM, "Stall")
    # A deadline far beyond the test: the plugin is still running when SIGTERM comes.
    far = fleet(tmp_path, 600)
    monkeypatch.setenv("PYTHONPATH", lab["PYTHONPATH"])  # LiveRun's processes inherit it
    run = LiveRun.start(
        tmp_path, path, "--fleet", str(far), "--no-check", speedup=10, timeout_s=300
    )
    pid = 0
    try:
        run.wait_for("running   Stall()", within_s=120)
        pid = node_pid(run.run_dir, "D1")
        signalled = time.monotonic()
        os.kill(pid, signal.SIGTERM)
        assert wait_gone(pid, 60), "the node did not end after SIGTERM"
        ended_s = time.monotonic() - signalled
    finally:
        run.kill()
        if pid:
            with contextlib.suppress(ProcessLookupError):
                os.kill(pid, signal.SIGKILL)
    assert ended_s < 60
    report: dict[str, Any] = json.loads(
        (run.run_dir / "logs" / "D1" / "report.json").read_text(encoding="utf-8")
    )
    assert report["aborted"] and report["abort_reason"] == "stopped by signal", report
    stall = [a for a in report["actions"] if a["action"] == "Stall"]
    assert [a["result"] for a in stall] == ["cancelled"]
    assert report["final"]["z"] == pytest.approx(0.0, abs=0.15) and not report["final"]["armed"]
