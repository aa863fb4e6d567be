"""ReturnHome, Yaw, SetSpeed, Orbit and Hold flown by ``eamos run`` on MAVLink drones.

A hybrid fleet: Drone1 is a MAVLink drone on a simulated autopilot (PX4 or
ArduCopter personality) that ``eamos run`` starts itself.  The mission flies each
new uniform action once; the vehicle's own log shows the modes and commands each
autopilot was given (eamos/hal/mavlink/manoeuvres.py: everything in the motion mode,
then the autopilot's LAND), and the summary where the drone ended: back home, landed
and disarmed.  The real autopilots fly the same in tests/sitl/test_sitl_actions.py.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tests.support.runs import run_mission

pytestmark = [pytest.mark.e2e, pytest.mark.timeout(400)]

MISSION = """\
package Manoeuvres

var Drone1 Quadcopter

func SEQ_Main() {
	Drone1.Arm()
	Drone1.Takeoff(2)
	Drone1.FlyByX(3)
	Drone1.Yaw(90)
	Drone1.SetSpeed(1)
	Drone1.Orbit(2, 1)
	Drone1.Hold(2)
	Drone1.ReturnHome()
	Drone1.Disarm()
}
"""

FLEET = """\
[drones.Drone1.hal]
adapter = "mavlink"
sim_vehicle = {{ autopilot = "{autopilot}", prearm_delay_s = 2 }}
connect_timeout_s = 30
armable_timeout_s = 90
"""

#: The modes each autopilot flew, in order (from the motion mode of the take-off): it
#: stays there (Hold, Orbit and ReturnHome steered by the adapter) until it lands.
MODES = {
    "px4": ["OFFBOARD", "AUTO.LAND"],
    "ardupilot": ["GUIDED", "LAND"],
}
#: MAV_CMD numbers each autopilot must have accepted: NAV_LAND (and ArduCopter's
#: DO_CHANGE_SPEED); never RTL, DO_ORBIT or CONDITION_YAW.
COMMANDS = {"px4": {21}, "ardupilot": {21, 178}}


@pytest.mark.parametrize("autopilot", ["px4", "ardupilot"])
def test_new_actions_through_eamos_run(tmp_path: Path, autopilot: str) -> None:
    mission = tmp_path / "manoeuvres.go"
    mission.write_text(MISSION)
    fleet = tmp_path / "fleet.toml"
    fleet.write_text(FLEET.format(autopilot=autopilot))
    proc, summary = run_mission(
        tmp_path, mission, "--fleet", str(fleet), speedup=4, timeout_s=300, process_timeout_s=360
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
    report = summary["drones"]["Drone1"]
    assert report["ok"] and all(a["result"] == "ok" for a in report["actions"]), report
    final = report["final"]
    assert abs(final["x"]) < 0.6 and abs(final["y"]) < 0.6, final
    assert final["z"] == pytest.approx(0.0, abs=0.15) and not final["armed"], final
    log = Path(summary["run_dir"]) / "logs" / "Drone1" / "sim-vehicle.log"
    events = [json.loads(line) for line in log.read_text().splitlines() if line.strip()]
    modes = [e["mode"] for e in events if e.get("event") == "vehicle.mode"]
    flown = modes[modes.index(MODES[autopilot][0]) :]
    assert flown[: len(MODES[autopilot])] == MODES[autopilot], modes
    accepted = {e["command"] for e in events if e.get("event") == "vehicle.command"}
    accepted_ok = {
        e["command"] for e in events if e.get("event") == "vehicle.command" and e["result"] == 0
    }
    assert COMMANDS[autopilot] <= accepted_ok, sorted(accepted)
    assert not {20, 34, 115} & accepted, sorted(accepted)


CAMERA_MISSION = """\
package Camera

type Inspector interface {
	Quadcopter
	TakePhoto()
	Gimbal(pitch_deg float64)
}

var Drone1 Inspector

func SEQ_Main() {
	Drone1.Arm()
	Drone1.Takeoff(2)
	Drone1.FlyByX(3)
	Drone1.Gimbal(-45)
	Drone1.TakePhoto()
	Drone1.Land()
	Drone1.Disarm()
}
"""


@pytest.mark.parametrize("autopilot", ["px4", "ardupilot"])
def test_camera_plugins_through_eamos_run(tmp_path: Path, autopilot: str) -> None:
    """The project's camera plugins (entry points) on a MAVLink drone: the photo's place."""
    mission = tmp_path / "camera.go"
    mission.write_text(CAMERA_MISSION)
    fleet = tmp_path / "fleet.toml"
    fleet.write_text(FLEET.format(autopilot=autopilot))
    proc, summary = run_mission(
        tmp_path, mission, "--fleet", str(fleet), speedup=4, timeout_s=300, process_timeout_s=360
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert summary["drones"]["Drone1"]["ok"]
    log = Path(summary["run_dir"]) / "logs" / "Drone1" / "adapter.log"
    events = [json.loads(line) for line in log.read_text().splitlines() if line.strip()]
    photo = next(e for e in events if e.get("event") == "adapter.photo")
    assert (photo["x_m"], photo["y_m"], photo["z_m"]) == pytest.approx((3.0, 0.0, 2.0), abs=0.6)
    assert photo["pitch_deg"] == pytest.approx(-45.0, abs=2.0)
