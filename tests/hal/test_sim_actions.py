"""SimCore runs ReturnHome, Hold, Yaw, SetSpeed, Orbit and plugin actions (pure, stepped by hand).

Positions, heading, timing and battery are read from the core after each step: simulated
times are exact, no thread and no clock.
"""

from __future__ import annotations

import math
from typing import Any

import pytest

from eamos.hal.sim.core import SIM_DT_S, SimCore
from eamos.hal.sim.motions import YAW_RATE_DEG_S, orbit_speed_mps, turn_towards
from eamos.hal.sim.plugin_api import SimOutcome, SimView
from eamos.hal.sim.settings import SimSettings
from eamos.program.camera import CAMERA_PLUGINS
from eamos.program.plugins import ActionPlugin, PluginRegistry
from eamos.program.uniform import (
    FlyBy,
    FlyToXYZ,
    Hold,
    Orbit,
    PluginAction,
    ReturnHome,
    SetSpeed,
    Yaw,
    decode_command,
)

from .test_hal_sim_core import EventLog, Results, Rig


class PluginRig(Rig):
    """A started core knowing ``plugins`` (the camera's by default)."""

    def __init__(self, plugins: PluginRegistry | None = None, **settings: Any) -> None:
        self.log = EventLog()
        self.now = 1_000.0
        self.plugins = plugins or PluginRegistry(CAMERA_PLUGINS)
        self.core = SimCore(
            "D1", SimSettings(**settings), self.log, clock=lambda: self.now, plugins=self.plugins
        )
        self.first = self.core.start()
        self.results = Results()
        self.samples = [self.first]

    def plugin(self, name: str, action: str, *args: float) -> Any:
        command = decode_command(action, args, self.plugins.specs())
        assert isinstance(command, PluginAction)
        return self.do(name, command)

    def track(self, name: str, max_s: float = 600.0) -> list[tuple[float, float, float, float]]:
        """Step until ``name`` finished, recording (t, x, y, z) after every step."""
        out: list[tuple[float, float, float, float]] = []
        for _ in range(round(max_s / SIM_DT_S)):
            if name in self.results.got:
                return out
            self.step()
            x, y, z, *_ = self.core.where()
            out.append((self.core.t_s, x, y, z))
        raise AssertionError(f"{name} not finished")


def test_yaw_turns_the_shorter_way_at_its_rate_and_stays_in_place() -> None:
    rig = PluginRig()
    rig.airborne(5.0)
    x0, y0, _z0, *_ = rig.core.where()
    t0 = rig.core.t_s
    assert rig.do("yaw", Yaw(90.0)).ok
    assert rig.core.heading_deg == 90.0
    assert rig.core.t_s - t0 == pytest.approx(90.0 / YAW_RATE_DEG_S, abs=2 * SIM_DT_S)
    assert math.dist(rig.core.where()[:3], (x0, y0, 5.0)) < 1e-6  # settled on the spot
    # 90 -> 0 turns back through 45 (not through 180); 0 -> 270 through 315.
    rig.run("back", Yaw(0.0))
    seen = []
    while "back" not in rig.results.got:
        rig.step()
        seen.append(rig.core.heading_deg)
    assert max(seen) <= 90.0 and rig.core.heading_deg == 0.0
    assert turn_towards(0.0, 270.0, 10.0) == 350.0
    assert turn_towards(355.0, 5.0, 20.0) == 5.0


def test_setspeed_limits_later_horizontal_moves() -> None:
    rig = PluginRig()
    rig.airborne(5.0)
    assert rig.do("speed", SetSpeed(0.5)).ok
    t0 = rig.core.t_s
    rig.run("fly", FlyBy("X", 10.0))
    fastest = 0.0
    while "fly" not in rig.results.got:
        rig.step()
        fastest = max(fastest, rig.core.state().horizontal_speed_mps)
    assert rig.results.got["fly"].ok
    assert fastest == pytest.approx(0.5, abs=1e-6)
    assert rig.core.t_s - t0 >= 10.0 / 0.5
    assert not rig.do("zero", SetSpeed(0.0)).ok


def test_hold_hovers_for_its_duration_and_needs_the_air() -> None:
    rig = PluginRig()
    result = rig.do("ground", Hold(1.0))
    assert (result.status, result.reason) == ("failed", "not flying")
    rig.airborne(5.0)
    t0 = rig.core.t_s
    battery = rig.core.where()[5]
    assert rig.do("hold", Hold(3.0)).ok
    assert rig.core.t_s - t0 == pytest.approx(3.0, abs=2 * SIM_DT_S)
    assert math.dist(rig.core.where()[:3], (0.0, 0.0, 5.0)) < 1e-6
    assert rig.core.where()[5] < battery  # hovering drains the battery


