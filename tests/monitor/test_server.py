"""The monitor's server for a real run: ``eamos run --monitor`` of experiment B over a websocket."""

from __future__ import annotations

import json
import re
import socket
import subprocess
import sys
import urllib.error
import urllib.request
from dataclasses import dataclass
from pathlib import Path

import pytest
from websockets.sync.client import connect

from eamos.ground.summary import RunSummary
from eamos.monitor.replay import load_replay
from eamos.monitor.setup import load_setup
from eamos.monitor.state import FINAL_NODE_STATES, apply_patches, final_node_states
from eamos.report import load_run, table7
from tests.monitor.live import URL, start_live_run
from tests.support.runs import INDEPENDENT, eamos

pytestmark = [pytest.mark.e2e, pytest.mark.xdist_group("monitor-live-b")]

FINAL_WORDS = {"finished", "failed", "aborted", "timed out"}
#: Node states a node may go to from each state (a loop's next iteration starts over).
MOVES = {
    "waiting": {"running", *FINAL_NODE_STATES},
    "running": {"running", *FINAL_NODE_STATES},
}


def post(url: str, body: dict) -> tuple[int, dict]:
    req = urllib.request.Request(
        url, json.dumps(body).encode(), {"Content-Type": "application/json"}, method="POST"
    )
    try:
        with urllib.request.urlopen(req, timeout=30) as res:
            return res.status, json.loads(res.read())
    except urllib.error.HTTPError as exc:
        return exc.code, json.loads(exc.read())


def expected_nodes(run_dir: Path, summary: RunSummary) -> dict[str, str]:
    setup = load_setup(run_dir)
    out: dict[str, str] = {}
    for name, result in summary.drones.items():
        out.update(final_node_states(setup, name, result.report))
    out.update(final_node_states(setup, "GCS", summary.ground_station))
    return out


@dataclass
class LiveB:
    """One ``eamos run --monitor`` of experiment B, watched over the websocket."""

    run_dir: Path
    messages: list[dict]
    page: dict
    summary: RunSummary
    lines: list[str]


@pytest.fixture(scope="module")
def live_b(tmp_path_factory: pytest.TempPathFactory) -> LiveB:
    tmp_path = tmp_path_factory.mktemp("live_b")
    # Speedup 5: the page connects while the drones start, well before the mission ends.
    run = start_live_run(tmp_path, "experiment_b", speedup=5)
    try:
        url, port, _token = run.wait_for(URL).groups()
        base = f"http://127.0.0.1:{port}"
        messages: list[dict] = []
        with connect(f"ws://127.0.0.1:{port}/ws", open_timeout=30) as ws:
            # Without the token nothing is aborted; the refusal is logged with its origin.
            assert post(f"{base}/api/abort", {"token": "wrong"})[0] == 403
            with urllib.request.urlopen(url, timeout=30) as res:
                assert b"monitor.js" in res.read()
            while True:
                msg = json.loads(ws.recv(timeout=180))
                messages.append(msg)
                page = messages[0]["state"]
                if msg["type"] == "patches":
                    apply_patches(page, msg["patches"])
                if page["mission"]["state"] in FINAL_WORDS:
                    break
        assert run.finish() == 0, "\n".join(run.lines)
    finally:
        if run.proc.poll() is None:
            run.proc.kill()
    summary = RunSummary.read(tmp_path / "summary.json")
    return LiveB(tmp_path / "run", messages, page, summary, run.lines)


def actions_of(summary: RunSummary) -> list[tuple[str, str, float]]:
    return sorted(
        (n, a.node, a.start)
        for n, r in summary.drones.items()
        for a in (r.report.actions if r.report else ())
    )


def test_websocket_messages_of_experiment_b_are_in_order_complete_and_end_as_the_summary(
    live_b: LiveB,
):
    messages, page, summary = live_b.messages, live_b.page, live_b.summary
    assert summary.ok
    # In order and complete: a snapshot, then numbered patches with no gap.
    assert messages[0]["type"] == "snapshot"
    seq = messages[0]["seq"]
    states: dict[str, list[str]] = {}
    for msg in messages[1:]:
        assert msg["type"] == "patches"
        assert msg["seq"] == seq + len(msg["patches"]), "a gap in the patch numbers"
        seq = msg["seq"]
        for p in msg["patches"]:
            if p["k"] == "node":
                states.setdefault(p["node"], []).append(p["state"])
    # Every node's final state is the summary's, and nodes only move forward.
    expected = expected_nodes(live_b.run_dir, summary)
    assert set(expected.values()) == {"done"}
    assert {k: v["state"] for k, v in page["nodes"].items()} == expected
    for node, seen in states.items():
        for a, b in zip(["waiting", *seen], seen, strict=False):
            assert b in MOVES.get(a, set()), f"{node}: {a} -> {b} ({seen})"
    assert page["mission"]["state"] == summary.word == "finished"
    # The drones' live positions went where their reports say they ended.
    homes = {p["name"]: p["home"] for p in page["setup"]["participants"]}
    assert homes["Drone1"] != homes["Drone2"]  # side by side, as the check sees them
    for name, result in summary.drones.items():
        final = result.report.final if result.report is not None else None
        assert final is not None
        shown = page["drones"][name]
        assert shown["x"] == pytest.approx(homes[name][0] + final.x, abs=1e-6)
        assert shown["y"] == pytest.approx(homes[name][1] + final.y, abs=1e-6)
        assert shown["trail"], f"{name}: no trail"
    # The timeline holds every action of the reports, with their times.
    assert sorted((b["drone"], b["node"], b["start"]) for b in page["bars"]) == actions_of(summary)
    assert any("abort refused" in line for line in live_b.lines), "\n".join(live_b.lines)
    # The live trigger counts per link end as the reports' (Table 7): each arc once.
    table = {row["drone"]: row for row in table7(load_run(live_b.run_dir)).records()}
    for name in summary.drones:
        sent = sum(v["sent"] for v in page["links"].values() if v["src"] == name)
        received = sum(v["received"] for v in page["links"].values() if v["dst"] == name)
        assert f"{sent} / {received}" == table[name]["triggers sent / received"]
    assert all(v["sent"] == v["received"] == v["arcs"] for v in page["links"].values())
    log = (live_b.run_dir / "logs" / "monitor.log").read_text()
    assert "monitor.abort.refused" in log and "127.0.0.1" in log


