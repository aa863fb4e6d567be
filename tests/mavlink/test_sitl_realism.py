"""The simulated vehicle fails the way real autopilots did (issue 16, item 7), driven by hand.

No socket, no thread: messages are plain objects, time advances one step at a time
(see test_sim_vehicle_core).  Figures come from the SITL notes in the shared notes.
"""

from __future__ import annotations

import math
import statistics

import pytest

from eamos.hal.sitl.ardupilot import BRAKE_DECEL_MPS2
from eamos.hal.sitl.core import LAND_DECEL_MPS2, stopping_point

from .test_sim_vehicle_core import ACCEPTED, ARM, SET_MODE, TAKEOFF, Msg, Rig, command

GUIDED, BRAKE, LAND_MODE = 4.0, 17.0, 9.0
LOCAL_NED, POSITION_ONLY, VELOCITY_ONLY = 1, 0x0FF8, 0x0DC7


def target(x: float, y: float, z_ned: float, mask: int = POSITION_ONLY, **v: float) -> Msg:
    return Msg(
        "SET_POSITION_TARGET_LOCAL_NED",
        type_mask=mask,
        coordinate_frame=LOCAL_NED,
        x=x,
        y=y,
        z=z_ned,
        vx=v.get("vx", 0.0),
        vy=v.get("vy", 0.0),
        vz=v.get("vz", 0.0),
    )


def airborne(autopilot: str, **options: object) -> Rig:
    """A vehicle hovering 5 m up in GUIDED / OFFBOARD with its own default parameters."""
    rig = Rig(autopilot, prearm_delay_s=0.0, **options)
    rig.run_s(1.5)
    offset = rig.core.offset_m
    if autopilot == "ardupilot":
        assert rig.ask(command(SET_MODE, 1.0, GUIDED)) == ACCEPTED
        assert rig.ask(command(ARM, 1.0)) == ACCEPTED
        assert rig.ask(command(TAKEOFF, 0, 0, 0, 0, 0, 0, 5.0)) == ACCEPTED
    else:
        rig.inbox.handle(target(0.0, 0.0, offset - 5.0))
        assert rig.ask(command(SET_MODE, 1.0, 6.0, 0.0)) == ACCEPTED
        assert rig.ask(command(ARM, 1.0)) == ACCEPTED
    for _ in range(60):
        rig.inbox.handle(target(0.0, 0.0, offset - 5.0))
        rig.run_s(0.25)
    assert rig.core.model.position[2] == pytest.approx(5.0, abs=0.05)
    return rig


def cruise(rig: Rig, x: float) -> float:
    """Fly north towards ``x`` (streaming the target) until the speed stops growing."""
    offset = rig.core.offset_m
    top = 0.0
    for _ in range(200):
        rig.inbox.handle(target(x, 0.0, offset - 5.0))
        rig.run_s(0.05)
        speed = rig.core.model.state.speed_mps
        if speed <= top and speed > 0.5:
            return speed
        top = max(top, speed)
    raise AssertionError("never reached a cruise speed")


@pytest.mark.parametrize(("autopilot", "speed"), [("ardupilot", 5.0), ("px4", 6.0)])
def test_position_targets_fly_at_the_autopilots_own_speed(autopilot: str, speed: float) -> None:
    rig = airborne(autopilot)
    assert cruise(rig, 60.0) == pytest.approx(speed, abs=0.05)


@pytest.mark.parametrize(
    ("autopilot", "name", "value", "speed"),
    [("ardupilot", "WPNAV_SPEED", 200.0, 2.0), ("px4", "MPC_XY_VEL_MAX", 2.0, 2.0)],
)
def test_speed_parameters_are_obeyed(autopilot: str, name: str, value: float, speed: float) -> None:
    rig = airborne(autopilot)
    rig.inbox.handle(Msg("PARAM_SET", param_id=name.encode(), param_value=value))
    assert cruise(rig, 60.0) == pytest.approx(speed, abs=0.05)


