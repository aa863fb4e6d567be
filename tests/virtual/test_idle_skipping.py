"""Idle vehicles are skipped, not stepped: the run shows exactly what stepping shows.

The driver lets a simulator core that can tell its idle steps sleep through
them (``LazyVehicle``) and jumps over steps in which every vehicle sleeps.
These tests run the same missions with that and with a plain wrapper that
hides the capability (every vehicle stepped every 20 ms) and require equal
results: action records with their times, final states bit for bit, the
telemetry samples the conditions saw, and the adapter log lines.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import pytest

from eamos.compiler import compile_file, compile_mission
from eamos.hal.api import ActionHandle, DoneCallback, Telemetry
from eamos.hal.sim import SIM_DT_S, SimCore, SimSettings
from eamos.program.uniform import Command, PauseFor, Takeoff
from eamos.virtual import IdleVehicle, VirtualMission

from .test_virtual_driver import MISSIONS, settings_for

REPO = Path(__file__).resolve().parents[2]


class Recorder:
    """A log that keeps every line (event and fields)."""

    def __init__(self) -> None:
        self.lines: list[tuple[str, dict[str, Any]]] = []

    def bind(self, **_: Any) -> Recorder:
        return self

    def info(self, event: str, **fields: Any) -> None:
        self.lines.append((event, fields))

    debug = warning = error = exception = info


class Stepped:
    """A core without ``idle_steps``/``skip``: the driver must step it every time."""

    def __init__(self, core: SimCore) -> None:
        self.core = core

    def start(self) -> Telemetry:
        return self.core.start()

    def run(self, command: Command, done: DoneCallback) -> ActionHandle:
        return self.core.run(command, done)

    def cancel(self, handle: ActionHandle) -> None:
        self.core.cancel(handle)

    def abort(self) -> None:
        self.core.abort()

    def step(self) -> Any:
        return self.core.step()

    def state(self) -> Any:
        return self.core.state()

    @property
    def settling(self) -> bool:
        return self.core.settling


def fly(programs: Any, settings: dict[str, SimSettings], lazy: bool) -> tuple[Any, dict]:
    logs: dict[str, Recorder] = {}

    def make(drone: str, clock: Any) -> Any:
        logs[drone] = Recorder()
        core = SimCore(drone, settings.get(drone, SimSettings()), logs[drone], clock)
        return core if lazy else Stepped(core)

    run = VirtualMission(programs, make).run()
    return run, {d: r.lines for d, r in logs.items()}


def without_handles(logs: dict[str, list[tuple[str, dict[str, Any]]]]) -> dict[str, list]:
    """The lines without action handle ids (numbered per process, not per run)."""
    return {
        d: [(e, {k: v for k, v in f.items() if k != "handle"}) for e, f in lines]
        for d, lines in logs.items()
    }


@pytest.mark.parametrize("mission", sorted(p.stem for p in MISSIONS.glob("*.go")))
def test_skipping_idle_steps_changes_nothing(mission: str) -> None:
    compiled = compile_file(MISSIONS / f"{mission}.go")
    settings = settings_for(mission)
    lazy, lazy_logs = fly(compiled.programs, settings, lazy=True)
    plain, plain_logs = fly(compiled.programs, settings, lazy=False)
    assert lazy.duration_s == plain.duration_s
    assert lazy.timed_out == plain.timed_out
    for drone, outcome in plain.drones.items():
        other = lazy.drones[drone]
        assert other.actions == outcome.actions, drone
        assert other.final == outcome.final, drone  # bit for bit, battery included
        assert other.resolved == outcome.resolved
    assert without_handles(lazy_logs) == without_handles(
        plain_logs
    )  # every adapter line, with its sim time and position


def test_a_long_pause_is_jumped_over() -> None:
    """Ten minutes of a fleet waiting on the ground take a handful of real steps."""
    source = """package main
