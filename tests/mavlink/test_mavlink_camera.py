"""TakePhoto, StartVideo, StopVideo and Gimbal on MAVLink, both autopilots (issue 13, item 2).

The project's camera plugins (eamos/program/camera.py) name their "mavlink" code in
eamos/hal/mavlink/camera.py; the adapter runs it through the payload seam
(eamos/hal/mavlink/payload.py).  The simulated vehicle answers the camera protocol
and gimbal v2 commands: CAMERA_IMAGE_CAPTURED with where the photo was taken,
GIMBAL_DEVICE_ATTITUDE_STATUS with the gimbal's pitch.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import pytest

from eamos.hal.mavlink.adapter import MavlinkAdapter
from eamos.hal.sitl import ACCEPTED, DENIED
from eamos.program.camera import CAMERA_PLUGINS
from eamos.program.plugins import ActionPlugin, PluginRegistry
from eamos.program.uniform import PluginAction

from .mavlink_helpers import Done, Flight

pytestmark = [pytest.mark.e2e, pytest.mark.timeout(240)]

AUTOPILOTS = ["px4", "ardupilot"]
IMAGE_START_CAPTURE, VIDEO_START, VIDEO_STOP, GIMBAL_PITCHYAW = 2000, 2500, 2501, 1000


def plugin(f: Flight, name: str, *values: float) -> Any:
    spec = f.adapter.plugins.get(name)
    assert spec is not None
    done = Done()
    f.adapter.run(PluginAction(name, spec.params, tuple(values)), done)
    return done.wait()


@pytest.fixture
def camera_flight(make_vehicle: Any, make_adapter: Any) -> Any:
    def factory(autopilot: str) -> Flight:
        sim, conn = make_vehicle(autopilot, speedup=5.0)
        adapter: MavlinkAdapter = make_adapter(conn)
        adapter.plugins = PluginRegistry(CAMERA_PLUGINS)
        return Flight.start(sim, adapter)

    return factory


def events(tmp_path: Path, name: str) -> list[dict[str, Any]]:
    lines = (tmp_path / "D1-adapter.log").read_text().splitlines()
    return [e for e in map(json.loads, lines) if e.get("event") == name]


@pytest.mark.parametrize("autopilot", AUTOPILOTS)
def test_photo_video_and_gimbal(camera_flight: Any, autopilot: str, tmp_path: Path) -> None:
    f = camera_flight(autopilot)
    f.airborne(2.0)
    f.ok("FlyByX", 3.0)
    assert plugin(f, "Gimbal", -45.0).ok
    assert plugin(f, "TakePhoto").ok
    assert plugin(f, "StartVideo").ok
    assert plugin(f, "StopVideo").ok
    commands = f.vehicle.commands
    for command in (GIMBAL_PITCHYAW, IMAGE_START_CAPTURE, VIDEO_START, VIDEO_STOP):
        assert (command, ACCEPTED) in commands, command
    photo = events(tmp_path, "adapter.photo")[0]
    # Where the vehicle took it (CAMERA_IMAGE_CAPTURED), and with the gimbal down 45 deg.
    assert photo["index"] == 0
    assert math.dist((photo["x_m"], photo["y_m"], photo["z_m"]), (3.0, 0.0, 2.0)) < 0.6
    assert photo["alt_m"] == pytest.approx(2.0, abs=0.6)
    assert photo["pitch_deg"] == pytest.approx(-45.0, abs=2.0)
    assert events(tmp_path, "adapter.gimbal")[0]["pitch_deg"] == -45.0


def test_a_refused_gimbal_command_and_a_missing_implementation_fail(
    camera_flight: Any,
) -> None:
    f = camera_flight("ardupilot")
    # Beyond the gimbal's travel: the vehicle refuses (the compiler's range would stop it
    # first in a mission; the adapter still reports the vehicle's answer).
    result = plugin(f, "Gimbal", -120.0)
    assert result.status == "failed"
    assert result.reason.startswith(
        "MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW rejected with MAV_RESULT_DENIED"
    )
    assert "Gimbal: pitch -120 outside -90..30" in result.reason
    assert (GIMBAL_PITCHYAW, DENIED) in f.vehicle.commands
    sim_only = ActionPlugin("Spray", (), "Spray.", {"sim": "eamos.hal.sim.camera:take_photo"})
    f.adapter.plugins = PluginRegistry([*CAMERA_PLUGINS, sim_only])
    result = plugin(f, "Spray")
    assert result.status == "failed" and "'mavlink'" in result.reason, result
