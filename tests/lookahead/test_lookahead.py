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
from eamos.check.lookahead import look_ahead, measured_drains, measured_speeds
from eamos.compiler import compile_file
from eamos.config import ConfigError, FleetConfig
from eamos.ground.lookahead import news, to_hold
from tests.support.runs import MISSIONS, REPO

sys.path.insert(0, str(REPO / "scripts"))
from bench_continuation import snapshot_at
from bench_lookahead import flown

CROSSING = MISSIONS / "crossing.go"
SLOW = REPO / "configs" / "crossing_slow.toml"
COLD = REPO / "configs" / "crossing_cold.toml"
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
    legs = {n.key for p in compiled.programs.values() for n in p.nodes
            if n.native and n.label in ("FlyByY(20)", "FlyByX(40)")}  # fmt: skip
    assert set(first.nodes) == legs and first.to_json()["nodes"] == list(first.nodes)
    # Foreseen at least 10 s ahead, within 2 s of when the flight really gets there.
    assert first.in_s is not None and first.in_s >= 10.0, first
    assert cross.start - t < first.in_s < cross.end - t + 2.0, (first.in_s, cross, t)
    assert ahead.speeds == {"Drone2": pytest.approx(1.0, abs=0.05)}
    # The same speed measured on the wall clock of a run at speed-up 3: 3 m/s of wall time.
    wall = json.loads(json.dumps(doc))
    wall["participants"]["Drone2"]["cruise_mps"] *= 3
    assert measured_speeds(wall, fleet, ["Drone2"]) == {}  # faster than declared: not slowed
    assert measured_speeds(wall, fleet, ["Drone2"], {"Drone2": 3.0}) == ahead.speeds
    assert ahead.end_in_s is not None and ahead.runs == 1 and ahead.cpu_s > 0
    # Without the measured speed it flies Drone2 as its type says: no conflict ahead.
    del doc["participants"]["Drone2"]["cruise_mps"]
    assert not [p for p in look_ahead(compiled, fleet, doc).predictions], "declared speeds"


def test_the_look_ahead_predicts_the_reserve_from_the_drain_drone2_was_seen_to_have() -> None:
    compiled = compile_file(CROSSING)
    fleet = FleetConfig.load(COLD)
    assert fleet.hal_for("Drone2")["disturbance_drain_factor"] == 6.0
    assert check_mission(compiled, fleet).ok  # the check cannot know the cold battery
    run, tracks = flown(compiled, fleet, {"Drone2": {"disturbance_drain_factor": 6.0}})
    leg = leg_of(run, "Drone2", "FlyByX")
    takeoff = leg_of(run, "Drone2", "Takeoff")
    t = leg.start + 14.0
    doc = json.loads(json.dumps(snapshot_at(compiled, run, tracks, t)))
    # What the ground station's telemetry tally shows by then: seconds, metres, climb, and
    # six times the battery the model would have used over them.
    seconds, metres, climbed = t - takeoff.start, 28.0, 3.0
    modelled = (4.0 * seconds + 0.5 * metres + 2.0 * climbed) / 60.0
    part = doc["participants"]["Drone2"]
    part["flown"] = {"s": seconds, "m": metres, "climbed_m": climbed,
                     "battery_used_pct": 6.0 * modelled}  # fmt: skip
    part["vehicle"]["battery"] = 100.0 - 6.0 * modelled
    ahead = look_ahead(compiled, fleet, doc)
    assert ahead.drains == {"Drone2": pytest.approx(6.0, rel=0.01)}
    [battery] = [p for p in ahead.predictions if p.check == "battery"]
    assert battery.drones == ("Drone2",) and battery.severity == "error"
    assert "below the reserve of 90 %" in battery.message
    assert ahead.to_json()["drain_factors"] == {"Drone2": 6.0}
    # Measured on the wall clock of a run at speed-up 2: half the seconds, the same drain.
    wall = json.loads(json.dumps(doc))
    wall["participants"]["Drone2"]["flown"]["s"] = seconds / 2
    assert measured_drains(wall, fleet, ["Drone2"]) != ahead.drains
    assert measured_drains(wall, fleet, ["Drone2"], {"Drone2": 2.0}) == {
        "Drone2": pytest.approx(6.0, rel=0.01)
    }
    # Drained as its model says, it lands above the reserve: nothing predicted.
    part["flown"]["battery_used_pct"] = modelled
    part["vehicle"]["battery"] = 100.0 - modelled
    calm = look_ahead(compiled, fleet, doc)
    assert calm.drains == {} and not calm.predictions
    # Too little flown to tell (under 1 % by the model): not measured.
    part["flown"] = {"s": 5.0, "m": 2.0, "climbed_m": 3.0, "battery_used_pct": 5.0}
    assert look_ahead(compiled, fleet, doc).drains == {}


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
