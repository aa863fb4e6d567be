"""A Try catches a low battery: below the fleet's reserve, a Body action fails and is caught.

missions/try_rescue.go with Drone1's battery draining 60 %/min in the air (fast_drain.toml):
Drone1's 30 m leg takes about 16 s, so its battery passes 85 % during it.  With a reserve of
85 % the leg fails ("battery ... below the reserve"), the Try catches it, Drone2's part of Body
is cancelled and PAR_Recover runs; with no reserve the same flight finishes its Body.
"""

from __future__ import annotations

import tomllib
from pathlib import Path

import pytest

from eamos.check import check_mission
from eamos.compiler import compile_file
from eamos.config import FleetConfig
from eamos.hal.sim.settings import SimSettings
from eamos.virtual import VirtualMission, sim_vehicles

REPO = Path(__file__).resolve().parents[2]
TRY_RESCUE = REPO / "missions" / "try_rescue.go"
FAST_DRAIN = Path(__file__).with_name("fast_drain.toml")


def _run(floor: float | None):  # type: ignore[no-untyped-def]
    doc = tomllib.loads(FAST_DRAIN.read_text())
    settings = {n: SimSettings.from_mapping(d["hal"]) for n, d in doc["drones"].items()}
    compiled = compile_file(TRY_RESCUE)
    return VirtualMission(compiled.programs, sim_vehicles(settings), battery_floor_pct=floor).run()


def test_a_battery_below_the_reserve_fails_the_body_action_and_the_try_catches_it() -> None:
    run = _run(85.0)
    assert run.ok, run.waiting
    d1 = run.drones["Drone1"].actions
    leg = next(a for a in d1 if a.action == "FlyByX")
    assert leg.result == "caught"
    assert "below the reserve of 85 %" in leg.reason
    assert "caught by the Try at line 16" in leg.reason
    # The leg stopped short of 30 m and OnFailure (FlyToXYZ home) ran on both drones.
    assert [a.action for a in d1][-3:] == ["FlyToXYZ", "Land", "Disarm"]
    d2 = [(a.action, a.result) for a in run.drones["Drone2"].actions]
    assert ("FlyToXYZ", "ok") in d2
    assert ("FlyByY", "ok") in d2 or ("FlyByY", "cancelled") in d2


def test_without_a_reserve_the_same_flight_finishes_its_body() -> None:
    run = _run(None)
    assert run.ok, run.waiting
    d1 = [(a.action, a.result) for a in run.drones["Drone1"].actions]
    assert ("FlyByX", "ok") in d1 and ("FlyByY", "ok") in d1
    assert all(a.action != "FlyToXYZ" for a in run.drones["Drone1"].actions)  # skipped


def test_the_pre_flight_check_flies_the_reserve_the_same_way(tmp_path: Path) -> None:
    fleet_file = tmp_path / "fleet.toml"
    fleet_file.write_text(FAST_DRAIN.read_text() + "\n[safety]\nbattery_reserve_pct = 85\n")
    compiled = compile_file(TRY_RESCUE)
    report = check_mission(compiled, FleetConfig.load(fleet_file), max_runs=1)
    # The first run is the one nothing was decided in: Drone1's leg hit the reserve and the
    # Try caught it, so the run ends normally, with OnFailure flown (longer than the Body).
    first = report.runs[0]
    plain = check_mission(compiled, FleetConfig.load(FAST_DRAIN), max_runs=1).runs[0]
    assert first.duration_s != pytest.approx(plain.duration_s, abs=0.5)
    assert not [f for f in report.findings if f.check in ("failed", "deadlock")]
