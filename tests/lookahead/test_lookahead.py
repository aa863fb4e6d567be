"""The live look-ahead's forecast and decisions (pure, in virtual time).

``missions/crossing.go``: Drone2 flies 40 m north across the line Drone1 later flies
20 m east.  At the speeds their type declares Drone2 is long past the crossing when
Drone1 gets there, and the pre-flight check passes; slowed to half its speed by a
disturbance the check cannot know (``configs/crossing_slow.toml``), Drone2 is at the
crossing when Drone1 is.  A snapshot of such a flight 4 s into Drone2's leg, with the
speed Drone2 was seen to hold, is enough for the look-ahead to predict the conflict
more than 10 s ahead, naming both drones and both lines; without that measured speed
it predicts nothing.
"""

from __future__ import annotations

import json
import sys
from typing import Any

import pytest

from eamos.check import check_mission
from eamos.check.lookahead import look_ahead
from eamos.compiler import compile_file
from eamos.config import ConfigError, FleetConfig
from eamos.ground.lookahead import news, to_hold
from tests.support.runs import MISSIONS, REPO

sys.path.insert(0, str(REPO / "scripts"))
from bench_continuation import snapshot_at
from bench_lookahead import flown

CROSSING = MISSIONS / "crossing.go"
SLOW = REPO / "configs" / "crossing_slow.toml"
#: How far into Drone2's leg the snapshot is taken (s).
INTO_LEG_S = 4.0


def line_of(text: str) -> str:
    """The line number of ``text`` in the mission."""
    lines = CROSSING.read_text().splitlines()
    return str(next(i for i, line in enumerate(lines, 1) if text in line))


def slow_flight() -> tuple[Any, FleetConfig, Any, dict[str, Any]]:
    """The crossing flown with Drone2's disturbance, in virtual time."""
    compiled = compile_file(CROSSING)
    fleet = FleetConfig.load(SLOW)
    assert fleet.hal_for("Drone2")["disturbance_speed_factor"] == 0.5
    slowed = {"Drone2": {"disturbance_speed_factor": 0.5}}
    run, tracks = flown(compiled, fleet, slowed)
    return compiled, fleet, run, tracks


def leg_of(run: Any, drone: str, action: str) -> Any:
    (leg,) = [r for r in run.drones[drone].actions if r.action == action]
    return leg


def test_the_preflight_check_passes_the_crossing_it_cannot_know_is_slowed() -> None:
    compiled = compile_file(CROSSING)
    report = check_mission(compiled, FleetConfig.load(SLOW))
    assert report.ok, report.lines()


def test_the_look_ahead_predicts_the_conflict_from_the_speed_drone2_was_seen_to_hold() -> None:
    compiled, fleet, run, tracks = slow_flight()
    leg = leg_of(run, "Drone2", "FlyByX")
    cross = leg_of(run, "Drone1", "FlyByY")
    t = leg.start + INTO_LEG_S
    doc = json.loads(json.dumps(snapshot_at(compiled, run, tracks, t)))
    (a, b) = (tracks["Drone2"].at(t - 1.0), tracks["Drone2"].at(t))
    doc["participants"]["Drone2"]["cruise_mps"] = abs(b[0] - a[0])  # what it held: 1 m/s
    ahead = look_ahead(compiled, fleet, doc)
    conflicts = [p for p in ahead.predictions if p.check == "separation"]
    assert conflicts, ahead
    first = conflicts[0]
    assert first.severity == "error" and set(first.drones) == {"Drone1", "Drone2"}
    lines = {line_of("Drone1.FlyByY(20)"), line_of("Drone2.FlyByX(40)")}
    assert {line.rsplit(":", 1)[1] for line in first.lines} == lines, first.lines
    # Foreseen at least 10 s ahead, within 2 s of when the flight really gets there.
    assert first.in_s is not None and first.in_s >= 10.0, first
    assert cross.start - t < first.in_s < cross.end - t + 2.0, (first.in_s, cross, t)
    assert ahead.speeds == {"Drone2": pytest.approx(1.0, abs=0.05)}
    assert ahead.end_in_s is not None and ahead.runs == 1 and ahead.cpu_s > 0
    # Without the measured speed it flies Drone2 as its type says: no conflict ahead.
    del doc["participants"]["Drone2"]["cruise_mps"]
    assert not [p for p in look_ahead(compiled, fleet, doc).predictions], "declared speeds"


def test_the_look_ahead_is_refused_another_missions_snapshot() -> None:
    compiled, fleet, run, tracks = slow_flight()
    doc = snapshot_at(compiled, run, tracks, 10.0)
    doc["mission_id"] = "sha256:another"
    with pytest.raises(ValueError, match="not the mission that flew"):
        look_ahead(compiled, fleet, doc)


def test_each_prediction_is_said_once_and_each_drone_held_once_within_the_horizon() -> None:
    far = {"check": "separation", "in_s": 30.0, "drones": ["Drone1", "Drone2"], "lines": ["m:3"]}
    near = {**far, "in_s": 11.5}
    said: set[str] = set()
    assert news(said, [far]) == [far]
    assert news(said, [near, far]) == []  # the same conflict, nearer: not said again
    held: set[str] = set()
    assert to_hold([far], 12.0, 0.2, held) == []
    assert [d for d, _ in to_hold([near], 12.0, 0.2, held)] == ["Drone1", "Drone2"]
    assert to_hold([near], 12.0, 0.2, held) == []  # held already
    battery = {**near, "check": "battery", "drones": ["Drone3"]}
    assert to_hold([battery], 12.0, 0.0, set()) == []  # only conflicts are held
    assert to_hold([near], 0.0, 0.0, set()) == []  # hold_before_s 0: never


def test_a_bad_look_ahead_table_is_refused_with_its_field(tmp_path: Any) -> None:
    path = tmp_path / "fleet.toml"
    path.write_text("[look_ahead]\nperiod_s = -1\n")
    with pytest.raises(ConfigError, match=r"look_ahead\.period_s"):
        FleetConfig.load(path)
    path.write_text("[look_ahead]\nhold_before_s = 10\n")
    with pytest.raises(ConfigError, match=r"needs look_ahead\.period_s"):
        FleetConfig.load(path)
    path.write_text("[look_ahead]\nperiod = 2\n")
    with pytest.raises(ConfigError, match="period"):
        FleetConfig.load(path)
