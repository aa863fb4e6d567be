"""ReturnHome, Hold, Yaw, SetSpeed and Orbit in the virtual-time driver, and in the check's tracks.

Idle skipping stays exact with them (same records, final states and adapter lines as
stepping every vehicle every step), and an orbit's track is the curve the vehicle flew.
"""

from __future__ import annotations

import math

import pytest

from eamos.check.tracks import TrackRecorder
from eamos.compiler import compile_mission
from eamos.hal.sim import SIM_DT_S, SimCore, SimSettings
from eamos.program.uniform import Arm, Orbit, Takeoff

from .test_idle_skipping import Recorder, fly, without_handles

MISSION = """package Moves
var D1 Quadcopter
var D2 Quadcopter
func INIT() { PAR_Go() }
func PAR_Go() { SEQ_One(); SEQ_Two() }
func SEQ_One() {
	D1.Arm()
	D1.Takeoff(5)
	D1.SetSpeed(1)
	D1.FlyByX(6)
	D1.Hold(20)
	D1.ReturnHome()
}
func SEQ_Two() {
	D2.Arm()
	D2.Takeoff(6)
	D2.Yaw(90)
	D2.Orbit(4, 1.5)
	D2.Hold(3)
	D2.ReturnHome()
}
"""


def test_new_actions_in_virtual_time_and_skipping_changes_nothing() -> None:
    compiled = compile_mission(MISSION, "m.go")
    lazy, lazy_logs = fly(compiled.programs, {}, lazy=True)
    plain, plain_logs = fly(compiled.programs, {}, lazy=False)
    assert lazy.ok, lazy
    assert lazy.duration_s == plain.duration_s
    for drone, outcome in plain.drones.items():
        assert lazy.drones[drone].actions == outcome.actions, drone
        assert lazy.drones[drone].final == outcome.final, drone
    assert without_handles(lazy_logs) == without_handles(plain_logs)
    assert [a for a, _, r in lazy.actions("D1") if r == "ok"] == [
        "Arm", "Takeoff", "SetSpeed", "FlyByX", "Hold", "ReturnHome"
    ]  # fmt: skip
    d1 = {a.action: a for a in lazy.drones["D1"].actions}
    assert d1["Hold"].end - d1["Hold"].start == pytest.approx(20.0, abs=0.05)
    assert d1["FlyByX"].end - d1["FlyByX"].start > 6.0  # 1 m/s, not the 2 m/s cruise
    for drone in ("D1", "D2"):
        final = lazy.drones[drone].final
        assert (final.x_m, final.y_m, final.z_m, final.landed) == pytest.approx(
            (0.0, 0.0, 0.0, True), abs=0.1
        )
    orbit_end = next(
        f for e, f in lazy_logs["D2"] if e == "adapter.action.end" and f["action"] == "Orbit"
    )
    # 1.5 turns around the point 4 m east: ends 8 m east of where it started, facing west.
    assert (orbit_end["x_m"], orbit_end["y_m"]) == pytest.approx((0.0, 8.0), abs=0.1)
    assert orbit_end["heading_deg"] == pytest.approx(270.0, abs=0.1)


def test_an_orbits_track_is_the_curve_flown() -> None:
    t = [0.0]
    core = SimCore("D1", SimSettings(arm_delay_s=0.0), Recorder(), lambda: t[0])
    clock_steps = [0]
    recorder = TrackRecorder("D1", core, lambda: clock_steps[0] * SIM_DT_S, (0.0, 0.0))
    recorder.start()
    flown: list[tuple[float, float, float, float]] = []
    results: list[str] = []
    for command in (Arm(), Takeoff(5.0), Orbit(6.0, 1.0)):
        recorder.run(command, lambda r: results.append(r.status))
        want = len(results) + 1
        for _ in range(round(300 / SIM_DT_S)):
            if len(results) == want:
                break
            clock_steps[0] += 1
            finished, _ = recorder.step()
            for done, result in finished:
                done(result)
            x, y, z, *_ = core.where()
            flown.append((clock_steps[0] * SIM_DT_S, x, y, z))
    assert results == ["ok", "ok", "ok"]
    track = recorder.track()
    assert len(track.points) > 100  # a circle is not drawn as a few straight lines
    worst = max(math.dist(track.at(ts), (x, y, z)) for ts, x, y, z in flown)
    assert worst < 1e-6
    # Halfway between two recorded steps the track stays on the circle (within a chord's sag).
    orbit = [(ts, x, y) for ts, x, y, z in flown if z > 4.99 and math.hypot(x - 6.0, y) > 5.5]
    mids = [track.at(ts - SIM_DT_S / 2) for ts, _, _ in orbit[1:]]
    assert max(abs(math.dist(m[:2], (6.0, 0.0)) - 6.0) for m in mids) < 0.3