def overshoot_after(rig: Rig, stop: Msg | None) -> float:
    """Distance travelled north from the moment of ``stop`` (None: a target at "here")."""
    x0 = rig.core.model.position[0]
    offset = rig.core.offset_m
    rig.inbox.handle(stop if stop is not None else target(x0, 0.0, offset - 5.0))
    furthest = x0
    for _ in range(400):
        rig.run_s(0.05)
        furthest = max(furthest, rig.core.model.position[0])
    return furthest - x0


def test_a_target_at_here_overshoots_while_brake_mode_stops_short() -> None:
    rig = airborne("ardupilot")
    v = cruise(rig, 80.0)
    # WPNAV_ACCEL 250 cm/s/s: v^2 / 5 = 5 m past "here", then back.
    assert overshoot_after(rig, None) == pytest.approx(v * v / 5.0, abs=0.3)
    rig = airborne("ardupilot")
    v = cruise(rig, 80.0)
    braked = overshoot_after(rig, command(SET_MODE, 1.0, BRAKE))
    assert braked == pytest.approx(v * v / (2 * BRAKE_DECEL_MPS2), abs=0.3)  # 1.7 m
    assert rig.core.mode == "BRAKE"


def test_px4_zero_velocity_setpoint_stops_at_mpc_acc_hor_max() -> None:
    rig = airborne("px4")
    v = cruise(rig, 80.0)
    stop = target(0.0, 0.0, 0.0, VELOCITY_ONLY)
    assert overshoot_after(rig, stop) == pytest.approx(v * v / 10.0, abs=0.3)  # 3.6 m


@pytest.mark.parametrize(("autopilot", "land"), [("ardupilot", (LAND_MODE,)), ("px4", (4.0, 6.0))])
def test_land_while_moving_brakes_gently(autopilot: str, land: tuple[float, ...]) -> None:
    rig = airborne(autopilot)
    v = cruise(rig, 80.0)
    travelled = overshoot_after(rig, command(SET_MODE, 1.0, *land))
    # The notes: ArduCopter touched down ~10 m beyond at 5 m/s, PX4 ~14 m at 6 m/s.
    assert travelled == pytest.approx(v * v / (2 * LAND_DECEL_MPS2), abs=0.3)
    assert rig.core.model.landed


def test_stopping_point_is_pure() -> None:
    assert stopping_point((1.0, 0.0, 5.0), (4.0, -2.0, 0.0), 2.0) == (5.0, -1.0, 5.0)


@pytest.mark.parametrize(
    ("autopilot", "name"), [("px4", "COM_DISARM_PRFLT"), ("ardupilot", "DISARM_DELAY")]
)
def test_preflight_auto_disarm_follows_its_parameter(autopilot: str, name: str) -> None:
    rig = Rig(autopilot, prearm_delay_s=0.0)
    rig.run_s(1.5)
    if autopilot == "ardupilot":
        rig.ask(command(SET_MODE, 1.0, GUIDED))
    assert rig.ask(command(ARM, 1.0)) == ACCEPTED
    rig.run_s(10.5)
    assert not rig.core.armed  # the default: 10 s
    rig.inbox.handle(Msg("PARAM_SET", param_id=name.encode(), param_value=0.0))
    assert rig.ask(command(ARM, 1.0)) == ACCEPTED
    rig.run_s(30.0)
    assert rig.core.armed  # 0: never


def test_wandering_estimate_is_seeded_and_sih_like() -> None:
    def hover_ys(seed: int) -> list[float]:
        rig = airborne("px4", wander_m=0.3, seed=seed)
        ys = []
        for _ in range(600):
            rig.run_s(0.1)
            rig.core.streams.send_message(32, rig.core.status())
            ys.append(rig.sent[-1][3])  # LOCAL_POSITION_NED y
        assert rig.core.model.position[1] == 0.0  # the truth does not move
        return ys

    first, again, other = hover_ys(7), hover_ys(7), hover_ys(8)
    assert first == again and first != other
    assert 0.1 < statistics.pstdev(first) < 0.6
    assert max(map(abs, first)) < 1.5
    assert not math.isclose(min(first), max(first))
