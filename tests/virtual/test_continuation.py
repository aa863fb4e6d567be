"""A virtual run that goes on from a mission's snapshot (issue 30): pure, no processes.

The snapshot is made the way the ground station makes it (:func:`drone_snapshot` of the
progress events a drone reports) from an uninterrupted virtual run stopped in Drone1's
third survey lane; the continuation must fly exactly what that run flew after the
moment, from where the drones were, and end where it ended.
"""

from __future__ import annotations

import json
import math
import re
import sys
from pathlib import Path
from typing import Any

import pytest

from eamos.check.explore import run_once
from eamos.compiler import compile_file
from eamos.ground.snapshot import drone_snapshot
from eamos.ground.station import DroneView
from eamos.hal.sim import SimSettings
from eamos.virtual import (
    SnapshotError,
    VirtualMission,
    VirtualRun,
    continuation,
    load_snapshot,
)
from tests.support.runs import MISSIONS, REPO, eamos

sys.path.insert(0, str(REPO / "scripts"))
# The snapshot of a virtual run, as the ground station makes it: one copy, shared with
# the benchmark of continuations.
from bench_continuation import snapshot_at

SURVEY = MISSIONS / "survey_repeat.go"


def full_run() -> tuple[Any, VirtualRun, dict[str, Any]]:
    compiled = compile_file(SURVEY)
    settings = {d: SimSettings() for d in compiled.programs}
    run, tracks = run_once(compiled, settings, {}, 1800.0)
    assert run.ok, run
    return compiled, run, tracks


def third_lane_start(run: VirtualRun) -> float:
    lanes = [r for r in run.drones["Drone1"].actions if r.action == "FlyByX" and r.args == (4.0,)]
    assert [r.iteration for r in lanes] == [(0,), (1,), (2,)]
    return lanes[2].start


def flown(run: VirtualRun, drone: str) -> list[tuple[str, tuple[int, ...]]]:
    """The actions ``drone`` flew in ``run`` that were not replayed, in order."""
    replayed = {(n, it) for d, n, it in run.replayed if d == drone}
    return [
        (r.node, tuple(r.iteration))
        for r in run.drones[drone].actions
        if (r.node, tuple(r.iteration)) not in replayed
    ]


def test_a_continuation_from_a_loops_third_iteration_flies_only_the_rest() -> None:
    compiled, full, tracks = full_run()
    t = third_lane_start(full) + 1.0  # 1 s into the third lane's first leg
    doc = snapshot_at(compiled, full, tracks, t)
    past = continuation(json.loads(json.dumps(doc)))  # as written and read back
    rest = VirtualMission(compiled.programs, continuation=past).run()
    assert rest.ok, rest
    for drone in ("Drone1", "Drone2"):
        ended = [(r.node, tuple(r.iteration)) for r in full.drones[drone].actions if r.end <= t]
        after = [(r.node, tuple(r.iteration)) for r in full.drones[drone].actions if r.end > t]
        # Nothing that had ended flies again: each ends at once, as it had.
        assert sorted((n, it) for d, n, it in rest.replayed if d == drone) == sorted(ended)
        replayed = [r for r in rest.drones[drone].actions if (r.node, r.iteration) in ended]
        assert all(r.start == r.end == 0.0 for r in replayed), replayed
        # What flies is what the uninterrupted run flew after the moment, in its order.
        assert flown(rest, drone) == after, drone
        # And it ends where the uninterrupted run ended.
        a, b = full.drones[drone].final, rest.drones[drone].final
        assert math.dist((a.x_m, a.y_m, a.z_m), (b.x_m, b.y_m, b.z_m)) < 0.3, (a, b)
        assert b.landed and not b.armed
    # Drone1's third lane goes on from where it was (its first leg to x = 4), then the rest.
    d1 = flown(rest, "Drone1")
    assert d1[0][1] == (2,) and all(it in ((2,), ()) for _, it in d1), d1
    first = next(r for r in rest.drones["Drone1"].actions if (r.node, r.iteration) == d1[0])
    same = next(r for r in full.drones["Drone1"].actions if (r.node, r.iteration) == d1[0])
    assert first.action == "FlyByX" and 0.5 < doc_x(doc) < 3.5
    # ... for what it had left: as long as the uninterrupted leg took after the moment.
    assert first.end - first.start == pytest.approx(same.end - t, abs=0.3)
    # The rest takes what the uninterrupted run took after the moment (within a second).
    assert rest.duration_s == pytest.approx(full.duration_s - t, abs=1.5)


def doc_x(doc: dict[str, Any]) -> float:
    return float(doc["participants"]["Drone1"]["vehicle"]["x"])


def test_the_loop_until_decision_comes_from_the_record_and_then_from_the_vehicle() -> None:
    """Drone2's RepeatUntil(Y > 5): the steps the snapshot shows begun are taken as begun;
    the next decision is simulated from where Drone2 is (two steps begun: a third)."""
    compiled, full, tracks = full_run()
    steps = [r for r in full.drones["Drone2"].actions if r.action == "FlyByY"]
    assert len(steps) == 3
    t = steps[1].start + 0.5  # in its second step
    rest = VirtualMission(
        compiled.programs, continuation=continuation(snapshot_at(compiled, full, tracks, t))
    )
    run = rest.run()
    assert [r.iteration for r in run.drones["Drone2"].actions if r.action == "FlyByY"] == [
        (0,),
        (1,),
        (2,),
    ]
    assert flown(run, "Drone2")[0] == (steps[1].node, (1,))