var D1 Quadcopter
var D2 Quadcopter
func main() { PAR_Go() }
func PAR_Go() { D1.PauseFor(600); D2.PauseFor(300) }
"""
    compiled = compile_mission(source, "t.go")
    mission = VirtualMission(compiled.programs)
    run = mission.run()
    assert run.duration_s == pytest.approx(600.0, abs=0.05)
    assert mission.jumped > 0.99 * mission.steps  # nearly every step was jumped over
    plain, _ = fly(compiled.programs, {}, lazy=False)
    assert plain.drones["D1"].final == run.drones["D1"].final
    assert plain.duration_s == run.duration_s


def test_idle_steps_are_none_while_anything_moves_or_is_queued() -> None:
    t = [0.0]
    core = SimCore("D1", SimSettings(arm_delay_s=0.0), Recorder(), lambda: t[0])
    assert isinstance(core, IdleVehicle)
    core.start()
    core.step()
    assert core.idle_steps(1000) == 1000  # on the ground, disarmed, nothing to do
    core.run(PauseFor(1.0), lambda r: None)
    assert core.idle_steps(1000) == 0  # a request is queued
    core.step()  # takes the pause up
    n = core.idle_steps(1000)
    assert 45 <= n < 50  # the pause ends at 1 s = 50 steps
    core.skip(n)
    finished, _ = core.step()
    assert finished and finished[0][1].status == "ok"
    with pytest.raises(RuntimeError, match="not idle"):
        core.run(Takeoff(2.0), lambda r: None)
        core.skip(1)


def test_idle_ends_before_the_shown_battery_changes() -> None:
    """A fast-draining battery: the skip stops before its shown 0.1 % step."""
    settings = SimSettings(drain_idle_pct_per_min=60.0, telemetry_hz=10.0)
    stepped = SimCore("D1", settings, Recorder(), lambda: 0.0)
    lazy = SimCore("D1", settings, Recorder(), lambda: 0.0)
    seen_stepped: list[float] = []
    seen_lazy: list[float] = []
    for core in (stepped, lazy):
        core.start()
    for _ in range(int(5.0 / SIM_DT_S)):
        seen_stepped += [s.battery_pct for s in stepped.step()[1]]
    steps = 0
    while steps < int(5.0 / SIM_DT_S):
        n = min(lazy.idle_steps(10_000), int(5.0 / SIM_DT_S) - steps)
        if n:
            lazy.skip(n)
            steps += n
            continue
        seen_lazy += [s.battery_pct for s in lazy.step()[1]]
        steps += 1
    assert seen_lazy == seen_stepped  # every 0.1 % the stepped core showed
    assert lazy.state() == stepped.state()
    assert len(seen_stepped) >= 40


# D1 hovers while D2 pauses and nobody reads D1's telemetry; then a condition reads
# its battery.  The branch taken says which battery value the condition saw.
UNREAD_THEN_READ = """package main
var D1 Quadcopter
var D2 Quadcopter
func SEQ_Main() {
    D1.Arm()
    D1.Takeoff(2)
    D2.PauseFor(PAUSE)
    If(D1.Battery() > LIMIT, SEQ_Above, SEQ_Below)
    D1.Land()
}
func SEQ_Above() { D2.PauseFor(1) }
func SEQ_Below() { D2.PauseFor(2) }
"""


class CountingCore(SimCore):
    """A simulator core that counts its real steps."""

    steps_taken = 0

    def step(self) -> Any:
        CountingCore.steps_taken += 1
        return super().step()


@pytest.mark.parametrize("pause", [37.0, 61.33])
def test_a_vehicle_nobody_reads_rests_through_its_battery_samples(pause: float) -> None:
    """Unread, a hovering drone's battery ends no rest; read again, the condition sees
    the value stepping every step showed (every limit around it decides the same way)."""
    settings = {"D1": SimSettings(arm_delay_s=0.0, drain_airborne_pct_per_min=6.0)}
    seen = []
    # Hovering drains 0.1 % a second: about 100 - pause / 10 when the condition reads it.
    estimate = 100.0 - pause / 10
    for limit in [round(estimate - 0.1 * k, 1) for k in range(-5, 15)]:
        source = UNREAD_THEN_READ.replace("PAUSE", f"{pause:g}").replace("LIMIT", f"{limit:g}")
        programs = compile_mission(source, "t.go").programs
        lazy, lazy_logs = fly(programs, settings, lazy=True)
        plain, plain_logs = fly(programs, settings, lazy=False)
        assert lazy.drones["D2"].actions == plain.drones["D2"].actions, limit
        assert lazy.drones["D1"].final == plain.drones["D1"].final
        assert without_handles(lazy_logs) == without_handles(plain_logs)
        seen.append([a.args for a in lazy.drones["D2"].actions][-1])
    assert (1.0,) in seen and (2.0,) in seen  # the limits straddle what it showed
    # The hover itself costs a few real steps, not one per 0.1 % of battery.
    CountingCore.steps_taken = 0
    source = UNREAD_THEN_READ.replace("PAUSE", f"{pause:g}").replace("LIMIT", "50")

    def make(drone: str, clock: Any) -> Any:
        return CountingCore(drone, settings.get(drone, SimSettings()), Recorder(), clock)

    VirtualMission(compile_mission(source, "t.go").programs, make).run()
    shown_changes = pause * 6.0 / 60 / 0.1  # 0.1 % steps of battery while hovering
    assert CountingCore.steps_taken < 400 + shown_changes / 4, CountingCore.steps_taken


if __name__ == "__main__":  # pragma: no cover
    sys.exit(pytest.main([__file__]))
