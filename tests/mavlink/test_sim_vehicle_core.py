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

    def __getattr__(self, name: str) -> Any:
        """A field the message was not given (mypy: fields are set dynamically)."""
        raise AttributeError(name)

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
    px4.run_s(5.0)  # the motors spool up first (MPC_TKO_RAMP_T + 2 s, as on PX4 main SITL)
    assert px4.core.model.landed
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
    ardu.run_s(3.5)  # ArduCopter SITL left the ground 3.6 s after NAV_TAKEOFF
    assert ardu.core.model.landed
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


# -- the mission protocol, the fence, coordinates out of range ------------------------------

REPOSITION, FENCE_ENABLE_CMD = 192, 207
GUIDED_MODE = 4.0
CLIENT = (255, 190)  # Msg's source


def mission_item(seq: int, x: int, y: int, z: float = 5.0, **extra: Any) -> Msg:
    fields: dict[str, Any] = {
        "seq": seq,
        "frame": 6,
        "command": 16,
        "current": 0,
        "autocontinue": 1,
        "param1": 0.0,
        "param2": 0.0,
        "param3": 0.0,
        "param4": math.nan,
        "x": x,
        "y": y,
        "z": z,
        "mission_type": 0,
    }
    fields.update(extra)
    return Msg("MISSION_ITEM_INT", **fields)


def upload(rig: Rig, items: list[Msg], mission_type: int = 0) -> list[tuple[Any, ...]]:
    """Upload ``items`` the way a client does (answering each request); what the vehicle sent."""
    start = len(rig.sent)
    rig.inbox.handle(Msg("MISSION_COUNT", count=len(items), mission_type=mission_type))
    answered = 0
    while True:
        replies = [m for m in rig.sent[start:] if m[0].startswith("mission_")]
        last = replies[-1]
        if last[0] == "mission_ack" or answered > len(items):
            return replies
        if last[0] == "mission_request":  # MAVSDK's NACK: "use the _INT messages"
            rig.inbox.handle(Msg("MISSION_ACK", type=3, mission_type=mission_type))
            continue
        rig.inbox.handle(items[last[3]])
        answered += 1


def local_lla(rig: Rig, x: float, y: float) -> tuple[int, int]:
    lat, lon, _ = rig.core.frame.to_lla(x, y, 0.0)
    return round(lat * 1e7), round(lon * 1e7)


def fence_square(rig: Rig, half: float) -> list[Msg]:
    corners = [(-half, -half), (half, -half), (half, half), (-half, half)]
    return [
        mission_item(
            i, *local_lla(rig, x, y), 0.0, command=5001, param1=4.0, frame=5, mission_type=1
        )
        for i, (x, y) in enumerate(corners)
    ]


@pytest.mark.parametrize("autopilot", ["px4", "ardupilot"])
def test_mission_upload_download_and_clear(autopilot: str) -> None:
    rig = Rig(autopilot)
    items = [mission_item(i, *local_lla(rig, 10.0 * i, 0.0)) for i in range(3)]
    replies = upload(rig, items)
    kinds = [m[0] for m in replies]
    # ArduCopter asks with MISSION_REQUEST; after MAVSDK's NACK both ask with _INT.
    assert kinds[0] == "mission_request" and kinds[-1] == "mission_ack"
    assert "mission_request_int" in kinds
    assert replies[-1][3] == 0  # MAV_MISSION_ACCEPTED, to the client (255, 190)
    assert replies[-1][1:3] == CLIENT
    assert len(rig.core.missions.items(0)) == 3
    rig.sent.clear()
    rig.inbox.handle(Msg("MISSION_REQUEST_LIST", mission_type=0))
    assert rig.sent[-1][0] == "mission_count" and rig.sent[-1][3] == 3
    rig.inbox.handle(Msg("MISSION_REQUEST_INT", seq=0, mission_type=0))
    first = rig.sent[-1]
    if autopilot == "ardupilot":
        # Item 0 is its home, frame GLOBAL; the rest without _INT frames.
        assert (first[4], first[5], first[12], first[14]) == (0, 16, round(46.6103 * 1e7), 450.0)
    else:
        assert (first[4], first[6], first[12]) == (6, 1, items[0].x)  # as sent, current
    rig.inbox.handle(Msg("MISSION_REQUEST_INT", seq=2, mission_type=0))
    assert rig.sent[-1][12] == items[2].x
    assert rig.sent[-1][4] == (3 if autopilot == "ardupilot" else 6)
    rig.inbox.handle(Msg("MISSION_REQUEST_INT", seq=3, mission_type=0))
    assert rig.sent[-1][0] == "mission_ack" and rig.sent[-1][3] == 13  # INVALID_SEQUENCE
    rig.inbox.handle(Msg("MISSION_SET_CURRENT", seq=1))
    assert rig.sent[-1][:3] == ("mission_current", 1, 3)
    rig.inbox.handle(Msg("MISSION_CLEAR_ALL", mission_type=255))
    assert rig.sent[-1][0] == "mission_ack" and rig.sent[-1][3] == 0
    assert rig.core.missions.items(0) == []