def test_a_snapshot_that_is_not_one_is_refused_with_where_and_why(tmp_path: Path) -> None:
    cases = [
        ([], "not a snapshot (no 'participants' table)"),
        ({"participants": {}}, "'mission_id' (text) and 't' (a time) are required"),
        (
            {"participants": {"D1": {"nodes": {}}}, "mission_id": "m", "t": 1.0},
            "participants.D1: no 'activations' list",
        ),
        (
            {"participants": {"D1": {"activations": [{"node": "n1"}]}}, "mission_id": "m", "t": 1},
            "participants.D1.activations[0]: needs 'node' (text), 'iteration' (integers)",
        ),
        (
            {
                "participants": {"D1": {"activations": [], "vehicle": {"x": 1, "y": "a", "z": 0}}},
                "mission_id": "m",
                "t": 1,
            },
            "participants.D1.vehicle.y: a number is required",
        ),
    ]
    for doc, message in cases:
        with pytest.raises(SnapshotError, match=re.escape(message)):
            continuation(doc)
    with pytest.raises(SnapshotError, match="cannot read the snapshot"):
        load_snapshot(tmp_path)
    (tmp_path / "snapshot.json").write_text("{")
    with pytest.raises(SnapshotError, match=re.escape("not a snapshot (not JSON")):
        load_snapshot(tmp_path)


def test_eamos_check_from_a_snapshot_of_another_mission_or_none_exits_2(tmp_path: Path) -> None:
    compiled, full, tracks = full_run()
    doc = snapshot_at(compiled, full, tracks, 5.0)
    doc["mission_id"] = "0" * 16
    (tmp_path / "snapshot.json").write_text(json.dumps(doc))
    proc = eamos("check", str(SURVEY), "--from", str(tmp_path))
    assert proc.returncode == 2, proc.stdout + proc.stderr
    assert "the snapshot is of mission 0000000000000000" in proc.stderr
    assert "Traceback" not in proc.stderr
    proc = eamos("check", str(SURVEY), "--from", str(tmp_path / "nowhere"))
    assert proc.returncode == 2 and "cannot read the snapshot" in proc.stderr, proc.stderr
    assert "Traceback" not in proc.stderr


def test_eamos_check_from_a_snapshot_checks_the_rest(tmp_path: Path) -> None:
    compiled, full, tracks = full_run()
    t = third_lane_start(full) + 1.0
    (tmp_path / "snapshot.json").write_text(json.dumps(snapshot_at(compiled, full, tracks, t)))
    proc = eamos("check", str(SURVEY), "--from", str(tmp_path), "--json")
    assert proc.returncode == 0, proc.stdout + proc.stderr
    report = json.loads(proc.stdout)
    assert report["settings"]["continued_from"]["why"] == "pause"
    assert all(r["duration_s"] < full.duration_s - t + 1.5 for r in report["runs"]), report
    plain = eamos("check", str(SURVEY), "--from", str(tmp_path))
    assert plain.returncode == 0 and "the rest of the mission from" in plain.stdout, plain.stdout


def test_the_snapshot_keeps_each_activations_last_state_and_where_it_first_began() -> None:
    """A suspended and resumed leg began where it first did; an If keeps its branch; an
    event with junk loop counters is left out (pure: the ground station's view in, the
    snapshot's part out)."""
    view = DroneView("D1")
    view.events += [
        {"t": 10.0, "state": "running", "node": "n5", "action": "FlyByX(4)",
         "iteration": [2], "position": [0.0, 2.0, 3.0]},
        {"t": 11.0, "state": "waiting", "node": "n5", "action": "FlyByX(4)",
         "iteration": [2], "detail": "suspended"},
        {"t": 15.0, "state": "running", "node": "n5", "action": "FlyByX(4)",
         "iteration": [2], "position": [1.0, 2.0, 3.0]},
        {"t": 16.0, "state": "decided", "node": "n6", "action": "If X > 1",
         "iteration": [], "detail": "then: X > 1 is true"},
        {"t": 17.0, "state": "ok", "node": "n7", "iteration": ["x"]},
        {"t": 18.0, "link": "lost"},
    ]  # fmt: skip
    part = drone_snapshot(view)
    assert part["activations"] == [
        {"node": "n5", "iteration": [2], "state": "running", "t": 15.0, "action": "FlyByX(4)",
         "at": 10.0, "from": [0.0, 2.0, 3.0]},
        {"node": "n6", "iteration": [], "state": "decided", "t": 16.0,
         "detail": "then: X > 1 is true"},
    ]  # fmt: skip
    assert [r["node"] for r in part["running"]] == ["n5"]
    past = continuation(
        {"mission_id": "m", "t": 20.0, "participants": {"D1": {**part, "vehicle": {
            "x": 3.0, "y": 2.0, "z": 3.0}}}}
    )  # fmt: skip
    # Begun at (0, 2, 3): its end, 4 m north of there (wherever the vehicle is now).
    assert past.rest("D1", "n5", (2,), "FlyByX", (4.0,)) == ("FlyToXYZ", (4.0, 2.0, 3.0))
    assert past.rest("D1", "n5", (1,), "FlyByX", (4.0,)) == ("FlyByX", (4.0,))  # not begun
    assert past.ended("D1", "n5", (2,)) is None
    assert past.ended("D9", "n5", (2,)) is None  # a participant the snapshot does not hold
    # Began at 10, the snapshot at 20: 20 s of 30 left (at 25: 15 s).
    assert past.rest("D1", "n5", (2,), "PauseFor", (30.0,)) == ("PauseFor", (20.0,))
    assert past.rest("D1", "n5", (2,), "PauseFor", (30.0,), 25.0) == ("PauseFor", (15.0,))
