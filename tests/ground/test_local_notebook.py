"""``eamos run`` keeps ``runs/latest``; the notebook as shipped finds it from any folder.

Issue 14: the notebook's default ``RUN_DIR = "runs/latest"`` existed nowhere.  Issue 29:
``runs/latest`` named runs the pre-flight check refused (no summary.json), so the notebook,
``eamos report runs/latest`` and ``eamos monitor runs/latest`` failed after one.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import urllib.request
from pathlib import Path

import pytest

from tests.support.runs import MISSIONS, REPO, RUN_TIMEOUT_S

pytestmark = pytest.mark.e2e

NOTEBOOK = REPO / "notebooks" / "analyse_run.ipynb"


def _eamos_run(cwd: Path) -> Path:
    """``eamos run`` of experiment B in ``cwd`` with the default run folder; that folder."""
    proc = subprocess.run(
        [
            *(sys.executable, "-m", "eamos.cli", "run", str(MISSIONS / "experiment_b.go")),
            *("--speedup", "20", "--plain", "--no-svg", "--no-check", "--timeout", "150"),
        ],
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=RUN_TIMEOUT_S,
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
    line = [ln for ln in proc.stdout.splitlines() if ln.startswith("summary: ")][-1]
    return Path(line.removeprefix("summary: ")).parent


# Left hovering at its end: the pre-flight check refuses it.
HOVERS = "var Drone1 Quadcopter\nfunc SEQ_Main() {\n    Drone1.Arm()\n    Drone1.Takeoff(2)\n}\n"


def _refused_run(cwd: Path) -> Path:
    """``eamos run`` of a mission the pre-flight check refuses, in ``cwd``; its run folder."""
    mission = cwd / "hovers.go"
    mission.write_text(HOVERS)
    proc = subprocess.run(
        [sys.executable, "-m", "eamos.cli", "run", str(mission), "--plain", "--no-svg"],
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=RUN_TIMEOUT_S,
    )
    assert proc.returncode == 1, proc.stdout + proc.stderr
    assert "pre-flight check found 1 error(s)" in proc.stderr
    (folder,) = (cwd / "runs").glob("hovers-*")
    assert f"the whole report: {folder.resolve() / 'check.json'}" in proc.stderr
    return folder


def _eamos(cwd: Path, *args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "eamos.cli", *args],
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=RUN_TIMEOUT_S,
    )


def test_a_refused_run_keeps_its_folder_but_latest_names_the_run_that_flew(
    tmp_path: Path,
) -> None:
    flown = _eamos_run(tmp_path)
    refused = _refused_run(tmp_path)
    assert (refused / "check.json").is_file() and not (refused / "summary.json").exists()
    latest = tmp_path / "runs" / "latest"
    assert latest.resolve() == flown.resolve()
    # eamos report runs/latest, as a newcomer types it, without EAMOS_RUN_DIR.
    made = _eamos(tmp_path, "report", "runs/latest")
    assert made.returncode == 0, made.stdout + made.stderr
    assert (flown / "report.html").is_file()
    # eamos monitor runs/latest serves the replay page.
    monitor = subprocess.Popen(
        [sys.executable, "-m", "eamos.cli", "monitor", "runs/latest"],
        cwd=tmp_path,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        assert monitor.stdout is not None
        line = monitor.stdout.readline()
        assert line.startswith("monitor (replay of runs/latest): http://"), line
        url = line.split(": ", 1)[1].split()[0]
        with urllib.request.urlopen(url, timeout=60) as page:
            assert page.status == 200 and b"<html" in page.read().lower()
    finally:
        monitor.send_signal(signal.SIGINT)
        monitor.communicate(timeout=60)
    assert monitor.returncode == 0
    # The refused folder is not a run to report on: said with the path, exit 2.
    refused_report = _eamos(tmp_path, "report", str(refused))
    assert refused_report.returncode == 2 and "summary.json" in refused_report.stderr


def _kernel_or_skip() -> None:
    pytest.importorskip("nbformat", reason="nbformat is not installed (pip install -e '.[test]')")
    pytest.importorskip("nbclient", reason="nbclient is not installed (pip install -e '.[test]')")
    from jupyter_client.kernelspec import KernelSpecManager

    if "python3" not in KernelSpecManager().find_kernel_specs():
        pytest.skip("no Jupyter kernel 'python3' (pip install ipykernel), the notebook cannot run")


def test_latest_names_the_newest_run(tmp_path: Path) -> None:
    first = _eamos_run(tmp_path)
    latest = tmp_path / "runs" / "latest"
    assert latest.is_symlink() and latest.resolve() == first.resolve()
    second = _eamos_run(tmp_path)
    assert second != first
    assert latest.resolve() == second.resolve()
    assert os.readlink(latest) == second.name  # relative: the runs folder can move whole
    assert (latest / "summary.json").is_file()


def test_the_notebook_as_shipped_finds_runs_latest_from_a_folder_below(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    _kernel_or_skip()
    import nbclient
    import nbformat

    run_dir = _eamos_run(tmp_path)
    _refused_run(tmp_path)  # a run refused since does not hide the one that flew
    below = tmp_path / "notebooks" / "mine"  # e.g. Jupyter started in a sub-folder
    below.mkdir(parents=True)
    monkeypatch.delenv("EAMOS_RUN_DIR", raising=False)  # the kernel inherits the environment
    notebook = nbformat.read(NOTEBOOK, as_version=4)
    client = nbclient.NotebookClient(
        notebook, timeout=180, kernel_name="python3", resources={"metadata": {"path": str(below)}}
    )
    client.execute()
    outputs = [o for c in notebook.cells if c.cell_type == "code" for o in c.outputs]
    assert not [o for o in outputs if o.output_type == "error"]
    printed = "".join(o.get("text", "") for o in outputs if o.output_type == "stream")
    assert f"run folder: {run_dir.resolve()}" in printed
    kinds = [k for o in outputs for k in o.get("data", {})]
    assert kinds.count("image/png") == 3  # Gantt chart, x/y and altitude


def test_the_notebook_says_what_to_do_without_a_run(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    _kernel_or_skip()
    import nbclient
    import nbformat

    monkeypatch.delenv("EAMOS_RUN_DIR", raising=False)
    notebook = nbformat.read(NOTEBOOK, as_version=4)
    client = nbclient.NotebookClient(
        notebook,
        timeout=180,
        kernel_name="python3",
        resources={"metadata": {"path": str(tmp_path)}},
    )
    with pytest.raises(
        nbclient.exceptions.CellExecutionError, match=r"run `eamos run MISSION\.go`"
    ):
        client.execute()
