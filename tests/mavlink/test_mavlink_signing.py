"""MAVLink 2 signing (issue 16, item 8): keys, both ends signing, unsigned or wrong ignored."""

from __future__ import annotations

import os
import stat
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from eamos.hal.api import AdapterError
from eamos.hal.mavlink.signing import (
    SIGNING_EPOCH_S,
    SigningKeyError,
    create_signing_key,
    parse_key,
    radio_status_only,
    read_key,
    refresh_timestamp,
    signing_timestamp,
)

from .mavlink_helpers import RawClient, connections

pytestmark = [pytest.mark.e2e, pytest.mark.timeout(180)]

ARM = 400
KEY = bytes(range(32))
OTHER = bytes(range(1, 33))


def key_file(tmp_path: Path, key: bytes, name: str = "k.key") -> Path:
    path = tmp_path / name
    path.write_text(key.hex() + "\n")
    path.chmod(0o600)
    return path


# -- pure parts --------------------------------------------------------------------------------


def test_keys_parse_from_hex_or_base64_and_nothing_else():
    import base64

    assert parse_key(KEY.hex()) == KEY
    assert parse_key(base64.b64encode(KEY).decode() + "\n") == KEY
    for bad in ("", "abc", KEY.hex()[:-2], "zz" * 32, base64.b64encode(KEY[:16]).decode()):
        with pytest.raises(ValueError, match="expected 32 bytes"):
            parse_key(bad)


def test_key_files_must_be_private(tmp_path):
    path = key_file(tmp_path, KEY)
    assert read_key(path) == KEY
    path.chmod(0o644)
    with pytest.raises(SigningKeyError, match=r"readable by others .*chmod 600"):
        read_key(path)
    with pytest.raises(SigningKeyError, match="cannot read the signing key"):
        read_key(tmp_path / "missing.key")


def test_created_keys_are_random_private_and_kept(tmp_path):
    path = create_signing_key(tmp_path)
    assert stat.S_IMODE(path.stat().st_mode) == 0o600
    first = read_key(path)
    with pytest.raises(FileExistsError):
        create_signing_key(tmp_path)
    assert read_key(create_signing_key(tmp_path, force=True)) != first


def test_timestamps_follow_the_clock_and_never_go_back():
    class Mav:
        class signing:  # pymavlink's attribute name
            timestamp = 0

    assert signing_timestamp(SIGNING_EPOCH_S + 1.5) == 150_000
    refresh_timestamp(Mav, SIGNING_EPOCH_S + 10)
    assert Mav.signing.timestamp == 1_000_000
    refresh_timestamp(Mav, SIGNING_EPOCH_S + 5)  # a clock step back: keep counting up
    assert Mav.signing.timestamp == 1_000_000
    assert radio_status_only(None, 109) and not radio_status_only(None, 0)


