"""The ground station refuses the new actions and every plugin action; the fake runs them.

ReturnHome, Hold, Yaw, SetSpeed and Orbit are uniform actions, so every adapter gets
them; the ground station flies nothing and carries no payload, so they fail there at once,
with a reason naming the action.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from eamos.hal.api import ActionResult
from eamos.hal.fake import FakeAdapter
from eamos.hal.station_adapter import GroundAdapter, GroundSettings
from eamos.logs import close_logger, make_logger
from eamos.program.camera import CAMERA_PLUGINS
from eamos.program.plugins import PluginRegistry
from eamos.program.uniform import Command, Orbit, PluginAction, ReturnHome, decode_command

from .hal_helpers import Done, TelemetrySink

NEW = [
    ("ReturnHome", ()),
    ("Hold", (5.0,)),
    ("Yaw", (90.0,)),
    ("SetSpeed", (3.0,)),
    ("Orbit", (5.0, 1.0)),
]
PLUGIN = decode_command("TakePhoto", (), PluginRegistry(CAMERA_PLUGINS).specs())


def _do(adapter: GroundAdapter | FakeAdapter, command: Command) -> ActionResult:
    done = Done()
    adapter.run(command, done)
    return done.wait()


@pytest.mark.parametrize(
    "command", [decode_command(a, args) for a, args in NEW] + [PLUGIN], ids=lambda c: c.action
)
def test_the_ground_station_cannot(command: Command, tmp_path: Path) -> None:
    log = make_logger(tmp_path / "adapter.log", drone="GCS")
    ground = GroundAdapter("GCS", GroundSettings(speedup=10.0), log)
    try:
        ground.start(TelemetrySink())
        result = _do(ground, command)
        assert result == ActionResult("failed", f"the ground station cannot {command.action}")
        assert ground.family == "ground" and not ground.plugins.plugins
    finally:
        ground.close()
        close_logger(log)


def test_the_fake_runs_them_and_records_the_typed_commands() -> None:
    fake = FakeAdapter("D1", auto=True, plugins=PluginRegistry(CAMERA_PLUGINS))
    fake.start(TelemetrySink())
    for command in [ReturnHome(), Orbit(5.0, 2.0), PLUGIN]:
        assert _do(fake, command).ok
    commands = [c.command for c in fake.calls_of("run")]
    assert commands == [ReturnHome(), Orbit(5.0, 2.0), PluginAction("TakePhoto", (), ())]
    assert fake.family == "sim" and fake.plugins.implemented_by("sim") >= {"TakePhoto"}
