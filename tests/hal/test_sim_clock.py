"""One clock steps every simulated vehicle of a process (issue 32).

The clock and the pacing are driven by hand with a fake wall clock (no thread,
no sleep): a tick runs the steps wall time has covered, several per tick at high
speed-ups; resting vehicles are left out of the ticks until their rest ends or a
request pokes them; simulated times are those of stepping each vehicle alone.
One test runs the real thread: twenty drones fly on one clock thread.
"""

from __future__ import annotations

import math
import threading

import pytest

from eamos.hal.api import ActionResult
from eamos.hal.sim import SIM_DT_S, SimAdapter, SimClock, SimSettings
from eamos.hal.sim.clock import MAX_LAG_S, MIN_WALL_TICK_S, Pacer
from eamos.logs import read_log
from eamos.program.uniform import Arm, Command, Land, PauseFor, Takeoff

from .hal_helpers import WAIT_S, Done, TelemetrySink, cmd

pytestmark = pytest.mark.timeout(180)


class FakeTime:
    """A wall clock that moves only when told."""

    def __init__(self) -> None:
        self.now = 1000.0

    def __call__(self) -> float:
        return self.now


def test_a_pacer_runs_the_steps_wall_time_covered() -> None:
    p = Pacer(10.0)  # 10 x: a step is 2 ms of wall time, a tick 2 steps
    assert p.steps_per_tick == 2 and p.wall_tick_s == pytest.approx(0.004)
    p.restart(0.0)
    assert p.due(0.0) == 0
    assert p.due(0.004) == 2
    assert p.due(0.005) == 0  # half a step more: nothing yet
    assert p.due(0.0101) == 3  # a late tick runs what it covered
    # Far behind (a stalled machine): one tick's steps, the rest lost, not burst through.
    assert p.due(0.0101 + 10 * MAX_LAG_S) == p.steps_per_tick
    assert p.due(0.0101 + 10 * MAX_LAG_S + 0.004) == 2
    fast = Pacer(100.0)  # several steps per tick, the tick at least MIN_WALL_TICK_S
    assert fast.steps_per_tick == 25 and fast.wall_tick_s >= MIN_WALL_TICK_S - 1e-12
    with pytest.raises(ValueError):
        Pacer(0.0)


def test_pacers_of_one_speed_up_step_on_one_grid() -> None:
    # Restarted at different moments, two vehicles at x10 step on the same 2 ms grid,
    # so rests that end at the same moment end on the same step.
    a, b = Pacer(10.0), Pacer(10.0)
    a.restart(1.0033)
    b.restart(1.0051)
    assert a.stepped_to() == pytest.approx(1.002) and b.stepped_to() == pytest.approx(1.004)
    assert a.due(1.0061) == 2 and b.due(1.0061) == 1  # each up to the grid's 1.006
    assert a.stepped_to() == pytest.approx(b.stepped_to()) == pytest.approx(1.006)
    a.restart(1.006)  # a time computed as a grid step stays on that step
    assert a.stepped_to() == pytest.approx(1.006)


def vehicles(n: int, clock: SimClock, speedup: float) -> list[SimAdapter]:
    out = []
    for i in range(n):
        sim = SimAdapter(f"D{i}", SimSettings(arm_delay_s=0.0, speedup=speedup), clock=clock)
        sim.start(lambda sample: None)
        out.append(sim)
    return out


def run_clock(clock: SimClock, fake: FakeTime, until: float, done: list[Done]) -> int:
    """Tick as the thread would (the wait it asks for) until ``done``; the fake time is
    then that of the round that saw it done."""
    rounds = 0
    while True:
        wait = clock.tick()
        rounds += 1
        if all(d.is_done for d in done):
            return rounds
        fake.now += wait if math.isfinite(wait) else 1.0
        assert fake.now < until, "not done in time"


def fly(sim: SimAdapter, clock: SimClock, fake: FakeTime, command: Command) -> ActionResult:
    done = Done()
    sim.run(command, done)
    run_clock(clock, fake, fake.now + 600.0, [done])
    return done.wait(0)


def test_one_clock_steps_every_vehicle_as_if_each_had_its_own() -> None:
    fake = FakeTime()
    clock = SimClock(time_fn=fake, threaded=False)
    fleet = vehicles(5, clock, speedup=10.0)
    # Each its own altitude: different durations, all on one clock.
    dones = []
    for sim in fleet:
        d = Done()
        sim.run(Arm(), d)
        dones.append(d)
    run_clock(clock, fake, fake.now + 60.0, dones)
    dones = []
    for i, sim in enumerate(fleet):
        d = Done()
        sim.run(Takeoff(2.0 + i), d)
        dones.append(d)
    start = fake.now
    run_clock(clock, fake, fake.now + 60.0, dones)
    assert all(d.wait(0).ok for d in dones)
    for i, sim in enumerate(fleet):
        assert sim.state.z_m == pytest.approx(2.0 + i, abs=0.15)
    # Simulated time follows wall time at the speed-up, for each vehicle.
    for sim in fleet:
        assert sim.sim_time_s == pytest.approx((fake.now - 1000.0) * 10.0, abs=0.1)
    assert fake.now - start < 10.0  # the climbs took seconds of (fake) wall time, not more
    for sim in fleet:
        sim.close()
    assert clock.attached == 0