@pytest.mark.parametrize(("autopilot", "stored"), [("px4", True), ("ardupilot", False)])
def test_an_item_out_of_range_is_refused_by_ardupilot_only(autopilot: str, stored: bool) -> None:
    rig = Rig(autopilot)
    good = [mission_item(i, *local_lla(rig, 5.0 * i, 0.0)) for i in range(2)]
    upload(rig, good)
    bad = [good[0], mission_item(1, -(2**31), good[1].y)]  # latitude -214.7 degrees
    replies = upload(rig, bad)
    if stored:  # PX4 main stores it (observed on its SITL)
        assert replies[-1][3] == 0 and rig.core.missions.items(0)[1].x == -(2**31)
    else:  # ArduCopter: MAV_MISSION_INVALID_PARAM5_X, the old mission kept
        assert replies[-1][3] == 10 and rig.core.missions.items(0)[1].x == good[1].x


def test_an_unanswered_upload_is_asked_again_then_given_up() -> None:
    rig = Rig("px4")
    rig.inbox.handle(Msg("MISSION_COUNT", count=2, mission_type=0))
    rig.run_s(10.0)  # the rig's wall clock follows simulated time
    requests = [m for m in rig.sent if m[0].startswith("mission_request")]
    assert len(requests) == 6  # the first and 5 repeats
    assert rig.sent[[m[0] for m in rig.sent].index("mission_ack")][3] == 15  # cancelled
    assert not rig.core.missions.uploading


def airborne(rig: Rig, autopilot: str, height: float = 5.0) -> None:
    rig.run_s(3.5)  # past the pre-arm delay
    if autopilot == "ardupilot":
        assert rig.ask(command(SET_MODE, 1.0, GUIDED_MODE)) == ACCEPTED
        assert rig.ask(command(ARM, 1.0)) == ACCEPTED
        assert rig.ask(command(TAKEOFF, 0, 0, 0, 0, 0, 0, height)) == ACCEPTED
    else:
        home_alt = rig.core.options.home[2]
        assert rig.ask(command(TAKEOFF, 0, 0, 0, 0, 0, 0, home_alt + height)) == ACCEPTED
        assert rig.ask(command(ARM, 1.0)) == ACCEPTED
    rig.run_s(12.0)
    assert rig.core.model.position[2] == pytest.approx(height, abs=0.1)


def fly_to(rig: Rig, autopilot: str, x: float, seconds: float) -> None:
    """Fly north to ``x`` (ArduPilot GUIDED targets; PX4 DO_REPOSITION in HOLD)."""
    if autopilot == "ardupilot":
        for _ in range(round(seconds)):
            rig.inbox.handle(
                Msg(
                    "SET_POSITION_TARGET_LOCAL_NED",
                    coordinate_frame=1,
                    type_mask=0x0FF8,
                    x=x,
                    y=0.0,
                    z=-5.0 + rig.core.offset_m,
                    yaw=0.0,
                    vx=0.0,
                    vy=0.0,
                    vz=0.0,
                )
            )
            rig.run_s(1.0)
    else:
        lat, lon = local_lla(rig, x, 0.0)
        rig.inbox.handle(
            Msg(
                "COMMAND_INT",
                command=REPOSITION,
                frame=6,
                param1=-1.0,
                param2=0.0,
                param3=0.0,
                param4=math.nan,
                x=lat,
                y=lon,
                z=5.0,
            )
        )
        rig.run_s(seconds)


