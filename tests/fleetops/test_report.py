"""Log analysis: ``eamos.report``, ``eamos report`` and the notebook, on a fresh ``eamos run``."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import pytest

from eamos import report

REPO = Path(__file__).resolve().parents[2]
NOTEBOOK = REPO / "notebooks" / "analyse_run.ipynb"


def test_table7_matches_the_summary_and_the_logs(local_run):
    run = report.load_run(local_run)
    table = report.table7(run)
    summary = json.loads((local_run / "summary.json").read_text())
    assert [r[0] for r in table.rows] == ["Drone1", "Drone2"]
    for row, name in zip(table.rows, ["Drone1", "Drone2"], strict=True):
        rep = summary["drones"][name]
        assert row[1] == rep["mdg"]["nodes"] and row[2] == rep["mdg"]["internal_arcs"]
        assert row[3] == f"{rep['external_in']} / {rep['external_out']}"
        assert row[4] == row[5] == row[3]  # reports, logs and MDG agree (paper Table 7)
        assert row[6] is True and row[7] > 0
    assert "Drone1" in str(table) and "<table" in table._repr_html_()


def test_timeline_and_trajectories(local_run):
    run = report.load_run(local_run)
    bars = report.action_bars(run)
    assert len(bars) == 18 and {b["drone"] for b in bars} == {"Drone1", "Drone2"}
    assert all(b["end_s"] >= b["start_s"] >= -0.01 for b in bars)
    assert [b["label"] for b in bars if b["drone"] == "Drone1"][:2] == ["Arm()", "Takeoff(1.5)"]
    tracks = report.trajectories(run)
    for drone, track in tracks.items():
        log = (local_run / "logs" / drone / "adapter.log").read_text()
        assert len(track["t"]) == log.count('"adapter.position"') > 3
        assert track["t"] == sorted(track["t"])
        # Inside the 1 m square, at most 1.5 m + 0.5 m high, and up in between (positions
        # are sampled about once a second of vehicle time: corners and touchdown may fall
        # between samples).
        assert all(-0.1 <= v <= 1.1 for v in track["x"] + track["y"])
        assert 1.0 < max(track["z"]) <= 2.1 and track["z"][0] == pytest.approx(0, abs=0.1)
    durations = {r[0]: r for r in report.durations(run).rows}
    assert durations["mission execution"][2] > 0
    assert durations["Drone1"][1] == 9


def test_html_report_is_self_contained(local_run, tmp_path):
    out = tmp_path / "r" / "report.html"
    proc = subprocess.run(
        [sys.executable, "-m", "eamos.cli", "report", str(local_run), "-o", str(out)],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=REPO,
    )
    assert proc.returncode == 0, proc.stderr
    page = out.read_text()
    assert page.count('src="data:image/png;base64,') == 3
    assert not re.search(r'(src|href)="(https?:)?//', page)  # nothing fetched from elsewhere
    for text in ("paper Table 7", "Drone1", "Drone2", "Mission timeline", "mission execution"):
        assert text in page


def test_report_of_a_folder_that_is_not_a_run(tmp_path):
    proc = subprocess.run(
        [sys.executable, "-m", "eamos.cli", "report", str(tmp_path)],
        capture_output=True,
        text=True,
        timeout=60,
        cwd=REPO,
    )
    assert proc.returncode == 2
    assert "no summary.json" in proc.stderr and "Traceback" not in proc.stderr


def test_notebook_runs_on_a_fresh_run(local_run, monkeypatch):
    nbformat = pytest.importorskip("nbformat")
    nbclient = pytest.importorskip("nbclient")
    monkeypatch.setenv("EAMOS_RUN_DIR", str(local_run))  # the kernel inherits it
    notebook = nbformat.read(NOTEBOOK, as_version=4)
    client = nbclient.NotebookClient(
        notebook,
        timeout=180,
        kernel_name="python3",
        resources={"metadata": {"path": str(REPO)}},  # the kernel's working folder
    )
    client.execute()
    outputs = [o for c in notebook.cells if c.cell_type == "code" for o in c.outputs]
    assert not [o for o in outputs if o.output_type == "error"]
    kinds = [k for o in outputs for k in o.get("data", {})]
    assert kinds.count("image/png") == 3  # Gantt chart, x/y and altitude
    html = "".join(o["data"].get("text/html", "") for o in outputs if "data" in o)
    assert "paper Table 7" in html and "Durations" in html
