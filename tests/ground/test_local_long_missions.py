"""A long mission's final report still reaches the ground station (issue 17, long missions).

A drone with 15 000 actions made a report of 1.38 MB, over the 1 MiB wire limit:
``WireError`` and "0 actions".  The report now lists the newest actions within
``LISTED_ACTIONS_MAX_BYTES`` and folds the oldest into counts, said in words.
"""

from __future__ import annotations

import json
from pathlib import Path

from eamos.actors.report import (
    LISTED_ACTIONS_MAX,
    LISTED_ACTIONS_MAX_BYTES,
    LISTED_BLOCKED_MAX,
    ActionEntry,
    DroneReport,
    fold_actions,
)
from eamos.compiler import compile_mission
from eamos.net import wire
from eamos.virtual import run_virtual

ACTIONS = 20_000

LONG = f"""\
// {ACTIONS} actions on one drone: a loop of pauses.
func SEQ_Long() {{
	Drone1.Arm()
	RepeatFor({ACTIONS - 2}, SEQ_Step)
	Drone1.Disarm()
}}

func SEQ_Step() {{
	Drone1.PauseFor(0.001)
}}
"""


def _report(actions: tuple[ActionEntry, ...], blocked: tuple[str, ...] = ()) -> DroneReport:
    return DroneReport(
        ok=True,
        resolved=True,
        aborted=False,
        abort_reason="",
        triggers_sent=1,
        triggers_received=1,
        external_out=1,
        external_in=1,
        mdg={"nodes": 3},
        blocked_nodes=blocked,
        actions=actions,
        final=None,
    )


def _over_the_wire(report: DroneReport) -> DroneReport:
    frames = wire.encode(wire.Report(mission="m", sender="Drone1", report=report.to_json()))
    assert len(frames[-1]) <= wire.MAX_PAYLOAD_BYTES
    message = wire.decode(frames)
    assert isinstance(message, wire.Report)
    return DroneReport.from_json(message.report)


def test_a_report_of_20000_actions_flown_in_virtual_time_fits_one_wire_message() -> None:
    compiled = compile_mission(LONG, "long.go")
    run = run_virtual(compiled.programs)
    records = run.drones["Drone1"].actions
    assert len(records) == ACTIONS
    report = _report(tuple(ActionEntry.of(r) for r in records))
    received = _over_the_wire(report)
    assert received.action_count == ACTIONS
    assert received.folded is not None and received.folded.count == ACTIONS - len(received.actions)
    assert received.folded.ok == received.folded.count
    assert received.actions[-1] == report.actions[-1]  # the newest are listed, exactly
    assert received.actions == report.actions[-len(received.actions) :]
    assert received.folded.first_start == report.actions[0].start
    # Said plainly where a reader of summary.json looks.
    note = received.to_json()["actions_folded"]["note"]
    assert f"the {received.folded.count} oldest actions are counted here" in note
    assert "uniform.log" in note
    # Reading back and writing again changes nothing (the summary writes what came in).
    assert DroneReport.from_json(received.to_json()) == received


def _entries(n: int, node: str = "SEQ_Step") -> tuple[ActionEntry, ...]:
    return tuple(
        ActionEntry(node, "PauseFor", (0.001,), (i,), float(i), i + 0.5, "ok") for i in range(n)
    )


def test_a_short_report_keeps_the_first_versions_keys() -> None:
    report = _report(_entries(50))
    data = report.to_json()
    assert "actions_folded" not in data and "blocked_nodes_more" not in data
    assert DroneReport.from_json(data) == report
    assert report.action_count == 50


def test_the_listed_actions_are_bounded_in_bytes_and_count() -> None:
    wide = _entries(3_000, node="N" * 400)
    listed, folded = fold_actions(wide)
    assert len(json.dumps(listed)) <= LISTED_ACTIONS_MAX_BYTES + 2 * len(listed)
    assert folded is not None and folded.count + len(listed) == 3_000
    small = tuple(
        ActionEntry("n", "Arm", (), (), float(i), float(i), "ok")
        for i in range(LISTED_ACTIONS_MAX + 10)
    )
    listed, folded = fold_actions(small)
    assert len(listed) <= LISTED_ACTIONS_MAX and folded is not None
    assert folded.count == LISTED_ACTIONS_MAX + 10 - len(listed)


def test_failed_and_cancelled_actions_are_counted_when_folded() -> None:
    mixed = tuple(
        ActionEntry("N" * 300, "FlyByX", (1.0,), (i,), float(i), i + 1.0, result)
        for i, result in enumerate(["ok", "failed", "cancelled"] * 2_000)
    )
    received = _over_the_wire(_report(mixed))
    assert received.folded is not None
    listed = [a.result for a in received.actions]
    assert received.folded.failed + listed.count("failed") == 2_000
    assert received.folded.cancelled + listed.count("cancelled") == 2_000


def test_many_blocked_nodes_are_counted_not_all_named() -> None:
    blocked = tuple(f"node{i:05d}" + "x" * 60 for i in range(30_000))
    received = _over_the_wire(_report(_entries(10), blocked))
    assert len(received.blocked_nodes) == LISTED_BLOCKED_MAX
    assert received.blocked_nodes_more == 30_000 - LISTED_BLOCKED_MAX


def test_a_report_json_file_stays_readable_at_any_length(tmp_path: Path) -> None:
    # drone.py writes report.json from to_json() (folded); the wire carries every
    # action, in parts when needed (test_local_report_parts.py).
    report = _report(_entries(20_000))
    path = tmp_path / "report.json"
    path.write_text(json.dumps(report.to_json()))
    assert DroneReport.from_json(json.loads(path.read_text())).action_count == 20_000
