"""The simulated MAVLink vehicle's core and personalities, driven by hand: no socket, no thread.

Messages are plain objects with the fields pymavlink would give; ``send`` records
what the vehicle would put on the wire.  Time advances one ``step()`` at a time.
"""

from __future__ import annotations

import math
from typing import Any

import pytest

from eamos.hal.sim.core import SIM_DT_S
from eamos.hal.sitl.core import VehicleCore
from eamos.hal.sitl.inbox import Inbox
from eamos.hal.sitl.vehicle import PERSONALITIES
from eamos.hal.sitl.wire import (
    ACCEPTED,
    DENIED,
    FAILED,
    TEMPORARILY_REJECTED,
    VehicleOptions,
)
from eamos.logs import make_logger

ARM, SET_MODE, TAKEOFF, LAND = 400, 176, 22, 21


class Msg:
    """A received message: its type name, source and fields."""

    def __init__(self, kind: str, **fields: Any) -> None:
        self._kind = kind
        fields.setdefault("target_system", 1)
        fields.setdefault("target_component", 1)
        self.__dict__.update(fields)

    def get_type(self) -> str:
        return self._kind

    def get_srcSystem(self) -> int:
        return 255

    def get_srcComponent(self) -> int:
        return 190


def command(cmd: int, *params: float) -> Msg:
    p = list(params) + [math.nan] * (7 - len(params))
    return Msg("COMMAND_LONG", command=cmd, **{f"param{i + 1}": p[i] for i in range(7)})


class Rig:
    def __init__(self, autopilot: str, **options: Any) -> None:
        self.sent: list[tuple[Any, ...]] = []
        self.wall = 0.0
        opts = VehicleOptions(autopilot, "udpout:127.0.0.1:1", **options)  # type: ignore[arg-type]
        self.core = VehicleCore(
            opts,
            PERSONALITIES[autopilot](),
            make_logger(None),
            lambda name, *args: self.sent.append((name, *args)),
            wall=lambda: self.wall,
        )
        self.inbox = Inbox(self.core)

    def run_s(self, seconds: float) -> None:
        for _ in range(round(seconds / SIM_DT_S)):
            self.core.step()
            self.wall += SIM_DT_S

    def ask(self, msg: Msg) -> int:
        self.inbox.handle(msg)
        acks = [m for m in self.sent if m[0] == "command_ack"]
        return int(acks[-1][2])

    def texts(self) -> str:
        """Every STATUSTEXT sent, chunks joined (a long text goes out in pieces)."""
        return "".join(m[2].decode() for m in self.sent if m[0] == "statustext")


@pytest.mark.parametrize(
    ("autopilot", "result", "text"),
    [
        ("px4", TEMPORARILY_REJECTED, "Arming denied: Resolve system health failures first"),
        ("ardupilot", FAILED, "Arm: EKF3 still initialising"),
    ],
)
def test_arming_too_early_is_refused_in_each_autopilots_words(
    autopilot: str, result: int, text: str
) -> None:
    rig = Rig(autopilot, prearm_delay_s=3.0)
    rig.run_s(2.0)
    assert rig.ask(command(ARM, 1.0)) == result
    assert text in rig.texts()
    assert not rig.core.armed
    rig.run_s(1.5)
    assert rig.ask(command(ARM, 1.0)) == ACCEPTED
    assert rig.core.armed


def test_boot_modes_and_ardupilot_ready() -> None:
    px4, ardu = Rig("px4"), Rig("ardupilot")
    assert (px4.core.mode, ardu.core.mode) == ("HOLD", "STABILIZE")
    ardu.run_s(2.0)
    assert "ArduPilot Ready" in ardu.texts()
    assert "ArduPilot Ready" not in Rig("px4").texts()


def test_takeoff_differs_px4_auto_takeoff_against_ardupilot_guided() -> None:
    px4 = Rig("px4", prearm_delay_s=0.0)
    px4.run_s(1.5)
    assert px4.ask(command(ARM, 1.0)) == ACCEPTED
    assert px4.ask(command(TAKEOFF, 0, 0, 0, 0, 0, 0, 450.0 + 3.0)) == ACCEPTED
    assert px4.core.mode == "AUTO.TAKEOFF"
    px4.run_s(8.0)
    assert px4.core.mode == "HOLD"  # take-off complete
    assert px4.core.model.position[2] == pytest.approx(3.0, abs=0.1)

    ardu = Rig("ardupilot", prearm_delay_s=0.0)
    ardu.run_s(1.5)
    assert ardu.ask(command(ARM, 1.0)) == ACCEPTED
    assert ardu.ask(command(TAKEOFF, 0, 0, 0, 0, 0, 0, 3.0)) == FAILED  # not GUIDED
    guided = 4.0  # ArduCopter's GUIDED mode number
    assert ardu.ask(command(SET_MODE, 1.0, guided)) == ACCEPTED
    assert ardu.ask(command(TAKEOFF, 0, 0, 0, 0, 0, 0, 3.0)) == ACCEPTED
    ardu.run_s(6.0)
    assert ardu.core.model.position[2] == pytest.approx(3.0, abs=0.1)


def test_refusals_answer_denied_on_px4_and_failed_on_ardupilot() -> None:
    for autopilot, refused in (("px4", DENIED), ("ardupilot", FAILED)):
        rig = Rig(autopilot)
        assert rig.ask(command(LAND)) == refused, autopilot  # not armed


def test_px4_offboard_failsafe_and_recovery() -> None:
    rig = Rig("px4", prearm_delay_s=0.0)
    rig.run_s(1.5)
    target = Msg(
        "SET_POSITION_TARGET_LOCAL_NED",
        type_mask=0,
        coordinate_frame=1,
        x=0.0,
        y=0.0,
        z=1.5 - 2.0,
    )
    rig.inbox.handle(target)
    assert rig.ask(command(SET_MODE, 1.0, 6.0, 0.0)) == ACCEPTED  # OFFBOARD
    assert rig.ask(command(ARM, 1.0)) == ACCEPTED
    rig.run_s(3.0)  # no more setpoints: failsafe into HOLD
    assert rig.core.mode == "HOLD"
    assert "Failsafe activated" in rig.texts()
    rig.inbox.handle(target)
    assert rig.core.mode == "OFFBOARD"  # back by itself once setpoints resume


def test_parameters_use_each_autopilots_wire_encoding() -> None:
    px4, ardu = Rig("px4"), Rig("ardupilot")
    assert "MIS_TAKEOFF_ALT" in px4.core.params.snapshot()
    assert "SYSID_THISMAV" in ardu.core.params.snapshot()
    px4.inbox.handle(Msg("PARAM_REQUEST_READ", param_id=b"MAV_SYS_ID", param_index=-1))
    (_, _, wire, ptype, _, _) = px4.sent[-1]
    assert ptype == 6 and wire != 1.0  # INT32 carried byte-wise in the float
    ardu.inbox.handle(Msg("PARAM_REQUEST_READ", param_id=b"SYSID_THISMAV", param_index=-1))
    assert ardu.sent[-1][2] == 1.0
