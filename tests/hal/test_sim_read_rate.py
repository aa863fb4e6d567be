"""A simulated vehicle whose samples are read at most so often sends its resting battery no faster.

Pure: one :class:`SimAdapter` on a :class:`SimClock` driven by hand with a fake wall
clock (no thread).  Hovering at x10, the shown battery (0.1 %) changes several times
a wall second; read at most twice a second (the ground station's rate), the vehicle
wakes and samples about that often, the battery it shows is the model's, and what
moves is sampled as before.
"""

from __future__ import annotations

import itertools
import math

import pytest

from eamos.hal.api import Telemetry, read_at_most
from eamos.hal.sim import SimAdapter, SimClock, SimSettings
from eamos.hal.sim.telemetry import ReadRate
from eamos.program.uniform import Arm, Takeoff

from .hal_helpers import TelemetrySink, cmd
from .test_sim_clock import FakeTime, fly

pytestmark = pytest.mark.timeout(180)

SPEEDUP = 10.0
HOVER_WALL_S = 10.0


def run_for(clock: SimClock, fake: FakeTime, wall_s: float) -> None:
    """Tick as the clock's thread would for ``wall_s`` of fake wall time."""
    end = fake.now + wall_s
    while fake.now < end:
        wait = clock.tick()
        fake.now += min(wait if math.isfinite(wait) else 1.0, end - fake.now) or 1e-3


Hovered = tuple[SimAdapter, list[Telemetry], int, list[Telemetry], tuple[float, float]]


def hover(read_hz: float | None) -> Hovered:
    """Take off, hover HOVER_WALL_S, fly 5 m: the adapter, the hover's samples and
    wake-ups, the flight's samples, (simulated time, battery) at the hover's end."""
    fake = FakeTime()
    clock = SimClock(time_fn=fake, threaded=False)
    sink = TelemetrySink()
    sim = SimAdapter("D1", SimSettings(arm_delay_s=0.0, speedup=SPEEDUP), clock=clock)
    sim.start(sink)
    read_at_most(sim, read_hz)
    assert fly(sim, clock, fake, Arm()).ok
    assert fly(sim, clock, fake, Takeoff(3.0)).ok
    run_for(clock, fake, 1.0)  # settled
    before, woke = sink.count(), sim.wakeups
    run_for(clock, fake, HOVER_WALL_S)
    hovered, wakeups = sink.samples[before:], sim.wakeups - woke
    end = (sim.sim_time_s, sim.state.battery_pct)
    before = sink.count()
    assert fly(sim, clock, fake, cmd("FlyByX", 5.0)).ok
    flown = sink.samples[before:]
    return sim, hovered, wakeups, flown, end


def test_a_resting_vehicle_read_twice_a_second_samples_its_battery_about_that_often() -> None:
    free, free_samples, free_wakeups, free_flight, (free_t, free_pct) = hover(None)
    paced, samples, wakeups, flight, (t, pct) = hover(2.0)
    # As they come: every 0.1 % of a hover draining 4 %/min, 100 simulated seconds.
    assert len(free_samples) >= 60 and free_wakeups >= 60
    # Read twice a wall second: at most that many samples, and a few wake-ups each.
    assert 2.0 * HOVER_WALL_S - 2 <= len(samples) <= 2.0 * HOVER_WALL_S + 1
    assert wakeups <= 3 * len(samples) + 3 < free_wakeups / 2
    # Every sample shows the battery the model had: the two runs drained alike (the
    # model's 4 %/min at hover, over the simulated time each covered) ...
    drain_per_s = SimSettings().drain_airborne_pct_per_min / 60.0
    assert free_pct - pct == pytest.approx(drain_per_s * (t - free_t), abs=1e-6)
    # ... each sample a step of the drain since the one before (half a wall second: 5
    # simulated seconds, a third of a percent) ...
    steps = [a.battery_pct - b.battery_pct for a, b in itertools.pairwise(samples)]
    assert all(0.1 - 1e-9 <= step <= 5 * drain_per_s + 0.1 + 1e-9 for step in steps)
    # ... and the latest one sent is the latest the other run sent, or one change before.
    assert free_samples[-1].battery_pct - samples[-1].battery_pct <= 0.1 + 1e-9
    # What moves is sent once a read period, and where it stopped at once; as they
    # come, at the sampling rate (10 Hz of simulated time: 100 a wall second at x10).
    moving, free_moving = [s for s in flight if s.x_m > 0], [s for s in free_flight if s.x_m > 0]
    flight_wall_s = len(free_moving) / SimSettings().telemetry_hz / SPEEDUP
    assert len(free_moving) >= 20 and 1 <= len(moving) <= 2.0 * flight_wall_s + 2
    assert moving[-1].x_m == free_moving[-1].x_m == pytest.approx(5.0, abs=0.05)
    assert len({(s.armed, s.landed) for s in flight}) == 1  # in the air throughout
    free.close()
    paced.close()


