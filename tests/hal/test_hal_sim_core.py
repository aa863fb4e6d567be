"""SimCore, the simulated quadcopter as pure logic: stepped by hand, no threads, no clock.

Every test here advances the core one SIM_DT_S step at a time and looks at what
each step returns, so simulated times are exact and the tests run in milliseconds.
"""

from __future__ import annotations

import math
from typing import Any

import pytest

from eamos.hal.api import ActionHandle, ActionResult, Telemetry
from eamos.hal.sim.core import PAYLOAD_DELAY_S, SIM_DT_S, SimCore
from eamos.hal.sim.settings import SimSettings, Waypoint
from eamos.program.uniform import (
    Arm,
    Command,
    Disarm,
    FlyBy,
    FlyToXYZ,
    Land,
    PauseFor,
    Payload,
    Takeoff,
)


class EventLog:
    """A stand-in for the adapter logger: records (event, fields)."""

    def __init__(self) -> None:
        self.events: list[tuple[str, dict[str, Any]]] = []

    def info(self, event: str, **fields: Any) -> None:
        self.events.append((event, fields))

    debug = warning = error = exception = info

    def names(self) -> list[str]:
        return [name for name, _ in self.events]

    def of(self, name: str) -> list[dict[str, Any]]:
        return [fields for event, fields in self.events if event == name]


class Results:
    """Done callbacks that record what they receive, by name."""

    def __init__(self) -> None:
        self.got: dict[str, ActionResult] = {}

    def done(self, name: str) -> Any:
        def callback(result: ActionResult) -> None:
            assert name not in self.got, f"{name} finished twice"
            self.got[name] = result

        return callback


class Rig:
    """A started core, with helpers that step it and invoke the returned callbacks."""

    def __init__(self, clock: Any = None, **settings: Any) -> None:
        self.log = EventLog()
        self.now = 1_000.0
        self.core = SimCore(
            "D1", SimSettings(**settings), self.log, clock=clock or (lambda: self.now)
        )
        self.first = self.core.start()
        self.results = Results()
        self.samples: list[Telemetry] = [self.first]

    def run(self, name: str, command: Command) -> ActionHandle:
        return self.core.run(command, self.results.done(name))

    def step(self) -> list[ActionResult]:
        finished, samples = self.core.step()
        self.samples += samples
        out = []
        for done, result in finished:
            done(result)
            out.append(result)
        return out

    def until(self, name: str, max_s: float = 300.0) -> ActionResult:
        """Step until ``name`` finished; fails after ``max_s`` simulated seconds."""
        for _ in range(round(max_s / SIM_DT_S)):
            if name in self.results.got:
                return self.results.got[name]
            self.step()
        raise AssertionError(f"{name} not finished within {max_s} simulated s")

    def do(self, name: str, command: Command) -> ActionResult:
        self.run(name, command)
        return self.until(name)

    def airborne(self, height: float = 5.0) -> None:
        assert self.do("arm", Arm()).ok
        assert self.do("takeoff", Takeoff(height)).ok


def at(core: SimCore, x: float, y: float, z: float, tol: float = 0.1) -> bool:
    s = core.state()
    return math.dist((s.x_m, s.y_m, s.z_m), (x, y, z)) <= tol


def test_start_returns_the_first_sample_and_logs_start() -> None:
    rig = Rig(battery_pct=80.0)
    first = rig.first
    assert (first.drone, first.x_m, first.z_m, first.battery_pct) == ("D1", 0.0, 0.0, 80.0)
    assert first.armed is False and first.landed is True
    assert first.time_s == 1_000.0  # stamped by the injected clock
    assert rig.log.names() == ["adapter.start"]
    assert rig.core.t_s == 0.0


def test_step_before_start_and_a_second_start_are_errors() -> None:
    core = SimCore("D1", SimSettings(), EventLog())
    with pytest.raises(RuntimeError, match="before start"):
        core.step()
    core.start()
    with pytest.raises(RuntimeError, match="already started"):
        core.start()