def final_view(state: dict) -> dict:
    """What must be equal between a live run's last page and its replay."""
    return {
        "nodes": {k: v["state"] for k, v in state["nodes"].items()},
        "mission": state["mission"]["state"],
        "bars": sorted((b["drone"], b["node"], b["start"], b["end"]) for b in state["bars"]),
        "drones": {
            n: (*(round(d[a], 6) for a in "xyz"), d["armed"]) for n, d in state["drones"].items()
        },
        "links": state["links"],
    }


def test_replay_of_the_run_folder_gives_the_same_final_page(live_b: LiveB):
    assert final_view(load_replay(live_b.run_dir).state_at(float("inf"))) == final_view(live_b.page)
    # ... through `eamos monitor RUN_DIR`, and its time slider goes back to the start.
    proc = subprocess.Popen(
        [sys.executable, "-m", "eamos.cli", "monitor", str(live_b.run_dir)],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    try:
        assert proc.stdout is not None
        line = proc.stdout.readline()
        found = re.search(r"http://127\.0\.0\.1:(\d+)/", line)
        assert found, line
        base = f"http://127.0.0.1:{found.group(1)}"
        with urllib.request.urlopen(f"{base}/api/setup", timeout=30) as res:
            span = json.loads(res.read())["replay"]
        assert span["start"] <= live_b.summary.started < span["end"]
        with connect(f"ws://127.0.0.1:{found.group(1)}/ws", open_timeout=30) as ws:
            ws.send(json.dumps({"type": "seek", "t": span["end"]}))
            end = json.loads(ws.recv(timeout=60))["state"]
            ws.send(json.dumps({"type": "seek", "t": span["start"]}))
            start = json.loads(ws.recv(timeout=60))["state"]
        assert final_view(end) == final_view(live_b.page)
        assert set(n["state"] for n in start["nodes"].values()) == {"waiting"}
        assert start["mission"]["state"] == "waiting for drones"
        assert post(f"{base}/api/abort", {"token": "x"})[0] == 409  # a replay cannot abort
    finally:
        proc.terminate()
        proc.wait(timeout=60)


def test_monitor_of_a_folder_that_is_no_run_is_bad_input(tmp_path):
    result = eamos("monitor", str(tmp_path / "nothing"))
    assert result.returncode == 2
    assert "no summary.json" in result.stderr and "Traceback" not in result.stderr


def test_monitor_on_a_taken_port_is_bad_input(live_b: LiveB):
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        result = eamos("monitor", str(live_b.run_dir), "--port", str(port))
    assert result.returncode == 2
    assert f"cannot listen on 127.0.0.1:{port}" in result.stderr
    assert "Traceback" not in result.stderr


def test_a_port_out_of_range_is_bad_input():
    result = eamos("run", "missions/experiment_b.go", "--monitor", "--port", "99999")
    assert result.returncode == 2
    assert "a port is 0..65535, not 99999" in result.stderr


def test_start_with_the_monitor_needs_a_run_folder(tmp_path):
    result = eamos("start", str(tmp_path), "--monitor")
    assert result.returncode == 2
    assert "no programs/*.program.json (not a run folder)" in result.stderr


def watch(port: str) -> dict:
    """The page's state over the websocket until the run's outcome word."""
    with connect(f"ws://127.0.0.1:{port}/ws", open_timeout=30) as ws:
        page = json.loads(ws.recv(timeout=180))["state"]
        while page["mission"]["state"] not in FINAL_WORDS:
            msg = json.loads(ws.recv(timeout=180))
            apply_patches(page, msg["patches"])
    return page


def test_a_failed_action_shows_failed_and_one_outcome_word(tmp_path):
    mission = tmp_path / "independent.go"
    mission.write_text(INDEPENDENT)
    fleet = tmp_path / "fleet.toml"
    fleet.write_text('[drones.Drone1.hal]\nadapter = "sim"\nreject_actions = ["FlyByX"]\n')
    run = start_live_run(tmp_path, mission, "--fleet", str(fleet), "--no-check", speedup=5)
    try:
        port = run.wait_for(URL).group(2)
        try:
            page = watch(port)
        except OSError as exc:
            run.finish()
            raise AssertionError("\n".join(run.lines)) from exc
        assert run.finish() == 1, "\n".join(run.lines)
    finally:
        if run.proc.poll() is None:
            run.proc.kill()
    summary = RunSummary.read(tmp_path / "summary.json")
    report = summary.drones["Drone1"].report
    assert report is not None and report.blocked_nodes
    flyby = next(a.node for a in report.actions if a.action == "FlyByX")
    assert page["nodes"][flyby]["state"] == "failed"
    for node in report.blocked_nodes:
        assert page["nodes"][node]["state"] == "failed", node
    assert page["mission"]["state"] == summary.word == "failed"
    assert page["mission"]["detail"] == "not ok: Drone1"
    # The terminal says the same word, and never "FAILED (ok)".
    assert any(line.startswith("mission independent failed (not ok: Drone1)") for line in run.lines)
    assert not any("(ok)" in line for line in run.lines)
