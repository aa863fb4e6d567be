"""Live trigger counts per link on the page of real runs (``eamos run --monitor``).

Each run's page is watched over the websocket; the counts come only from
live events (the run's end adds none), and they must end equal to the
drones' own reports as ``eamos report``'s Table 7 reads them -- for
experiment C and for a loop whose arcs cross drones (counts above the arcs).
Experiment B's run is checked in test_server.py.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import pytest
from websockets.sync.client import connect

from eamos.ground.summary import RunSummary
from eamos.monitor.state import apply_patches
from eamos.report import load_run, table7
from tests.monitor.live import URL, start_live_run

pytestmark = pytest.mark.e2e

FINAL_WORDS = {"finished", "failed", "aborted", "timed out"}

#: A RepeatFor whose body goes from Drone1 to Drone2 and back: 4 arcs each way, 6 triggers.
LOOP_ACROSS = """
func SEQ_Main() {
    PAR_Arm()
    PAR_Takeoff()
    RepeatFor(3, SEQ_Pass)
    PAR_Land()
    PAR_Disarm()
}
func PAR_Arm() {
    Drone1.Arm()
    Drone2.Arm()
}
func PAR_Takeoff() {
    Drone1.Takeoff(2)
    Drone2.Takeoff(3)
}
func SEQ_Pass() {
    Drone1.FlyByX(1)
    Drone2.FlyByX(1)
}
func PAR_Land() {
    Drone1.Land()
    Drone2.Land()
}
func PAR_Disarm() {
    Drone1.Disarm()
    Drone2.Disarm()
}
"""


@dataclass
class Watched:
    page: dict
    summary: RunSummary
    run_dir: Path
    link_patches_while_running: int
    link_patches_after_end: int


def watch_run(tmp_path: Path, mission: str | Path, speedup: float = 5) -> Watched:
    run = start_live_run(tmp_path, mission, speedup=speedup)
    running = after = 0
    try:
        port = run.wait_for(URL).group(2)
        with connect(f"ws://127.0.0.1:{port}/ws", open_timeout=30) as ws:
            page = json.loads(ws.recv(timeout=180))["state"]
            while page["mission"]["state"] not in FINAL_WORDS:
                msg = json.loads(ws.recv(timeout=180))
                for patch in msg["patches"]:
                    apply_patches(page, [patch])
                    if patch["k"] != "link":
                        continue
                    if page["mission"]["state"] == "running":
                        running += 1
                    elif page["mission"]["state"] in FINAL_WORDS:
                        after += 1
        assert run.finish() == 0, "\n".join(run.lines)
    finally:
        if run.proc.poll() is None:
            run.proc.kill()
    summary = RunSummary.read(tmp_path / "summary.json")
    return Watched(page, summary, tmp_path / "run", running, after)


def check_counts(w: Watched) -> dict[str, tuple[int, int]]:
    """The page's links add up to Table 7's sent / received per drone; those totals."""
    assert w.summary.ok
    assert w.link_patches_while_running > 0, "the counts did not move while the mission ran"
    assert w.link_patches_after_end == 0
    totals: dict[str, tuple[int, int]] = {}
    for link in w.page["links"].values():
        s, r = totals.get(link["src"], (0, 0))
        totals[link["src"]] = (s + link["sent"], r)
        s, r = totals.get(link["dst"], (0, 0))
        totals[link["dst"]] = (s, r + link["received"])
    table = table7(load_run(w.run_dir)).records()
    assert [row["drone"] for row in table] == list(w.summary.drones)
    for row in table:
        sent, received = (int(x) for x in row["triggers sent / received"].split(" / "))
        assert totals[row["drone"]] == (sent, received), row
    gcs = w.summary.ground_station
    assert gcs is not None and totals["GCS"][0] == gcs.triggers_sent
    return totals


def test_experiment_c_link_counts_end_as_table_7(tmp_path):
    w = watch_run(tmp_path, "experiment_c")
    check_counts(w)
    # A loop-free mission that ran to its end: every link carried each arc once.
    for link in w.page["links"].values():
        assert link["sent"] == link["received"] == link["arcs"], link
    assert {(v["src"], v["dst"]) for v in w.page["links"].values()} >= {
        ("Drone1", "Drone3"),
        ("Drone3", "Drone1"),
        ("GCS", "Drone3"),
    }


def test_a_loop_across_drones_counts_more_triggers_than_arcs(tmp_path):
    mission = tmp_path / "loop_across.go"
    mission.write_text(LOOP_ACROSS)
    w = watch_run(tmp_path, mission)
    check_counts(w)
    links = {(v["src"], v["dst"]): v for v in w.page["links"].values()}
    for pair in (("Drone1", "Drone2"), ("Drone2", "Drone1")):
        # The arc inside the loop carries a trigger per iteration (3), the others one each.
        assert links[pair]["arcs"] == 4
        assert links[pair]["sent"] == links[pair]["received"] == 4 + 2, links[pair]