@pytest.mark.parametrize(("autopilot", "mode"), [("px4", "HOLD"), ("ardupilot", "RTL")])
def test_a_geofence_breach_gets_each_autopilots_default_action(autopilot: str, mode: str) -> None:
    rig = Rig(autopilot)
    assert upload(rig, fence_square(rig, 15.0), mission_type=1)[-1][3] == 0
    assert len(rig.core.geofence.inclusion) == 1
    if autopilot == "ardupilot":
        assert rig.core.outside_fence((30.0, 0.0, 5.0)) is None  # FENCE_ENABLE 0: not enforced
        rig.inbox.handle(Msg("PARAM_SET", param_id=b"FENCE_ENABLE", param_value=1.0))
    airborne(rig, autopilot)
    if autopilot == "ardupilot":
        # ArduCopter refuses a GUIDED target outside its fence: it stays.
        fly_to(rig, autopilot, 30.0, 5.0)
        assert rig.core.model.position[0] == pytest.approx(0.0, abs=0.1)
        rig.inbox.handle(Msg("PARAM_SET", param_id=b"FENCE_ENABLE", param_value=0.0))
        fly_to(rig, autopilot, 25.0, 10.0)  # out, with the fence off
        rig.inbox.handle(Msg("PARAM_SET", param_id=b"FENCE_ENABLE", param_value=1.0))
        rig.run_s(0.1)
        assert "Polygon fence breached" in rig.texts()
        assert rig.core.mode == mode
        rig.run_s(60.0)  # RTL: home at RTL_ALT, then land and disarm
        assert "Fence breach cleared" in rig.texts()
        assert rig.core.model.landed and not rig.core.armed
        assert math.hypot(*rig.core.model.position[:2]) < 0.5
    else:
        fly_to(rig, autopilot, 30.0, 15.0)
        assert "Geofence violation: approaching or outside geofence" in rig.texts()
        assert rig.core.mode == mode
        x = rig.core.model.position[0]
        assert 15.0 < x < 17.0  # held about where it crossed (PX4 main SITL: 16.3)
        # A ceiling: GF_MAX_VER_DIST.
        rig.inbox.handle(Msg("PARAM_SET", param_id=b"GF_MAX_VER_DIST", param_value=8.0))
        rig.inbox.handle(
            Msg(
                "COMMAND_INT",
                command=REPOSITION,
                frame=6,
                param1=-1.0,
                param2=0.0,
                param3=0.0,
                param4=math.nan,
                x=local_lla(rig, 10.0, 0.0)[0],
                y=local_lla(rig, 10.0, 0.0)[1],
                z=12.0,
            )
        )
        rig.run_s(15.0)
        assert "exceeding maximum altitude above Home" in rig.texts()
        assert rig.core.model.position[2] < 9.5


def test_coordinates_out_of_range_are_refused_as_each_autopilot_does() -> None:
    for autopilot, long_result, int_result in (
        ("ardupilot", 3, DENIED),  # COMMAND_LONG: UNSUPPORTED; COMMAND_INT: DENIED
        ("px4", ACCEPTED, ACCEPTED),  # PX4 main accepts (and flew away); here it stays
    ):
        rig = Rig(autopilot)
        airborne(rig, autopilot)
        _lat, lon = local_lla(rig, 5.0, 0.0)
        assert (
            rig.ask(command(REPOSITION, -1, 1, 0, math.nan, -214.7483648, lon / 1e7, 5.0))
            == long_result
        ), autopilot
        bad = Msg(
            "COMMAND_INT",
            command=REPOSITION,
            frame=6,
            param1=-1.0,
            param2=1.0,
            param3=0.0,
            param4=math.nan,
            x=-(2**31),
            y=lon,
            z=5.0,
        )
        assert rig.ask(bad) == int_result, autopilot
        rig.run_s(5.0)
        assert rig.core.model.position[0] == pytest.approx(0.0, abs=0.1), autopilot
        # A global target out of range is ignored.
        rig.inbox.handle(
            Msg(
                "SET_POSITION_TARGET_GLOBAL_INT",
                coordinate_frame=6,
                type_mask=0x0FF8,
                lat_int=-(2**31),
                lon_int=lon,
                alt=5.0,
            )
        )
        rig.run_s(3.0)
        assert rig.core.model.position[0] == pytest.approx(0.0, abs=0.1), autopilot
