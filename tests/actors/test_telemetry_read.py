"""telemetry_read_hz: how often a drone's own samples are read, from its program (pure)."""

from __future__ import annotations

from pathlib import Path

from eamos.actors.wiring import telemetry_read_hz
from eamos.compiler import compile_file
from eamos.net.settings import LinkSettings

REPO = Path(__file__).resolve().parents[2]
LINK = LinkSettings(telemetry_max_hz=2.0)


def test_a_drone_whose_own_conditions_read_it_reads_its_samples_as_they_come() -> None:
    programs = dict(compile_file(REPO / "missions" / "whenever_battery.go").programs)
    # Drone1's Whenever reads Drone1's battery and position: every sample, on board.
    assert telemetry_read_hz(programs["Drone1"], LINK, None) is None
    # Drone2 reads nobody's properties: its samples leave at the link's rate, no faster.
    assert telemetry_read_hz(programs["Drone2"], LINK, None) == 2.0


def test_a_battery_floor_reads_every_sample() -> None:
    programs = dict(compile_file(REPO / "missions" / "whenever_battery.go").programs)
    # A Try's Body fails below the floor: the battery is read on board as it drains.
    assert telemetry_read_hz(programs["Drone2"], LINK, 20.0) is None
