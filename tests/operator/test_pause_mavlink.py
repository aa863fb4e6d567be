"""Pause and resume MAVLink drones mid-move (issue 30): simulated PX4 and ArduCopter
autopilots (``eamos-sim-vehicle``), real processes, real MAVLink bytes.

Both drones fly a 20 m leg at once; ``eamos pause`` mid-leg: each adapter brakes and
holds (the leg is suspended, not cancelled); ``eamos resume`` 6 s later: each leg goes
on to its original end (the drones land there), and the mission ends ok.
"""

from __future__ import annotations

import time
from pathlib import Path

import pytest

from tests.operator.runs import (
    HERE,
    distance,
    log_lines,
    operator,
    positions,
    resume_to_the_end,
    start,
)

pytestmark = pytest.mark.e2e

PAUSE_S = 6.0
SETTLE_S = 3.0  # braking, then the hold
HOLD_M = 0.5


def test_mavlink_drones_hold_mid_leg_and_go_on_to_its_end(tmp_path: Path) -> None:
    fleet = ("--fleet", str(HERE / "mavlink_fleet.toml"))
    run = start(tmp_path, HERE / "long_legs.go", speedup=1, extra=fleet)
    try:
        run.wait_for("Drone2 running   FlyByY(20)")
        run.wait_for("Drone1 running   FlyByX(20)")
        operator("pause", str(run.run_dir))
        time.sleep(PAUSE_S)
        summary = resume_to_the_end(run, tmp_path)
    finally:
        run.kill()
    for drone, axis in (("Drone1", "x"), ("Drone2", "y")):
        actions = summary["drones"][drone]["actions"]
        assert [a["action"] for a in actions] == ["Arm", "Takeoff", f"FlyBy{axis.upper()}", "Land"]
        suspended = log_lines(run.run_dir, drone, "uniform", "uniform.suspend")
        assert [s["actions"] for s in suspended] == [1], drone  # the leg, mid-way
        resumed = log_lines(run.run_dir, drone, "uniform", "uniform.resume")
        assert [r["issued"] for r in resumed] == ["FlyToXYZ"], drone
        heard = log_lines(run.run_dir, drone, "mission", "mission.operator")
        paused_at, resumed_at = heard[0]["ts"], heard[1]["ts"]
        # Logged while it moves: where it was once braked, then any line of the hold.
        track = positions(run.run_dir, drone)
        braked = [p for p in track if p[0] <= paused_at + SETTLE_S]
        held = braked[-1:] + [p for p in track if paused_at + SETTLE_S < p[0] <= resumed_at]
        assert held, drone
        spread = max(distance(held[0], p) for p in held)
        assert spread <= HOLD_M, f"{drone} moved {spread:.2f} m while paused"
        final = summary["drones"][drone]["final"]
        assert abs(final[axis] - 20.0) < 1.0, (drone, final)  # the leg's original end
        assert final["landed"], final
