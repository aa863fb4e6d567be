"""The simulated vehicle against the SITL notes, driven by a plain pymavlink client."""

from __future__ import annotations

import itertools
import signal
import socket
import statistics
import struct
import subprocess
import sys
import threading
import time

import pytest

from eamos.ground.vehicles import free_port
from eamos.hal.sitl.vehicle import (
    ACCEPTED,
    DENIED,
    FAILED,
    TEMPORARILY_REJECTED,
    UNSUPPORTED,
    SimVehicle,
    VehicleOptions,
)

from .mavlink_helpers import WAIT_S, RawClient, connections

pytestmark = [pytest.mark.e2e, pytest.mark.timeout(120)]

ARM, SET_MODE, TAKEOFF, LAND = 400, 176, 22, 21
SET_INTERVAL, REQUEST_MESSAGE = 511, 512
PREARM = 0x10000000
HOLD, OFFBOARD, AUTO_LAND = 0x03040000, 0x00060000, 0x06040000
LOCAL_NED = 1
POSITION_MASK = 0x0FF8


def start(make_vehicle, raw_client, autopilot, **options):
    vehicle, conn = make_vehicle(autopilot, **options)
    client = raw_client(conn)
    client.heartbeat()  # a TCP or UDP peer learns of us
    return vehicle, client


def test_px4_heartbeat_and_boot_mode(make_vehicle, raw_client):
    _vehicle, client = start(make_vehicle, raw_client, "px4", sysid=3, speedup=2.0)
    hb = client.wait("HEARTBEAT", lambda m: m.get_srcSystem() == 3)
    assert (hb.autopilot, hb.type, hb.get_srcComponent()) == (12, 2, 1)
    assert hb.custom_mode == HOLD and hb.base_mode & 1 and not hb.base_mode & 128
    # PX4 streams on its onboard link without being asked.
    client.wait("LOCAL_POSITION_NED")
    client.wait("SYS_STATUS")
    assert hb.get_msgbuf()[0] == 0xFD  # MAVLink 2 magic


def test_ardupilot_heartbeat_and_quiet_link(make_vehicle, raw_client):
    _vehicle, client = start(make_vehicle, raw_client, "ardupilot", speedup=2.0)
    hb = client.wait("HEARTBEAT")
    assert (hb.autopilot, hb.type, hb.custom_mode) == (3, 2, 0)  # STABILIZE
    client.wait("HEARTBEAT", after=2)
    # Nothing until asked (ArduCopter SITL on SERIAL0: HEARTBEAT and STATUSTEXT only).
    assert client.count("LOCAL_POSITION_NED") == 0
    assert client.count("SYS_STATUS") == 0
    client.mav.request_data_stream_send(1, 1, 6, 4, 1)  # MAV_DATA_STREAM_POSITION at 4 Hz
    client.wait("GLOBAL_POSITION_INT")
    client.wait("LOCAL_POSITION_NED")


def test_ardupilot_mode_set_during_boot_is_overwritten(make_vehicle, raw_client):
    _vehicle, client = start(make_vehicle, raw_client, "ardupilot", speedup=1.0)
    assert client.command(SET_MODE, 1, 4) == ACCEPTED  # GUIDED, before "ArduPilot Ready"
    client.wait("TEXT", lambda t: t == "ArduPilot Ready")
    seen = client.count("HEARTBEAT")
    assert client.wait("HEARTBEAT", after=seen).custom_mode == 0  # back to STABILIZE
    assert client.command(SET_MODE, 1, 4) == ACCEPTED
    assert client.wait("HEARTBEAT", lambda m: m.custom_mode == 4)


@pytest.mark.parametrize(
    ("autopilot", "result", "text"),
    [
        ("px4", TEMPORARILY_REJECTED, "Arming denied: Resolve system health failures first"),
        ("ardupilot", FAILED, "Arm: EKF3 still initialising"),
    ],
)
def test_arming_before_pre_arm_checks_pass(make_vehicle, raw_client, autopilot, result, text):
    vehicle, client = start(make_vehicle, raw_client, autopilot, prearm_delay_s=float("inf"))
    client.wait("HEARTBEAT")
    if autopilot == "ardupilot":
        client.wait("TEXT", lambda t: t == "ArduPilot Ready")
        client.mav.request_data_stream_send(1, 1, 2, 2, 1)  # EXTENDED_STATUS: SYS_STATUS
    status = client.wait("SYS_STATUS")
    assert status.onboard_control_sensors_present & PREARM
    assert not status.onboard_control_sensors_health & PREARM
    assert client.command(ARM, 1) == result
    client.wait("TEXT", lambda t: t == text)  # 51 characters: PX4 sends it in two chunks
    assert not vehicle.armed