def test_a_request_is_taken_up_at_the_next_step_and_nothing_calls_back() -> None:
    rig = Rig()
    handle = rig.run("pause", PauseFor(0.1))
    assert (handle.action, handle.args) == ("PauseFor", (0.1,))
    assert "adapter.action.start" not in rig.log.names()
    steps = 0
    while "pause" not in rig.results.got:
        assert rig.step() == [] or "pause" in rig.results.got
        steps += 1
    # Taken up at the start of step 1 (t = 0), finished once t reaches 0.1 s.
    assert steps == round(0.1 / SIM_DT_S)
    assert rig.results.got["pause"] == ActionResult("ok")
    assert rig.core.t_s == pytest.approx(steps * SIM_DT_S)


def test_arm_completes_exactly_at_arm_delay() -> None:
    rig = Rig(arm_delay_s=1.0)
    rig.run("arm", Arm())
    while "arm" not in rig.results.got:
        rig.step()
    assert rig.results.got["arm"].ok
    assert rig.core.t_s == pytest.approx(1.0, abs=SIM_DT_S / 2)
    assert rig.core.state().armed


def test_square_flight_lands_at_home() -> None:
    rig = Rig()
    rig.airborne(5.0)
    assert at(rig.core, 0, 0, 5)
    corners = [(10, 0), (10, 10), (0, 10), (0, 0)]
    legs = [FlyBy("X", 10.0), FlyBy("Y", 10.0), FlyBy("X", -10.0), FlyBy("Y", -10.0)]
    for i, (leg, (x, y)) in enumerate(zip(legs, corners, strict=True)):
        assert rig.do(f"leg{i}", leg).ok
        assert at(rig.core, x, y, 5)
    assert rig.do("land", Land()).ok
    assert rig.core.state().landed
    assert rig.do("disarm", Disarm()).ok
    assert not rig.core.state().armed
    ends = rig.log.of("adapter.action.end")
    assert [e["action"] for e in ends] == [
        "Arm",
        "Takeoff",
        "FlyByX",
        "FlyByY",
        "FlyByX",
        "FlyByY",
        "Land",
        "Disarm",
    ]


def test_rules_refuse_with_reasons() -> None:
    rig = Rig(reject_actions=("Calibrate",))
    assert rig.do("t", Takeoff(5.0)) == ActionResult("failed", "not armed")
    assert rig.do("c", Payload("Calibrate")) == ActionResult("failed", "rejected by vehicle")
    assert rig.do("p", PauseFor(-1.0)) == ActionResult("failed", "duration_s must be >= 0")
    assert rig.do("arm", Arm()).ok
    assert rig.do("fly", FlyBy("X", 3.0)) == ActionResult("failed", "not flying")
    assert rig.do("t0", Takeoff(0.0)) == ActionResult("failed", "height_m must be > 0")
    assert rig.do("takeoff", Takeoff(3.0)).ok
    assert rig.do("disarm", Disarm()) == ActionResult("failed", "in the air")
    rig.run("far", FlyBy("X", 20.0))
    assert rig.do("busy", FlyToXYZ(1.0, 1.0, 2.0)) == ActionResult("failed", "busy")
    low = rig.do("low", PauseFor(0.0))
    assert low.ok  # non-motion actions run beside a motion action
    assert rig.until("far").ok
    assert "not above ground" in rig.do("down", FlyBy("Z", -10.0)).reason


def test_payload_takes_its_delay() -> None:
    rig = Rig()
    rig.run("cam", Payload("TurnOnCamera"))
    while "cam" not in rig.results.got:
        rig.step()
    assert rig.core.t_s == pytest.approx(PAYLOAD_DELAY_S)


def test_motion_timeout_holds_the_vehicle() -> None:
    rig = Rig(action_timeout_s=4.0)
    rig.airborne(2.0)
    result = rig.do("far", FlyBy("X", 50.0))
    assert result == ActionResult("failed", "timeout after 4 s: target not reached")
    for _ in range(round(5.0 / SIM_DT_S)):
        rig.step()
    assert rig.core.state().speed_mps == 0.0
    assert 3.0 < rig.core.state().x_m < 12.0


