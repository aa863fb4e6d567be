"""The SimAdapter's pacing thread rests while the vehicle rests, and a request wakes it.

Issue 15: a hovering drone used to cost ~200 wake-ups a second.  Now the thread sleeps
on an event through the steps SimCore calls idle; these tests count its wake-ups and
check that time, actions, telemetry and the position log stay what stepping gives.
"""

from __future__ import annotations

import itertools
import time

import pytest

from eamos.hal.sim.adapter import MIN_WALL_TICK_S
from eamos.logs import read_log
from tests.support.sim_fixtures import SimFactory

from .hal_helpers import Done, TelemetrySink, cmd, do

pytestmark = pytest.mark.timeout(180)


def test_a_pause_on_the_ground_is_slept_through_and_ends_on_time(make_sim: SimFactory) -> None:
    sim = make_sim(speedup=1)
    sim.start(TelemetrySink())
    before = sim.wakeups
    t0 = time.monotonic()
    assert do(sim, "PauseFor", 2.0).ok
    wall = time.monotonic() - t0
    woke = sim.wakeups - before
    # Stepping would wake every MIN_WALL_TICK_S: ~400 times in 2 s.
    assert woke < 0.1 * 2.0 / MIN_WALL_TICK_S, woke
    assert 1.9 <= wall < 10.0
    assert sim.sim_time_s == pytest.approx(wall, abs=0.5)


def test_a_request_wakes_a_resting_vehicle_at_once(make_sim: SimFactory) -> None:
    sim = make_sim(speedup=1, arm_delay_s=0.0)
    sim.start(TelemetrySink())
    pause = Done()
    sim.run(cmd("PauseFor", 60.0), pause)  # rests for a simulated minute
    t0 = time.monotonic()
    assert do(sim, "Arm").ok  # not after the pause: now
    assert time.monotonic() - t0 < 5.0
    assert not pause.is_done
    sim.close()
    assert pause.wait().status == "cancelled"


def test_hovering_rests_yet_telemetry_and_the_log_show_every_change(
    make_sim: SimFactory, tmp_path: object
) -> None:
    sink = TelemetrySink()
    sim = make_sim(speedup=20, arm_delay_s=0.0, drain_airborne_pct_per_min=6.0)
    sim.start(sink)
    assert do(sim, "Arm").ok
    assert do(sim, "Takeoff", 5.0).ok
    shown = sink.count()
    before = sim.wakeups
    assert do(sim, "Hold", 40.0).ok  # 40 simulated s: 2 s of wall time at speedup 20
    woke = sim.wakeups - before
    # Stepping wakes every MIN_WALL_TICK_S; resting wakes a few times per shown 0.1 %.
    assert woke < 0.5 * (40.0 / 20) / MIN_WALL_TICK_S, woke
    # 6 %/min for 40 s drains 4 %: a sample for each 0.1 % the battery showed.
    batteries = [s.battery_pct for s in sink.snapshot()[shown:]]
    assert len(batteries) >= 38
    assert {round(a - b, 1) for a, b in itertools.pairwise(batteries)} == {0.1}
    lines = read_log(tmp_path / "D1-adapter.log")  # type: ignore[operator]
    [end] = [e for e in lines if e["event"] == "adapter.action.end" and e["action"] == "Hold"]
    assert end["duration_sim_s"] == pytest.approx(40.0, abs=0.05)