def test_pre_arm_bit_appears_after_the_delay(make_vehicle, raw_client):
    vehicle, client = start(make_vehicle, raw_client, "px4", prearm_delay_s=3.0, speedup=3.0)
    first = client.wait("SYS_STATUS")
    assert not first.onboard_control_sensors_health & PREARM
    client.wait("SYS_STATUS", lambda m: m.onboard_control_sensors_health & PREARM)
    assert vehicle.sim_time_s >= 3.0
    assert client.command(ARM, 1) == ACCEPTED
    client.wait("HEARTBEAT", lambda m: m.base_mode & 128)
    client.wait("TEXT", lambda t: t == "Armed by external command")


def test_commands_and_intervals(make_vehicle, raw_client):
    _vehicle, client = start(make_vehicle, raw_client, "px4", speedup=2.0)
    client.wait("HEARTBEAT")
    assert client.command(183, 1, 1500) == UNSUPPORTED  # MAV_CMD_DO_SET_SERVO: not here
    assert client.command(SET_INTERVAL, 0, 100_000) == FAILED  # HEARTBEAT stays at 1 Hz
    assert client.command(SET_INTERVAL, 32, 50_000) == ACCEPTED  # LOCAL_POSITION_NED 20 Hz
    seen = client.count("LOCAL_POSITION_NED")
    client.wait("LOCAL_POSITION_NED", after=seen + 30)
    with client._cond:
        stamps = [m.time_boot_ms for m in client.messages["LOCAL_POSITION_NED"][seen + 5 :]]
    # Rates are in simulated time (time_boot_ms): 50 ms apart.
    assert statistics.median(b - a for a, b in itertools.pairwise(stamps)) == pytest.approx(
        50, abs=12
    )
    assert client.command(SET_INTERVAL, 32, -1) == ACCEPTED  # off
    assert client.command(REQUEST_MESSAGE, 148) == ACCEPTED
    version = client.wait("AUTOPILOT_VERSION")
    assert version.capabilities & 0x2000 and version.capabilities & 0x10  # MAVLink 2, byte-wise
    assert client.command(410) == ACCEPTED  # MAV_CMD_GET_HOME_POSITION
    home = client.wait("HOME_POSITION")
    assert home.latitude == round(46.6103 * 1e7) and home.altitude == 450_000


def test_parameters_px4_bytewise(make_vehicle, raw_client):
    vehicle, client = start(make_vehicle, raw_client, "px4")
    client.wait("HEARTBEAT")
    client.mav.param_request_read_send(1, 1, b"COM_OBL_RC_ACT", -1)
    value = client.wait("PARAM_VALUE", lambda m: m.param_id == "COM_OBL_RC_ACT")
    assert value.param_type == 6  # INT32, carried byte-wise in the float
    assert struct.unpack("<i", struct.pack("<f", value.param_value))[0] == 5
    client.mav.param_set_send(1, 1, b"MIS_TAKEOFF_ALT", 4.0, 9)
    client.wait("PARAM_VALUE", lambda m: m.param_id == "MIS_TAKEOFF_ALT" and m.param_value == 4.0)
    seen = client.count("PARAM_VALUE")
    client.mav.param_request_list_send(1, 1)
    last = client.wait("PARAM_VALUE", lambda m: m.param_index == m.param_count - 1, after=seen)
    assert last.param_count == len(vehicle.params)


