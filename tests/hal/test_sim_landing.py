"""The simulated autopilot disarms by itself after landing, as PX4 and ArduCopter do.

PX4 "Disarmed by landing" COM_DISARM_LAND (2 s) after landing; ArduCopter about
2 s after "Land complete" (both seen on the SITLs, docs/flying-real-drones.md).  Stepped
by hand: exact simulated times.
"""

from __future__ import annotations

import pytest

from eamos.hal.api import AdapterError
from eamos.hal.sim.core import SIM_DT_S
from eamos.hal.sim.landing import DISARM_AFTER_LANDING_S, LandingDisarm
from eamos.hal.sim.settings import SimSettings
from eamos.program.uniform import Arm, Disarm, Land, PauseFor, Takeoff

from .test_hal_sim_core import Rig


def land_and_watch(rig: Rig) -> float:
    """Take off, land; the simulated time the Land action ended."""
    rig.airborne(2.0)
    assert rig.do("land", Land()).ok
    return rig.core.t_s


def test_it_disarms_two_simulated_seconds_after_touchdown() -> None:
    rig = Rig()
    landed_at = land_and_watch(rig)
    assert rig.core.state().armed and rig.core.settling
    # Still armed one step before the delay is up, disarmed at it.
    while rig.core.t_s < landed_at + DISARM_AFTER_LANDING_S - SIM_DT_S - 1e-9:
        rig.step()
        assert rig.core.state().armed
    rig.step()
    assert not rig.core.state().armed and not rig.core.settling
    (event,) = rig.log.of("adapter.disarm_after_landing")
    assert event["t_sim"] == pytest.approx(landed_at + DISARM_AFTER_LANDING_S, abs=1e-9)
    # The telemetry shows it: the last sample is landed and disarmed.
    for _ in range(10):
        rig.step()
    assert rig.samples[-1].landed and not rig.samples[-1].armed


def test_the_delay_is_a_setting_and_zero_turns_it_off() -> None:
    rig = Rig(disarm_after_landing_s=5.0)
    landed_at = land_and_watch(rig)
    while rig.core.state().armed:
        rig.step()
    assert rig.core.t_s == pytest.approx(landed_at + 5.0, abs=1e-9)

    off = Rig(disarm_after_landing_s=0)
    land_and_watch(off)
    assert not off.core.settling
    for _ in range(round(30 / SIM_DT_S)):
        off.step()
    assert off.core.state().armed and off.log.of("adapter.disarm_after_landing") == []


def test_armed_on_the_ground_without_a_flight_stays_armed() -> None:
    rig = Rig()
    assert rig.do("arm", Arm()).ok
    assert rig.do("land", Land()).ok  # already on the ground: no landing
    for _ in range(round(10 / SIM_DT_S)):
        rig.step()
    assert rig.core.state().armed and not rig.core.settling


def test_a_take_off_before_the_delay_cancels_the_disarm() -> None:
    rig = Rig()
    land_and_watch(rig)
    assert rig.do("again", Takeoff(2.0)).ok  # within the 2 s: still armed
    for _ in range(round(5 / SIM_DT_S)):
        rig.step()
    st = rig.core.state()
    assert st.armed and not st.landed and not rig.core.settling


def test_an_explicit_disarm_ends_the_wait_and_a_late_take_off_needs_arm() -> None:
    rig = Rig()
    land_and_watch(rig)
    assert rig.do("disarm", Disarm()).ok and not rig.core.settling
    rig2 = Rig()
    land_and_watch(rig2)
    assert rig2.do("pause", PauseFor(3.0)).ok
    result = rig2.do("late", Takeoff(2.0))
    assert result.status == "failed" and "not armed" in result.reason


def test_idle_steps_stop_short_of_the_disarm() -> None:
    rig = Rig()
    landed_at = land_and_watch(rig)
    for _ in range(20):
        rig.step()  # let the last sample and position line out
    idle = rig.core.idle_steps(10_000)
    assert 0 < idle < round(DISARM_AFTER_LANDING_S / SIM_DT_S)
    rig.core.skip(idle)
    assert rig.core.state().armed
    rig.step()
    assert not rig.core.state().armed
    assert rig.core.t_s == pytest.approx(landed_at + DISARM_AFTER_LANDING_S, abs=1e-9)


def test_the_rule_alone() -> None:
    rule = LandingDisarm.of(2.0, SIM_DT_S)
    assert rule.delay_steps == 100
    assert not rule.update(5, was_landed=False, landed=True, armed=True)  # touchdown
    assert rule.due_step == 105 and rule.idle_limit(5) == 99
    assert not rule.update(104, True, True, True)
    assert rule.update(105, True, True, True) and not rule.pending
    assert LandingDisarm.of(0.0, SIM_DT_S).delay_steps is None


def test_a_negative_delay_is_refused_naming_the_setting() -> None:
    with pytest.raises(AdapterError, match="disarm_after_landing_s"):
        SimSettings.from_mapping({"disarm_after_landing_s": -1})
    assert SimSettings.from_mapping({}).disarm_after_landing_s == DISARM_AFTER_LANDING_S