def test_the_read_rate_is_checked_and_can_be_lifted() -> None:
    fake = FakeTime()
    clock = SimClock(time_fn=fake, threaded=False)
    sim = SimAdapter("D1", SimSettings(arm_delay_s=0.0, speedup=SPEEDUP), clock=clock)
    sim.start(lambda sample: None)
    with pytest.raises(ValueError, match="hz"):
        sim.read_at_most(0.0)
    sim.read_at_most(2.0)
    sim.read_at_most(None)  # an amended program reads its own battery: as they come again
    read_at_most(object(), 2.0)  # an adapter that cannot pace its samples is left alone
    sim.close()


def test_vehicles_that_came_to_rest_at_different_times_wake_together() -> None:
    # A relay: each takes off after the one before, so each rest begins at its own
    # moment.  Read at the same rate, their reads fall on the same multiples of the
    # period, and the clock wakes about once a period for all of them, where it
    # woke once for each (ten vehicles, twice a second: about 20 rounds a second).
    fake = FakeTime()
    fake.now += 0.0123  # not on any grid
    clock = SimClock(time_fn=fake, threaded=False)
    sinks = [TelemetrySink() for _ in range(10)]
    fleet = [
        SimAdapter(f"D{i}", SimSettings(arm_delay_s=0.0, speedup=SPEEDUP), clock=clock)
        for i in range(len(sinks))
    ]
    for sim, sink in zip(fleet, sinks, strict=True):
        sim.start(sink)
        read_at_most(sim, 2.0)
    for sim in fleet:
        assert fly(sim, clock, fake, Arm()).ok
        assert fly(sim, clock, fake, Takeoff(1.0 + 0.37 * int(sim.drone[1:]))).ok
        run_for(clock, fake, 0.077)  # the next one starts at its own moment
    run_for(clock, fake, 1.0)  # settled
    before = [sink.count() for sink in sinks]
    rounds = clock.ticks
    run_for(clock, fake, HOVER_WALL_S)
    assert clock.ticks - rounds <= 2.0 * HOVER_WALL_S + 3
    for sim, sink, count in zip(fleet, sinks, before, strict=True):
        # Each still sends its battery twice a second, and its simulated time keeps
        # up with the wall clock (no step lost to the shared grid).
        assert 2.0 * HOVER_WALL_S - 2 <= sink.count() - count <= 2.0 * HOVER_WALL_S + 1
        assert sim.sim_time_s == pytest.approx((fake.now - 1000.0123) * SPEEDUP, abs=0.5)
        sim.close()


def sample_at(x_m: float, armed: bool = True, landed: bool = False) -> Telemetry:
    return Telemetry("D1", 0.0, x_m, 0.0, 3.0, 0.0, 0.0, 3.0, 90.0, armed, landed)


def test_a_moving_vehicle_read_twice_a_second_sends_its_latest_sample_that_often() -> None:
    reads = ReadRate()
    reads.period_s = 0.5
    out = [reads.pass_on([sample_at(0.0)], 10.0, news=False)]  # the first goes at once
    # Moving: a sample every 10 ms of wall time; one goes out each half second, the latest.
    out += [reads.pass_on([sample_at(i / 100)], 10.0 + i / 100, news=False) for i in range(1, 100)]
    sent = [s.x_m for batch in out for s in batch]
    assert sent == [0.0, 0.5]
    # Held: the newest waits for the period's end, even without a newer sample.
    assert reads.pass_on([], 11.0, news=False) == [sample_at(0.99)]
    # What arms, lands, ends an action or comes to rest goes at once.
    assert reads.pass_on([sample_at(1.0, landed=True)], 11.01, news=False) == [
        sample_at(1.0, landed=True)
    ]
    assert reads.pass_on([sample_at(1.1, landed=True)], 11.02, news=True) == [
        sample_at(1.1, landed=True)
    ]
    # Read as they come again: every sample, the held one first.
    assert reads.pass_on([sample_at(1.2, landed=True)], 11.03, news=False) == []
    reads.period_s = None
    assert reads.pass_on([sample_at(1.3, landed=True)], 11.04, news=False) == [
        sample_at(1.2, landed=True),
        sample_at(1.3, landed=True),
    ]
