"""Each node's identity by content, and renumbering an amended mission (issue 31).

Pure: compiled missions in, programs and records out.  What the check makes of an
amendment: ``tests/check/test_amendment.py``; a roll-out that redeploys by content:
``tests/fleetops/test_rollout_by_content.py``.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from eamos.compiler import compile_file, compile_mission
from eamos.compiler.amendment import (
    Place,
    compare,
    execution_digest,
    node_progress,
    places,
    rekey,
    renumbering,
)
from tests.support.runs import MISSIONS, REPO

EVERY_MISSION = sorted(MISSIONS.glob("*.go")) + sorted((MISSIONS / "fleets").glob("*.go"))
LANES = REPO / "tests" / "operator" / "four_lanes.go"


def lanes(edit: tuple[str, str] | None = None):  # type: ignore[no-untyped-def]
    text = LANES.read_text()
    if edit is not None:
        assert edit[0] in text
        text = text.replace(edit[0], edit[1], 1)
    return compile_mission(text, str(LANES))


@pytest.mark.parametrize("path", EVERY_MISSION, ids=lambda p: p.name)
def test_a_mission_renumbered_against_itself_is_itself(path: Path) -> None:
    compiled = compile_file(path)
    again = rekey(compiled.programs, compiled)
    for drone, program in compiled.programs.items():
        assert again.programs[drone].to_json() == program.to_json()
    assert not any(c.changes for c in compare(compiled.programs, again.programs).values())
    # Places are unique: the renumbering is one to one.
    assert len(set(places(compiled.programs).values())) == len(places(compiled.programs))


def test_an_insertion_into_one_drones_lane_renumbers_nothing_of_the_others() -> None:
    running = lanes()
    edited = lanes(("\tDrone2.FlyByX(-12)\n", "\tDrone2.FlyByZ(1)\n\tDrone2.FlyByX(-12)\n"))
    # Numbered as written, every node after the insertion moves: all drones differ.
    assert all(
        execution_digest(edited.programs[d]) != execution_digest(running.programs[d])
        for d in ("Drone3", "Drone4")
    )
    amended = rekey(running.programs, edited)
    for drone in ("GCS", "Drone1", "Drone3", "Drone4"):
        # Node for node what they run (lines below the insertion moved down by one).
        assert execution_digest(amended.programs[drone]) == execution_digest(
            running.programs[drone]
        )
        keys = [(n.key, n.label) for n in amended.programs[drone].nodes]
        assert keys == [(n.key, n.label) for n in running.programs[drone].nodes], drone
        assert amended.programs[drone].arcs == running.programs[drone].arcs, drone
    changes = compare(running.programs, amended.programs)
    assert [d for d, c in changes.items() if c.changes] == ["Drone2"]
    [added] = changes["Drone2"].added
    top = max(n.meg for p in running.programs.values() for n in p.nodes)
    assert added.label == "FlyByZ(1)" and added.key == f"n{top + 1}"  # after the running's
    assert changes["Drone2"].switch == added
    # Drone2's running leg is only redirected (what follows it changes), not touched.
    leg = next(n for n in running.programs["Drone2"].nodes if n.label == "FlyByX(12)")
    assert changes["Drone2"].redirected == (leg.key,)
    assert amended.mission_id == running.mission_id


def test_the_renumbered_graphs_agree_with_the_programs() -> None:
    running = lanes()
    amended = rekey(
        running.programs, lanes(("\tDrone1.Land()\n", "\tDrone1.FlyByY(-1)\n\tDrone1.Land()\n"))
    )
    megs = {n.meg for p in amended.programs.values() for n in p.nodes}
    assert set(amended.meg.nodes) == megs
    for drone, program in amended.programs.items():
        graph = amended.mdgs[drone]
        assert set(graph.nodes) == {n.key for n in program.nodes}
        assert {(a.src, a.dst) for a in program.arcs} == set(graph.edges)
        assert all(graph.nodes[n.key]["meg"] == n.meg for n in program.nodes)


def test_a_changed_argument_keeps_its_node_and_shows_as_changed() -> None:
    running = lanes()
    amended = rekey(running.programs, lanes(("\tDrone4.FlyByX(-12)\n", "\tDrone4.FlyByX(-10)\n")))
    change = compare(running.programs, amended.programs)["Drone4"]
    [changed] = change.changed
    assert changed.label == "FlyByX(-10)" and not change.added and not change.removed
    old = next(n for n in running.programs["Drone4"].nodes if n.label == "FlyByX(-12)")
    assert changed.key == old.key and change.touched == (old.key,)


def test_a_place_is_drone_block_kind_action_and_ordinal() -> None:
    running = lanes()
    found = places(running.programs)
    legs = sorted(
        (p for p in found.values() if p.drone == "Drone3" and p.action == "FlyByX"),
        key=lambda p: p.ordinal,
    )
    assert legs == [
        Place("Drone3", "SEQ_Lane3", "action", "FlyByX", 0),
        Place("Drone3", "SEQ_Lane3", "action", "FlyByX", 1),
    ]
    forks = [p for p in found.values() if p.kind == "fork"]
    assert forks and all(p.drone == "" for p in forks)  # one place for all its copies


def test_new_nodes_are_numbered_after_the_running_missions_last() -> None:
    running = lanes()
    edited = lanes(("\tDrone1.Land()\n", "\tDrone1.FlyByY(-1)\n\tDrone1.Land()\n"))
    numbers = renumbering(running.programs, edited.programs)
    top = max(n.meg for p in running.programs.values() for n in p.nodes)
    assert sorted(v for v in numbers.values() if v > top) == [top + 1]
    assert len(set(numbers.values())) == len(numbers)


def test_progress_marks_what_ran_before_a_reported_node_as_ended() -> None:
    programs = lanes().programs
    leg = next(n for n in programs["Drone1"].nodes if n.label == "FlyByX(12)")
    arm = next(n for n in programs["Drone1"].nodes if n.label == "Arm()")
    land = next(n for n in programs["Drone1"].nodes if n.label == "Land()")
    progress = node_progress(programs, {leg.key: "running"})
    assert progress[leg.key] == "running" and progress[arm.key] == "ended"
    assert land.key not in progress
    assert node_progress(programs, {leg.key: "ok"})[leg.key] == "ended"


def test_an_amended_copy_of_a_mission_without_package_keeps_the_running_name() -> None:
    # Without a `package` line a mission is named after its file: the amended copy's
    # file name must not make every drone's program differ.
    text = LANES.read_text().replace("package FourLanes\n", "")
    running = compile_mission(text, "lanes.go")
    edited = compile_mission(
        text.replace("\tDrone2.FlyByX(-12)\n", "\tDrone2.FlyByX(-6)\n\tDrone2.FlyByX(-6)\n"),
        "lanes-split.go",
    )
    assert edited.programs["Drone1"].mission != running.programs["Drone1"].mission
    amended = rekey(running.programs, edited)
    changes = compare(running.programs, amended.programs)
    assert [d for d, c in changes.items() if c.touched] == ["Drone2"], changes
    assert {p.mission for p in amended.programs.values()} == {running.programs["GCS"].mission}
