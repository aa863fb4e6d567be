"""Checking an amendment against a flying mission's snapshot (issue 31, ``eamos amend``).

The snapshot is the one a ground station would write halfway through every drone's
first leg of ``tests/operator/four_lanes.go`` (flown in virtual time, as the look-ahead's
tests do); the amendments are edits of its text.  The same judged on a real paused run:
``tests/operator/test_amend.py``.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

import pytest

from eamos.check import check_amendment
from eamos.compiler import compile_mission
from eamos.config import FleetConfig
from eamos.virtual import SnapshotError
from tests.support.four_lanes import (
    HEAD_ON,
    LANES,
    LATER_PARTS,
    RUNNING_LEG,
    TEXT,
    amended,
    line_of,
)
from tests.support.runs import REPO

sys.path.insert(0, str(REPO / "scripts"))
from bench_continuation import snapshot_at
from bench_lookahead import flown


@pytest.fixture(scope="module")
def flying() -> tuple[Any, dict[str, Any]]:
    """(the running mission compiled, the snapshot halfway through Drone1's first leg)."""
    compiled = compile_mission(TEXT, str(LANES))
    run, tracks = flown(compiled, FleetConfig.empty())
    leg = next(r for r in run.drones["Drone1"].actions if r.action == "FlyByX")
    doc = json.loads(json.dumps(snapshot_at(compiled, run, tracks, (leg.start + leg.end) / 2)))
    return compiled, doc


def judge(flying: tuple[Any, dict[str, Any]], text: str, force: bool = False) -> Any:
    compiled, doc = flying
    new = compile_mission(text, str(LANES))
    return check_amendment(compiled.programs, new, doc, FleetConfig.empty(), force=force)


def test_a_change_to_two_drones_later_parts_is_accepted_and_touches_only_them(flying):
    report = judge(flying, amended(*LATER_PARTS))
    assert report.accepted, report.lines("four_lanes.go")
    assert report.touched == ["Drone3", "Drone4"]
    running = flying[0].programs
    for drone in ("GCS", "Drone1", "Drone2"):  # node for node what they run
        assert report.amended.programs[drone].nodes == running[drone].nodes
        assert report.amended.programs[drone].arcs == running[drone].arcs
    d3, d4 = report.changes["Drone3"], report.changes["Drone4"]
    # By place: Drone3's second FlyByX of its lane changes, a third is added.
    assert [n.label for n in d3.changed] == ["FlyByX(-6)"]
    assert [n.label for n in d3.added] == ["FlyByX(-6)"] and not d3.removed
    assert [n.label for n in d4.added] == ["FlyByZ(1)"] and not d4.removed
    # Drone3 switches at its first new leg; Drone4 at its climb, not at its first leg.
    assert d3.switch is not None and d3.switch.label == "FlyByX(-6)"
    assert d4.switch is not None and d4.switch.label == "FlyByZ(1)"
    text = amended(*LATER_PARTS)
    assert d4.switch.line == line_of(text, "Drone4.FlyByZ(1)")
    # Every node of the running programs the amendment keeps has the same key.
    kept = {n.key for n in running["Drone4"].nodes}
    assert kept <= {n.key for n in report.amended.programs["Drone4"].nodes}
    assert report.amended.mission_id == flying[0].mission_id
    assert report.check is not None and report.check.ok
    assert report.lines("x.go")[-1] == "accepted"
    assert report.lines("x.go")[0].endswith("(pause):")  # the snapshot it was judged on


def test_an_amendment_that_makes_two_drones_meet_is_refused_with_the_located_finding(flying):
    text = amended(*HEAD_ON)
    report = judge(flying, text)
    assert not report.accepted
    assert report.check is not None and not report.check.ok
    separation = [f for f in report.check.errors if f.check == "separation"]
    assert separation, report.lines("x.go")
    lines = {p.line for f in separation for p in f.places}
    assert {line_of(text, "Drone1.FlyByY(5)"), line_of(text, "Drone2.FlyByY(-5)")} <= lines
    assert "finds" in report.refusals[-1].reason and "--force" in report.refusals[-1].reason
    rendered = "\n".join(report.lines("four_lanes.go"))
    assert f"four_lanes.go:{line_of(text, 'Drone1.FlyByY(5)')}:" in rendered
    # Forced, it is accepted all the same, and says so.
    forced = judge(flying, text, force=True)
    assert forced.accepted and forced.forced
    assert "forced" in forced.lines("x.go")[-1]


def test_an_amendment_that_touches_a_running_node_is_refused_with_the_node_named(flying):
    report = judge(flying, amended(*RUNNING_LEG))
    assert not report.accepted
    assert report.check is None  # refused before any check: nothing to fly
    [refusal] = report.refusals
    assert refusal.node is not None and refusal.node.label == "FlyByX(12)"
    assert refusal.node.line == line_of(TEXT, "Drone1.FlyByX(12)")
    assert "Drone1:" in refusal.reason and "is running" in refusal.reason


def test_an_amendment_to_what_is_over_is_refused_too(flying):
    # Drone2's Takeoff has ended: changing it is refused, forced or not.
    report = judge(flying, amended(("\tDrone2.Takeoff(2)\n", "\tDrone2.Takeoff(3)\n")), True)
    assert not report.accepted
    [refusal] = report.refusals
    assert refusal.node is not None and refusal.node.label == "Takeoff(2)"
    assert "has ended (ok)" in refusal.reason


def test_an_amendment_keeps_the_fleet(flying):
    text = TEXT.replace("var Drone4 Quadcopter\n", "var Drone4 Quadcopter\nvar Drone5 Quadcopter\n")
    text = text.replace("\tSEQ_Lane4()\n", "\tSEQ_Lane4()\n\tDrone5.Arm()\n")
    report = judge(flying, text)
    assert not report.accepted
    assert "adds Drone5" in report.refusals[0].reason


def test_the_same_text_changes_nothing(flying):
    report = judge(flying, TEXT)
    assert report.accepted and report.touched == [] and report.check is None
    assert "changes no drone's program" in "\n".join(report.lines("x.go"))


def test_a_snapshot_of_another_mission_is_refused(flying):
    compiled, doc = flying
    other = dict(doc, mission_id="0123456789abcdef")
    with pytest.raises(SnapshotError, match="of mission 0123456789abcdef"):
        check_amendment(compiled.programs, compile_mission(TEXT, str(LANES)), other)


def test_the_report_as_json_names_what_changes(flying, tmp_path: Path):
    doc = judge(flying, amended(*LATER_PARTS)).to_json()
    assert doc["accepted"] and doc["touched"] == ["Drone3", "Drone4"]
    assert doc["changes"]["Drone4"]["added"][0]["label"] == "FlyByZ(1)"
    json.dumps(doc)  # plain data