def test_px4_offboard_rules_and_failsafe(make_vehicle, raw_client):
    vehicle, client = start(make_vehicle, raw_client, "px4", speedup=2.0)
    client.wait("SYS_STATUS", lambda m: m.onboard_control_sensors_health & PREARM)
    # On the ground, disarmed: OFFBOARD is accepted without a stream, but then
    # the vehicle is not armable any more and arming is refused.
    assert client.command(SET_MODE, 1, 6) == ACCEPTED
    client.wait("SYS_STATUS", lambda m: not m.onboard_control_sensors_health & PREARM)
    assert client.command(ARM, 1) == TEMPORARILY_REJECTED

    ground = client.wait("LOCAL_POSITION_NED")
    stream = {"z": ground.z}
    paused = threading.Event()
    halt = threading.Event()

    def streamer() -> None:
        # The client's own 20 Hz setpoint stream, paced by the halt event.
        while not halt.wait(0.05):
            if not paused.is_set():
                client.mav.set_position_target_local_ned_send(
                    0, 1, 1, LOCAL_NED, POSITION_MASK, 0.0, 0.0, stream["z"], 0, 0, 0, 0, 0, 0, 0, 0
                )

    thread = threading.Thread(target=streamer, daemon=True)
    thread.start()
    try:
        client.wait(
            "SYS_STATUS",
            lambda m: m.onboard_control_sensors_health & PREARM,
            after=client.count("SYS_STATUS"),
        )
        assert client.command(ARM, 1) == ACCEPTED
        stream["z"] = ground.z - 3.0  # 3 m up (NED)
        assert vehicle.wait_until(lambda v: v.position[2] > 2.8, WAIT_S)
        # Setpoints stop: after COM_OF_LOSS_T the failsafe holds position.
        paused.set()
        client.wait("TEXT", lambda t: t.startswith("Failsafe activated"))
        client.wait("HEARTBEAT", lambda m: m.custom_mode == HOLD)
        # Switching back to OFFBOARD in the air without a stream is refused...
        assert client.command(SET_MODE, 1, 6) == TEMPORARILY_REJECTED
        client.wait("TEXT", lambda t: "Offboard is currently not available" in t)
        # ...and the vehicle returns to OFFBOARD by itself once setpoints resume.
        paused.clear()
        client.wait(
            "HEARTBEAT", lambda m: m.custom_mode == OFFBOARD, after=client.count("HEARTBEAT")
        )
        # Disarming in the air is denied; landing is not.
        assert client.command(ARM, 0) == DENIED
        client.wait("TEXT", lambda t: t == "Disarming denied: not landed")
        assert client.command(LAND, 0, 0, 0, float("nan")) == ACCEPTED
        client.wait("HEARTBEAT", lambda m: m.custom_mode == AUTO_LAND)
        client.wait("TEXT", lambda t: t == "Landing detected")
        t_down = vehicle.sim_time_s
        client.wait("TEXT", lambda t: t == "Disarmed by landing")
        assert vehicle.sim_time_s - t_down == pytest.approx(2.0, abs=1.0)
        assert client.wait("EXTENDED_SYS_STATE", lambda m: m.landed_state == 1)
    finally:
        halt.set()
        thread.join(5)


def test_ardupilot_takeoff_needs_guided(make_vehicle, raw_client):
    vehicle, client = start(make_vehicle, raw_client, "ardupilot", speedup=2.0)
    client.wait("TEXT", lambda t: t == "EKF3 IMU0 is using GPS")
    assert client.command(ARM, 1) == ACCEPTED  # arming in STABILIZE works...
    assert client.command(TAKEOFF, 0, 0, 0, 0, 0, 0, 3.0) == FAILED  # ...taking off does not
    assert client.command(SET_MODE, 1, 4) == ACCEPTED
    assert client.command(TAKEOFF, 0, 0, 0, 0, 0, 0, 3.0) == ACCEPTED
    assert vehicle.wait_until(lambda v: v.position[2] > 2.9, WAIT_S)
    assert client.command(LAND) == ACCEPTED
    client.wait("TEXT", lambda t: t == "Disarming motors")
    assert vehicle.mode == "LAND" and not vehicle.armed


def test_auto_disarm_without_takeoff(make_vehicle, raw_client):
    vehicle, client = start(make_vehicle, raw_client, "px4", disarm_after_s=2.0, speedup=2.0)
    client.wait("SYS_STATUS", lambda m: m.onboard_control_sensors_health & PREARM)
    assert client.command(ARM, 1) == ACCEPTED
    t_armed = vehicle.sim_time_s
    client.wait("TEXT", lambda t: t == "Disarmed by auto preflight disarming")
    assert vehicle.sim_time_s - t_armed == pytest.approx(2.0, abs=1.0)


def test_tcp_vehicle_accepts_a_new_client(make_vehicle, raw_client):
    _vehicle, conn = make_vehicle("ardupilot")
    first = raw_client(conn)
    first.heartbeat()
    first.wait("HEARTBEAT")
    first.close()
    second = raw_client(conn)  # ArduPilot SITL takes a reconnecting GCS
    second.heartbeat()
    assert second.command(ARM, 0) == ACCEPTED


def test_two_tcp_clients_at_once(make_vehicle, raw_client):
    vehicle, conn = make_vehicle("ardupilot", speedup=2.0)
    first, second = raw_client(conn), RawClient(conn, sysid=251)
    first.heartbeat()
    second.heartbeat()
    assert vehicle.wait_until(lambda v: v.clients == 2, WAIT_S)
    first.wait("HEARTBEAT")
    second.wait("HEARTBEAT")
    # One link shared by every client (as behind MAVProxy): rates are the vehicle's.
    first.mav.request_data_stream_send(1, 1, 6, 4, 1)
    second.wait("LOCAL_POSITION_NED")
    # A command's acknowledgement goes to the client that sent it only.
    assert second.command(ARM, 0) == ACCEPTED
    first.wait("HEARTBEAT", after=first.count("HEARTBEAT") + 1)
    assert first.count("COMMAND_ACK") == 0
    first.close()  # one leaves, the other stays served
    try:
        assert vehicle.wait_until(lambda v: v.clients == 1, WAIT_S)
        after = second.count("HEARTBEAT")
        second.wait("HEARTBEAT", after=after + 1)
    finally:
        second.close()