def test_orbit_circles_clockwise_around_the_point_ahead_and_ends_where_it_started() -> None:
    rig = PluginRig()
    rig.airborne(5.0)
    assert rig.do("face east", Yaw(90.0)).ok
    start = rig.core.where()[:3]
    battery = rig.core.where()[5]
    t0 = rig.core.t_s
    rig.run("orbit", Orbit(4.0, 1.0))
    track = rig.track("orbit")
    assert rig.results.got["orbit"].ok
    centre = (start[0], start[1] + 4.0)  # ahead along heading 90: east
    radii = [math.dist((x, y), centre) for _, x, y, _ in track]
    assert max(abs(r - 4.0) for r in radii) < 0.3
    assert all(abs(z - start[2]) < 1e-6 for *_, z in track)
    # Clockwise from the west of the centre: first north of it, then east, south.
    quarter = next(i for i, (_, x, y, _) in enumerate(track) if x > start[0] + 3.5)
    half = next(i for i, (_, x, y, _) in enumerate(track) if y > start[1] + 7.5)
    assert quarter < half
    assert min(x for _, x, _, _ in track) < start[0] - 3.5  # swept the south side too
    assert math.dist(rig.core.where()[:3], start) <= 0.1
    assert rig.core.heading_deg == pytest.approx(90.0, abs=1e-6)  # faces the centre again
    speed = orbit_speed_mps(2.0, 2.0, 4.0)
    assert rig.core.t_s - t0 == pytest.approx(2 * math.pi * 4.0 / speed, rel=0.1)
    assert rig.core.where()[5] < battery


def test_orbit_is_cancelled_like_a_move_and_a_busy_vehicle_refuses_it() -> None:
    rig = PluginRig()
    rig.airborne(5.0)
    handle = rig.run("orbit", Orbit(10.0, 2.0))
    for _ in range(100):
        rig.step()
    rig.run("other", Orbit(1.0, 1.0))
    rig.step()
    assert rig.results.got["other"].reason == "busy"
    rig.core.cancel(handle)
    assert rig.until("orbit").status == "cancelled"
    here = rig.core.where()[:3]
    for _ in range(200):
        rig.step()
    assert math.dist(rig.core.where()[:3], here) < 0.5  # held there, no longer circling


def test_return_home_flies_above_home_at_its_height_then_lands() -> None:
    rig = PluginRig()
    rig.airborne(5.0)
    assert rig.do("away", FlyToXYZ(12.0, -6.0, 7.0)).ok
    rig.run("home", ReturnHome())
    track = rig.track("home")
    assert rig.results.got["home"].ok
    x, y, z, landed, armed, _ = rig.core.where()
    assert math.hypot(x, y) <= 0.1 and z == 0.0 and landed
    assert not armed  # disarmed after touchdown, as RTL does
    # No descent before it is above home.
    for _, tx, ty, tz in track:
        if math.hypot(tx, ty) > 0.2:
            assert tz == pytest.approx(7.0, abs=0.05)
    assert rig.do("on ground", ReturnHome()).reason == "not flying"


def test_take_photo_logs_where_and_gimbal_keeps_its_pitch() -> None:
    rig = PluginRig()
    rig.airborne(5.0)
    assert rig.do("away", FlyToXYZ(3.0, 4.0, 5.0)).ok
    assert rig.plugin("gimbal", "Gimbal", -45.0).ok
    assert rig.core.payload["gimbal_pitch_deg"] == -45.0
    assert rig.plugin("photo", "TakePhoto").ok
    photo = rig.log.of("adapter.plugin")[-1]
    assert photo["action"] == "TakePhoto" and photo["photo"] == 1
    assert (photo["x_m"], photo["y_m"], photo["z_m"]) == pytest.approx((3.0, 4.0, 5.0), abs=0.1)
    assert photo["gimbal_pitch_deg"] == -45.0
    end = [e for e in rig.log.of("adapter.action.end") if e["action"] == "TakePhoto"][-1]
    assert end["payload"]["photos"] == 1.0
    assert rig.plugin("video", "StartVideo").ok
    assert rig.plugin("video again", "StartVideo").reason == "already recording"
    assert rig.plugin("stop", "StopVideo").ok
    assert not rig.core.payload["video"]


def test_a_plugin_without_a_sim_implementation_or_with_a_bug_fails_its_action_only() -> None:
    plugins = PluginRegistry(
        [
            ActionPlugin("Spray", ("duration_s",), "spray", {"mavlink": "x.y:z"}),
            ActionPlugin("Drop", (), "drop", {"sim": f"{__name__}:_broken"}),
            ActionPlugin("Lost", (), "lost", {"sim": "no_such_module_xyz:f"}),
        ]
    )
    rig = PluginRig(plugins)
    assert "no 'sim' implementation" in rig.plugin("spray", "Spray", 2.0).reason
    assert "nozzle jammed" in rig.plugin("drop", "Drop").reason
    assert "cannot load" in rig.plugin("lost", "Lost").reason
    assert rig.do("hold ground", Hold(0.0)).reason == "not flying"  # the core still works


def _broken(view: SimView, command: PluginAction) -> SimOutcome:
    raise RuntimeError("nozzle jammed")


def test_a_plugin_action_takes_its_simulated_duration() -> None:
    rig = PluginRig()
    t0 = rig.core.t_s
    assert rig.plugin("gimbal", "Gimbal", -90.0).ok  # 90 degrees at 0.01 s/deg
    assert rig.core.t_s - t0 == pytest.approx(0.9, abs=2 * SIM_DT_S)