def test_cancel_holds_and_frees_the_motion_slot() -> None:
    rig = Rig()
    rig.airborne(5.0)
    handle = rig.run("far", FlyBy("X", 30.0))
    while rig.core.state().x_m < 4.0:
        rig.step()
    rig.core.cancel(handle)
    assert rig.step() == [ActionResult("cancelled", "cancelled")]
    rig.core.cancel(handle)  # a finished action: nothing happens
    assert rig.step() == []
    assert rig.do("next", FlyBy("Y", 1.0)).ok


def test_abort_cancels_lands_and_disarms() -> None:
    rig = Rig()
    rig.airborne(4.0)
    rig.run("far", FlyBy("X", 30.0))
    rig.run("pause", PauseFor(1_000.0))
    rig.step()
    rig.core.abort()
    results = rig.step()
    assert results == [ActionResult("cancelled", "aborted")] * 2
    # While aborting, motion is refused and waits are allowed.
    assert rig.do("arm while aborting", Arm()) == ActionResult("failed", "aborting")
    for _ in range(round(60.0 / SIM_DT_S)):
        rig.step()
        if "adapter.abort.done" in rig.log.names():
            break
    state = rig.core.state()
    assert state.landed and not state.armed
    assert rig.do("arm again", Arm()).ok


def test_pilot_defers_mission_motion_until_its_path_ends() -> None:
    pilot = (Waypoint(4.0, 0.0, 4.0, hold_s=1.0), Waypoint(4.0, 4.0, 4.0))
    rig = Rig(pilot=pilot)
    rig.airborne(3.0)
    assert rig.core.pilot_flying
    rig.run("fly", FlyToXYZ(0.0, 0.0, 2.0))
    rig.step()
    assert rig.log.of("adapter.action.deferred")[0]["action"] == "FlyToXYZ"
    assert rig.do("pause", PauseFor(0.2)).ok  # non-motion runs meanwhile
    assert rig.until("fly").ok
    assert not rig.core.pilot_flying
    assert at(rig.core, 0, 0, 2)
    names = rig.log.names()
    assert names.count("adapter.pilot.waypoint") == 2
    assert names.index("adapter.pilot.end") < max(
        i for i, (n, f) in enumerate(rig.log.events) if f.get("action") == "FlyToXYZ"
    )


def test_telemetry_is_sampled_at_its_rate_and_only_on_change() -> None:
    rig = Rig(telemetry_hz=5.0, drain_idle_pct_per_min=0, drain_airborne_pct_per_min=0)
    for _ in range(round(2.0 / SIM_DT_S)):
        rig.step()
    assert rig.samples == [rig.first]  # at rest: nothing new
    rig.run("arm", Arm())
    rig.until("arm")
    rig.run("takeoff", Takeoff(3.0))
    t0, n0 = rig.core.t_s, len(rig.samples)
    rig.until("takeoff")
    climbing = len(rig.samples) - n0
    assert 5 <= climbing <= (rig.core.t_s - t0) * 5 + 1
    zs = [s.z_m for s in rig.samples]
    assert zs == sorted(zs)
    assert all(s.z_m == round(s.z_m, 2) for s in rig.samples)


def test_time_stamps_come_from_the_injected_clock() -> None:
    ticks = iter(range(10_000))
    rig = Rig(clock=lambda: float(next(ticks)))
    rig.run("arm", Arm())
    rig.until("arm")
    stamps = [s.time_s for s in rig.samples]
    assert stamps[0] == 0.0 and stamps == sorted(stamps)


def test_the_same_commands_give_the_same_flight() -> None:
    def fly() -> list[tuple[float, ...]]:
        rig = Rig()
        rig.airborne(3.0)
        rig.do("x", FlyBy("X", 4.0))
        rig.do("land", Land())
        return [s.state() for s in rig.samples]

    assert fly() == fly()


def test_finish_all_ends_running_and_queued_actions() -> None:
    rig = Rig()
    rig.run("pause", PauseFor(100.0))
    rig.step()
    rig.run("queued", Arm())
    finished = rig.core.finish_all(ActionResult("cancelled", "adapter closed"))
    for done, result in finished:
        done(result)
    assert rig.results.got == {
        "pause": ActionResult("cancelled", "adapter closed"),
        "queued": ActionResult("cancelled", "adapter closed"),
    }
    assert rig.step() == []