def test_resting_vehicles_are_left_out_and_a_request_pokes_one_awake() -> None:
    fake = FakeTime()
    clock = SimClock(time_fn=fake, threaded=False)
    a, b = vehicles(2, clock, speedup=1.0)
    clock.tick()
    pause = Done()
    a.run(PauseFor(30.0), pause)
    clock.tick()  # a takes the pause up
    fake.now += 0.02
    clock.tick()
    # Both rest now (b on the ground, a through its pause): the clock waits for a's end.
    before = a.wakeups, b.wakeups
    wait = clock.tick()
    assert wait == pytest.approx(30.0, abs=0.1)
    fake.now += 10.0
    assert math.isinf(clock.tick()) is False  # a's rest is still pending
    assert (a.wakeups, b.wakeups) == before  # nobody paced in 10 s of rest
    # A request wakes b at the next tick; a sleeps on.
    armed = Done()
    b.run(Arm(), armed)
    assert clock.tick() < 1.0  # b ticks now: the clock no longer waits for a alone
    run_clock(clock, fake, fake.now + 5.0, [armed])
    assert armed.wait(0).ok and not pause.is_done
    assert a.wakeups == before[0]
    # a's pause ends on time: 30 simulated seconds at x1 from when it began.
    began = a.sim_time_s - (fake.now - 1000.0 - 0.02)
    run_clock(clock, fake, fake.now + 40.0, [pause])
    assert pause.wait(0).ok
    assert fake.now - 1000.0 == pytest.approx(30.02 + began, abs=0.1)
    assert a.sim_time_s == pytest.approx(fake.now - 1000.0, abs=0.05)
    a.close()
    b.close()


def test_at_high_speed_ups_a_tick_runs_several_steps_and_keeps_the_physics(tmp_path) -> None:
    from eamos.logs import close_logger, make_logger

    results = {}
    for speedup in (1.0, 50.0):
        fake = FakeTime()
        clock = SimClock(time_fn=fake, threaded=False)
        log = make_logger(tmp_path / f"x{speedup:g}.log", drone="D1")
        sim = SimAdapter("D1", SimSettings(arm_delay_s=0.0, speedup=speedup), log, clock=clock)
        sim.start(lambda sample: None)
        assert fly(sim, clock, fake, Arm()).ok
        assert fly(sim, clock, fake, Takeoff(3.0)).ok
        rounds_before = clock.ticks
        assert fly(sim, clock, fake, cmd("FlyByX", 10.0)).ok
        rounds = clock.ticks - rounds_before
        assert fly(sim, clock, fake, Land()).ok
        sim.close()
        close_logger(log)
        ends = [
            e
            for e in read_log(tmp_path / f"x{speedup:g}.log")
            if e["event"] == "adapter.action.end"
        ]
        results[speedup] = ([round(e["duration_sim_s"], 1) for e in ends], rounds)
    # The same simulated durations at x1 and x50; far fewer ticks than steps at x50.
    assert results[1.0][0] == results[50.0][0]
    fly_s = results[50.0][0][2]
    assert results[50.0][1] < fly_s / SIM_DT_S / 5


def test_twenty_drones_fly_on_one_clock_thread() -> None:
    clock = SimClock("test-clock")
    before = threading.active_count()
    sinks = [TelemetrySink() for _ in range(20)]
    fleet = []
    for i, sink in enumerate(sinks):
        sim = SimAdapter(f"D{i}", SimSettings(arm_delay_s=0.0, speedup=20.0), clock=clock)
        sim.start(sink)
        fleet.append(sim)
    assert threading.active_count() == before + 1  # the clock's, not one per drone
    try:
        for command in (Arm(), Takeoff(2.0), cmd("FlyByX", 3.0), Land()):
            dones = [Done() for _ in fleet]
            for sim, d in zip(fleet, dones, strict=True):
                sim.run(command, d)
            assert all(d.wait(WAIT_S).ok for d in dones), command
        for sim, sink in zip(fleet, sinks, strict=True):
            assert sim.state.x_m == pytest.approx(3.0, abs=0.15)
            # The sample showing the landing follows at the next telemetry step.
            assert sink.wait_last(lambda last: last.landed, WAIT_S)
    finally:
        for sim in fleet:
            sim.close()
        clock.close()
    assert not clock.errors
