"""``eamos amend --apply`` on a flying mission (issue 31): four simulated drones, real processes.

The four-lane mission flies twice at the same speed-up: once as written, once with an
amendment applied while every drone flies its first leg (Drone3 splits its way back in
two, Drone4 climbs a metre before it).  The amended drones fly their new parts; Drone1
and Drone2, which the amendment does not touch, are told nothing and fly as in the run
without it: each of their actions takes the same time within 0.2 s.  Then the refusals
a drone itself makes: an amendment staged while Drone1 flew its first leg, applied once
Drone1's way back has begun, is refused by Drone1 with the node named, and nothing changes
on any drone.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

from eamos.check import FlyingMission
from eamos.compiler import compile_file
from eamos.ground.amend import changed_drones, read_programs
from eamos.ground.operator import send_command
from eamos.program.format import load_program
from tests.operator.runs import HERE, log_lines, start
from tests.support.four_lanes import LATER_PARTS, amended
from tests.support.runs import eamos

pytestmark = pytest.mark.e2e

LANES = HERE / "four_lanes.go"
SPEEDUP = 2
#: The untouched drones' actions take the time they take without the amendment (issue 31).
SAME_WITHIN_S = 0.2


def flown(tmp_path: Path, edit: Any = None) -> dict[str, Any]:
    """Fly the four lanes; ``edit(run)`` while every drone flies its first leg.  The summary."""
    run = start(tmp_path, LANES, speedup=SPEEDUP)
    try:
        for drone in ("Drone1", "Drone2", "Drone3", "Drone4"):
            run.wait_for(f"{drone} running   FlyByX(12)")
        if edit is not None:
            edit(run)
        assert run.finish(240) == 0, run.text()
    finally:
        run.kill()
    summary: dict[str, Any] = json.loads((tmp_path / "summary.json").read_text())
    assert summary["ok"], summary
    return summary


def actions(summary: dict[str, Any], drone: str) -> list[tuple[str, list[float], float]]:
    """(action, arguments, seconds it took) of each action ``drone`` flew, in order."""
    return [
        (a["action"], a["args"], a["end"] - a["start"]) for a in summary["drones"][drone]["actions"]
    ]


def test_an_applied_amendment_changes_only_the_drones_it_touches(tmp_path: Path) -> None:
    plain = flown(tmp_path / "plain")
    out: dict[str, Any] = {}

    def amend(run: Any) -> None:
        mission = tmp_path / "later.go"
        mission.write_text(amended(*LATER_PARTS))
        proc = eamos("amend", str(run.run_dir), str(mission), "--apply", "--json", timeout=120)
        assert "Traceback" not in proc.stderr, proc.stderr
        assert proc.returncode == 0, proc.stdout + proc.stderr
        out.update(json.loads(proc.stdout), run_dir=run.run_dir)

    changed = flown(tmp_path / "amended", amend)
    assert out["applied"] is True and out["touched"] == ["Drone3", "Drone4"], out
    run_dir: Path = out["run_dir"]
    # The changed drones flew their new parts.
    assert [(a, g) for a, g, _ in actions(changed, "Drone3")][2:] == [
        ("FlyByX", [12.0]),
        ("FlyByX", [-6.0]),
        ("FlyByX", [-6.0]),
        ("Land", []),
    ]
    assert [(a, g) for a, g, _ in actions(changed, "Drone4")][2:] == [
        ("FlyByX", [12.0]),
        ("FlyByZ", [1.0]),
        ("FlyByX", [-12.0]),
        ("Land", []),
    ]
    # The others were told nothing and flew as without the amendment.
    largest = 0.0
    for drone in ("Drone1", "Drone2"):
        assert not log_lines(run_dir, drone, "mission", "mission.amendment"), drone
        before, after = actions(plain, drone), actions(changed, drone)
        assert [(a, g) for a, g, _ in after] == [(a, g) for a, g, _ in before]
        for (action, _, was), (_, _, now) in zip(before, after, strict=True):
            assert abs(now - was) <= SAME_WITHIN_S, (drone, action, was, now)
            largest = max(largest, abs(now - was))
    print(f"untouched drones: their actions' times differ by at most {largest:.3f} s")
    # Each changed drone took it in two phases, and the run folder holds what flies now.
    for drone in ("Drone3", "Drone4"):
        phases = [e["phase"] for e in log_lines(run_dir, drone, "mission", "mission.amendment")]
        assert phases == ["prepared", "committed"], (drone, phases)
        # A restart of its node would resume the amended program (its record names it).
        amended_program = load_program(
            run_dir / "amendments" / "1" / "programs" / f"{drone}.program.json"
        )
        record = json.loads((run_dir / "logs" / drone / "node-state.json").read_text())
        assert record["program"] == amended_program.checksum, (drone, record)
        # Its vehicle was told again how often the new program reads its samples.
        rates = log_lines(run_dir, drone, "adapter", "adapter.read_rate")
        assert len(rates) == 2, (drone, rates)
    for drone in ("Drone1", "Drone2"):
        assert len(log_lines(run_dir, drone, "adapter", "adapter.read_rate")) == 1, drone
    applied = json.loads((run_dir / "amendments" / "1" / "applied.json").read_text())
    assert applied["drones"] == ["Drone3", "Drone4"]
    staged = run_dir / "amendments" / "1" / "programs" / "Drone3.program.json"
    assert (run_dir / "programs" / "Drone3.program.json").read_text() == staged.read_text()
    # What the look-ahead forecasts from now on: the mission as it flies, amended.
    flying = FlyingMission(compile_file(LANES), run_dir).now()
    assert changed_drones(read_programs(run_dir / "programs"), flying.programs) == []


def test_a_drone_refuses_an_amendment_to_a_node_begun_since_it_was_judged(
    tmp_path: Path,
) -> None:
    later = (("\tDrone1.FlyByX(-12)\n", "\tDrone1.FlyByX(-10)\n"),)
    why: list[str] = []

    def stale(run: Any) -> None:
        mission = tmp_path / "later.go"
        mission.write_text(amended(*later))
        send_command(run.run_dir, "snapshot", "", "test")
        proc = eamos("amend", str(run.run_dir), str(mission), timeout=120)
        assert proc.returncode == 0, proc.stdout + proc.stderr  # staged, not applied
        run.wait_for("Drone1 running   FlyByX(-12)")
        proc = eamos("amend", str(run.run_dir), "--staged", "1", timeout=120)
        assert proc.returncode == 1, proc.stdout + proc.stderr
        why.append(proc.stdout)

    summary = flown(tmp_path / "run", stale)
    assert why[0].startswith("not applied: "), why
    assert "Drone1: n" in why[0] and "FlyByX(-12) has begun" in why[0], why
    assert "nothing changed" in why[0], why
    for drone, report in summary["drones"].items():
        legs = [a["args"] for a in report["actions"] if a["action"].startswith("FlyBy")]
        assert legs == [[12.0], [-12.0]], (drone, legs)
    assert not (tmp_path / "run" / "run" / "amendments" / "1" / "applied.json").exists()