def test_eamos_keys_writes_the_signing_key_beside_the_curve_keys(tmp_path):
    out = tmp_path / "keys"
    proc = subprocess.run(
        [sys.executable, "-m", "eamos.cli", "keys", str(out), "--fleet", "D1", "D2"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert proc.returncode == 0, proc.stderr
    path = out / "mavlink_signing.key"
    assert len(read_key(path)) == 32
    assert stat.S_IMODE(os.stat(path).st_mode) == 0o600
    assert "signing_key" in proc.stdout and path.read_text().strip() not in proc.stdout


# -- on the wire ---------------------------------------------------------------------------------


def test_signed_flight_and_unsigned_or_wrong_commands_ignored(flight, tmp_path, raw_client):
    path = key_file(tmp_path, KEY)
    f = flight("px4", vehicle={"signing_key": KEY, "speedup": 4.0}, signing_key=str(path))
    f.airborne(1.5)
    assert f.vehicle.signing
    # Another client without the key (or with the wrong one): the vehicle ignores it.
    for key in (None, OTHER):
        refused = f.vehicle.refused
        # Straight at the vehicle's own UDP port (PX4 style: it sends from there).
        port = f.vehicle.address[1]
        intruder = RawClient(f"udpout:127.0.0.1:{port}")
        try:
            if key is not None:
                intruder.conn.setup_signing(key, sign_outgoing=True)
            intruder.mav.command_long_send(1, 1, ARM, 0, 0, 21196, 0, 0, 0, 0, 0)  # force disarm
            assert f.vehicle.wait_until(lambda v, r=refused: v.refused > r, 30)
            assert f.vehicle.armed
            assert intruder.count("COMMAND_ACK") == 0
        finally:
            intruder.close()
    f.ok("Land")
    f.ok("Disarm")
    log = (tmp_path / "D1-adapter.log").read_text()
    assert KEY.hex() not in log


def test_adapter_refuses_an_unsigned_or_wrongly_signed_vehicle_and_says_why(
    make_vehicle, make_adapter, tmp_path
):
    path = key_file(tmp_path, KEY)
    for autopilot, vehicle_key, why in (
        ("px4", None, r"signing required, the vehicle sends unsigned messages.*PX4 has no"),
        ("ardupilot", None, r"signing required, the vehicle sends unsigned messages"),
        ("px4", OTHER, r"signs its messages with another key than hal\.signing_key"),
    ):
        _, conn = make_vehicle(autopilot, signing_key=vehicle_key)
        adapter = make_adapter(conn, signing_key=str(path), connect_timeout_s=20.0)
        t0 = time.monotonic()
        with pytest.raises(AdapterError, match=why):
            adapter.start(lambda s: None)
        # Refused on the vehicle's first heartbeats, not at the connect timeout.
        assert time.monotonic() - t0 < 10
        assert adapter.facts()["signed"] is False


def test_signing_off_flies_unsigned_and_says_so(flight, tmp_path):
    path = key_file(tmp_path, KEY)
    f = flight("px4", signing_key=str(path), signing="off")
    f.ok("Arm")
    f.ok("Disarm")
    assert f.adapter.facts()["signed"] is False


def test_setup_that_never_signs_stops_the_run_within_its_bound(make_adapter, tmp_path):
    """A vehicle that ignores SETUP_SIGNING (PX4 main) is refused after signing_timeout_s."""
    path = key_file(tmp_path, KEY)
    vehicle_conn, conn = connections("px4")
    stop = threading.Event()
    # A PX4-like vehicle that only ever sends unsigned HEARTBEATs (SETUP_SIGNING ignored).
    px4 = RawClient(vehicle_conn, sysid=1)
    px4.conn.mav.srcComponent = 1

    def beat() -> None:
        while not stop.wait(0.1):
            px4.mav.heartbeat_send(2, 12, 0, 0, 3)

    beater = threading.Thread(target=beat, daemon=True)
    beater.start()
    try:
        adapter = make_adapter(
            conn, signing_key=str(path), signing_setup=True, signing_timeout_s=2.0
        )
        t0 = time.monotonic()
        with pytest.raises(AdapterError, match=r"signing setup failed: .*unsigned.*PX4 has no"):
            adapter.start(lambda s: None)
        assert 2.0 <= time.monotonic() - t0 < 10
        assert px4.count("SETUP_SIGNING") >= 1  # it was asked, and it never signed
    finally:
        stop.set()
        beater.join(5)
        px4.close()


def test_setup_signing_provisions_the_vehicle(flight, tmp_path):
    path = key_file(tmp_path, KEY)
    f = flight("px4", signing_key=str(path), signing_setup=True)
    assert f.vehicle.wait_until(lambda v: v.signing, 30)
    assert f.adapter.facts()["signed"] is True  # start() returned once the vehicle signed
    f.ok("Arm")  # signed both ways from here on
    f.ok("Disarm")


def test_bad_signing_settings_are_config_errors(make_adapter, tmp_path):
    loose = key_file(tmp_path, KEY)
    loose.chmod(0o644)
    with pytest.raises(AdapterError, match=r"hal\.signing_key: .*readable by others"):
        make_adapter("udpin:127.0.0.1:14999", signing_key=str(loose))
    with pytest.raises(AdapterError, match=r"hal\.signing_key: expected a file path"):
        make_adapter("udpin:127.0.0.1:14999", signing_key=3)
