"""DoUntil brakes a MAVLink drone through ``eamos run`` (issue 16, item 1, end to end).

``DoUntil(Drone1.X() > 5, SEQ_Long)`` with ``SEQ_Long`` = ``FlyByX(20); FlyByY(20)``,
flown by ``eamos run`` on a hybrid fleet: Drone1 is a MAVLink drone on a simulated
autopilot (``eamos-sim-vehicle``, PX4 or ArduCopter personality), started by the
run itself.  Before issue 16 the drone touched down at x = 15.2 m (ArduCopter) and
19.4 m (PX4) on the real SITLs; the ``sim`` adapter stops at 5.06 m.

The stated bound: the drone type's horizontal speed ``v`` (``hal.horizontal_speed_mps``,
2 m/s, set on the vehicle by the adapter) times the reaction time, plus the
braking distance ``v^2 / (2 a)`` the adapter's brake plans with (a position target at
the stopping point, a = 2.5 m/s/s on both), plus the completion tolerance.  The
reaction time is the telemetry period (10 Hz: 0.1 s), the way through the node's
runtime to the cancel and the command's way: 0.3 s of vehicle time, plus 0.25 s of
wall time (a loaded machine) scaled by the vehicle's clock (speed-up 2): 0.8 s.
So either may touch down up to 3.0 m past x = 5 (before: 14.4 m).
"""

from __future__ import annotations

from pathlib import Path

import pytest

from eamos.hal.mavlink.autopilots import autopilot_named
from eamos.hal.sitl.core import LAND_DECEL_MPS2
from tests.support.runs import run_mission

pytestmark = [pytest.mark.e2e, pytest.mark.timeout(400)]

SPEEDUP = 2.0
SPEED_MPS = 2.0
LIMIT_X_M = 5.0
STOP_DECEL = {name: autopilot_named(name).brake_decel_mps2 for name in ("px4", "ardupilot")}
TOLERANCE_M = {"px4": 0.6, "ardupilot": 0.6}
REACTION_S = 0.3 + 0.25 * SPEEDUP

MISSION = """\
package Braking

var Drone1 Quadcopter

func SEQ_Main() {
	Drone1.Arm()
	Drone1.Takeoff(2)
	DoUntil(Drone1.X() > 5, SEQ_Long)
	Drone1.Land()
	Drone1.Disarm()
}

func SEQ_Long() {
	Drone1.FlyByX(20)
	Drone1.FlyByY(20)
}
"""

FLEET = """\
[drones.Drone1.hal]
adapter = "mavlink"
sim_vehicle = {{ autopilot = "{autopilot}", prearm_delay_s = 2 }}
horizontal_speed_mps = {speed}
connect_timeout_s = 30
armable_timeout_s = 90
"""


def braking_bound_m(autopilot: str, speed: float = SPEED_MPS) -> float:
    """How far past the limit the drone may touch down (see the module docstring)."""
    return speed * REACTION_S + speed**2 / (2 * STOP_DECEL[autopilot]) + TOLERANCE_M[autopilot]


def test_the_bound_is_far_below_what_landing_at_speed_would_give() -> None:
    for autopilot in STOP_DECEL:
        # LAND alone brakes at LAND_DECEL_MPS2; at the autopilots' own cruise speeds
        # (5 and 6 m/s) that was 10 and 14 m on the real SITLs.
        assert braking_bound_m(autopilot) <= 3.0 + 1e-9
        assert braking_bound_m(autopilot) < 5.0**2 / (2 * LAND_DECEL_MPS2)


@pytest.mark.parametrize("autopilot", ["px4", "ardupilot"])
def test_do_until_brakes_a_mavlink_drone_through_eamos_run(tmp_path: Path, autopilot: str) -> None:
    mission = tmp_path / "braking.go"
    mission.write_text(MISSION)
    fleet = tmp_path / "fleet.toml"
    fleet.write_text(FLEET.format(autopilot=autopilot, speed=SPEED_MPS))
    proc, summary = run_mission(
        tmp_path,
        mission,
        "--fleet",
        str(fleet),
        speedup=SPEEDUP,
        timeout_s=300,
        process_timeout_s=360,
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
    report = summary["drones"]["Drone1"]
    assert report["ok"], report
    results = {a["action"]: a["result"] for a in report["actions"]}
    assert results["FlyByX"] == "cancelled", report["actions"]
    assert "FlyByY" not in results  # the rest of the body never ran
    final = report["final"]
    bound = braking_bound_m(autopilot)
    assert LIMIT_X_M <= final["x"] <= LIMIT_X_M + bound, (final, bound)
    assert abs(final["y"]) < TOLERANCE_M[autopilot], final
    assert final["z"] == pytest.approx(0.0, abs=0.15) and not final["armed"], final
    adapter_log = (Path(summary["run_dir"]) / "logs" / "Drone1" / "adapter.log").read_text()
    assert '"event": "adapter.brake"' in adapter_log
    print(f"{autopilot}: touched down at x = {final['x']:.2f} m (bound {LIMIT_X_M + bound:.2f})")