@pytest.mark.parametrize("autopilot", ["px4", "ardupilot"])
def test_a_second_client_watches_a_flight_without_disturbing_it(flight, autopilot):
    f = flight(autopilot, vehicle={"speedup": 4.0})
    host, port = f.vehicle.address
    # ArduPilot style: another TCP client on the same port; PX4 style: a peer that sends
    # to the vehicle's own UDP port and is answered from then on.
    watcher = RawClient(
        f"tcp:{host}:{port}" if autopilot == "ardupilot" else f"udpout:{host}:{port}"
    )
    try:
        watcher.heartbeat()
        assert f.vehicle.wait_until(lambda v: v.clients == 2, WAIT_S)
        f.airborne(2.0)
        f.ok("FlyByX", 3.0)
        seen = watcher.wait("LOCAL_POSITION_NED", lambda m: m.x > 2.9)
        assert abs(seen.y) < 0.2
        f.ok("Land")
        f.wait_vehicle(lambda v: not v.armed)
        watcher.wait("HEARTBEAT", lambda m: not m.base_mode & 128)
        # It saw the flight, sent no command, and got none of the adapter's acknowledgements.
        assert watcher.count("COMMAND_ACK") == 0
        assert f.vehicle.position[0] == pytest.approx(3.0, abs=0.3)
    finally:
        watcher.close()


# -- the command line ------------------------------------------------------------------------


def vehicle_cli(*args: str) -> subprocess.Popen[str]:
    return subprocess.Popen(
        [sys.executable, "-m", "eamos.cli.sim_vehicle", *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT])
def test_cli_runs_and_stops_cleanly(tmp_path, sig):
    vehicle_conn, client_conn = connections("px4")
    client = RawClient(client_conn)
    log = tmp_path / "v.log"
    proc = vehicle_cli(
        "--autopilot",
        "px4",
        "--connection",
        vehicle_conn,
        "--sysid",
        "7",
        "--speedup",
        "4",
        "--reject",
        "MAV_CMD_NAV_TAKEOFF=FAILED",
        "--log",
        str(log),
    )
    try:
        hb = client.wait("HEARTBEAT", lambda m: m.get_srcSystem() == 7, timeout=30)
        assert hb.autopilot == 12
        client.heartbeat()
        assert client.command(TAKEOFF, target=7) == FAILED
        proc.send_signal(sig)
        out, err = proc.communicate(timeout=15)
    finally:
        if proc.poll() is None:
            proc.kill()
        client.close()
    assert proc.returncode == 0, err
    assert "px4 sysid 7 on udpout" in out
    assert '"event": "vehicle.stop"' in log.read_text()


def test_cli_rejects_bad_arguments():
    proc = vehicle_cli(
        "--autopilot", "px4", "--connection", "udpout:127.0.0.1:9", "--reject", "MAV_CMD_WARP_DRIVE"
    )
    _, err = proc.communicate(timeout=30)
    assert proc.returncode == 2 and "unknown MAVLink command 'MAV_CMD_WARP_DRIVE'" in err
    proc = vehicle_cli("--autopilot", "inav", "--connection", "udpout:127.0.0.1:9")
    _, err = proc.communicate(timeout=30)
    assert proc.returncode == 2 and "invalid choice: 'inav'" in err


def test_cli_port_in_use():
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen(1)
        port = taken.getsockname()[1]
        proc = vehicle_cli("--autopilot", "ardupilot", "--connection", f"tcpin:127.0.0.1:{port}")
        _, err = proc.communicate(timeout=30)
    assert proc.returncode == 3 and f"cannot open tcpin:127.0.0.1:{port}" in err


def test_vehicle_options_are_checked():
    with pytest.raises(ValueError, match="connection must be udpout:, udpin: or tcpin:"):
        VehicleOptions("px4", "tcp:127.0.0.1:5760")
    with pytest.raises(ValueError, match="autopilot must be px4 or ardupilot"):
        VehicleOptions("betaflight", "udpout:127.0.0.1:14540")  # type: ignore[arg-type]
    port = free_port(socket.SOCK_DGRAM)
    with SimVehicle(VehicleOptions("px4", f"udpout:127.0.0.1:{port}")) as vehicle:
        assert vehicle.mode == "HOLD" and not vehicle.armed
    assert time.monotonic() > 0
