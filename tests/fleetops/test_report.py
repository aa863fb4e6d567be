"""Log analysis: ``eamos.report``, ``eamos report`` and the notebook, on a fresh ``eamos run``."""

from __future__ import annotations

import itertools
import json
import re
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

from eamos import report

REPO = Path(__file__).resolve().parents[2]
NOTEBOOK = REPO / "notebooks" / "analyse_run.ipynb"
# The tests on the session's one `eamos run` (local_run) share one worker: it is flown once.
pytestmark = [pytest.mark.e2e, pytest.mark.xdist_group("fleet-local-run")]


def test_table7_matches_the_summary_and_the_logs(local_run):
    run = report.load_run(local_run)
    table = report.table7(run)
    summary = json.loads((local_run / "summary.json").read_text())
    assert [r[0] for r in table.rows] == ["Drone1", "Drone2"]
    for row, name in zip(table.rows, ["Drone1", "Drone2"], strict=True):
        rep = summary["drones"][name]
        assert row[1] == rep["mdg"]["nodes"] and row[2] == rep["mdg"]["internal_arcs"]
        # Sent first, received second, in every column (as the CLI prints them).
        assert row[3] == f"{rep['external_out']} / {rep['external_in']}"
        assert row[4] == row[5] == row[3]  # reports, logs and MDG agree (paper Table 7)
        assert row[6] is True and row[7] == "" and row[8] > 0
    assert table.columns[4] == "triggers sent / received"
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
        # Every line, plus a point where each hold ended (the lines stop while it holds).
        assert len(track["t"]) >= log.count('"adapter.position"') > 20
        assert track["t"] == sorted(track["t"])
        # Inside the 1 m square, at most 1.5 m + 0.5 m high, and up in between.
        assert all(-0.11 <= v <= 1.11 for v in track["x"] + track["y"])
        assert 1.0 < max(track["z"]) <= 2.1 and track["z"][0] == pytest.approx(0, abs=0.1)
    durations = {r[0]: r for r in report.durations(run).rows}
    assert durations["mission execution"][2] > 0
    assert durations["Drone1"][1] == 9


def at(track: dict[str, list[float]], t: float) -> tuple[float, float, float]:
    """The track's position at ``t``, interpolated linearly."""
    ts = track["t"]
    i = next((k for k, v in enumerate(ts) if v >= t), len(ts) - 1)
    if i == 0 or ts[i] <= t:
        return track["x"][i], track["y"][i], track["z"][i]
    f = (t - ts[i - 1]) / (ts[i] - ts[i - 1])
    return tuple(  # type: ignore[return-value]
        track[a][i - 1] + f * (track[a][i] - track[a][i - 1]) for a in ("x", "y", "z")
    )


def test_the_drawn_square_is_a_square(local_run):
    """The report's tracks pass through every corner at the time the summary ends each move.

    Positions are logged at 5 Hz while moving (and the report holds the
    position through the pauses between lines), so at each FlyBy's end the
    track must be at the corner the mission's relative moves add up to.
    """
    run = report.load_run(local_run)
    tracks = report.trajectories(run)
    for drone in run.drones:
        expected = [0.0, 0.0, 0.0]
        corners = 0
        rep = run.report(drone)
        assert rep is not None
        for action in rep.actions:
            if action.action == "Takeoff":
                expected[2] = action.args[0]
            elif action.action.startswith("FlyBy"):
                expected["XYZ".index(action.action[-1])] += action.args[0]
            else:
                continue
            got = at(tracks[drone], action.end - run.t0)
            assert got == pytest.approx(tuple(expected), abs=0.12), (drone, action)
            corners += 1
        assert corners == 6  # Takeoff, the four sides, the climb


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


def test_gantt_labels_never_overlap_and_long_bars_keep_theirs():
    """Many short actions (experiment D's loops): labels fit or are left out, never overlap."""
    bars: list[dict[str, Any]] = [
        {"drone": "D1", "label": "Takeoff(2)", "start_s": 0.0, "duration_s": 60.0, "end_s": 60.0}
    ]
    t = 60.0
    for i in range(80):  # 80 short hops of 0.5-1.5 s
        d = 0.5 + (i % 3) * 0.5
        bars.append(
            {"drone": "D1", "label": f"FlyByX({i})", "start_s": t, "duration_s": d, "end_s": t + d}
        )
        t += d
    width_pt = 10 * 72 * 0.85
    labels = report.gantt_labels(bars, width_pt)
    assert labels[0] == report.GanttLabel(0, 30.0, False)  # the long bar: inside, upright
    per_pt = t / width_pt
    extents = []
    for lab in labels:
        half = (
            7.0 * 1.2 * per_pt / 2
            if lab.rotated
            else len(bars[lab.bar]["label"]) * 4.2 * per_pt / 2
        )
        extents.append((lab.x_s - half, lab.x_s + half))
    extents.sort()
    assert all(a[1] <= b[0] + 1e-9 for a, b in itertools.pairwise(extents))
    assert 5 < len(labels) < len(bars)  # some short ones labelled, the rest left out
