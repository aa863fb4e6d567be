"""Security: fleet keys, CURVE links, the ZAP authenticator, plain only on loopback.

Intruders here have their own keys (a second ``eamos keys`` run with the same
participant names) and know everything public: the endpoints, the fleet's
public keys, the mission id and the wire format.
"""

from __future__ import annotations

import os
import stat
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
import zmq

from eamos.actors.runtime import DroneRuntime, DroneRuntimeError, NetSettings
from eamos.compiler import compile_mission
from eamos.config import ConfigError, NodeConfig
from eamos.hal.fake import FakeAdapter
from eamos.logs import close_logger, make_logger, read_log
from eamos.net import InBridge, OutBridge, wire
from eamos.net.keys import (
    FleetAuthenticator,
    FleetKeys,
    KeysError,
    create_fleet_keys,
    is_local_endpoint,
    plain_refusal,
)

from .link_helpers import MISSION, WAIT_S, Inbox, eventually, free_port, network, trig

pytestmark = pytest.mark.timeout(120)
REPO = Path(__file__).resolve().parents[2]


# -- keys ---------------------------------------------------------------------------


def test_keys_layout_permissions_and_loading(tmp_path: Path) -> None:
    out = create_fleet_keys(tmp_path / "k", ["GCS", "D1", "D2"])
    assert stat.S_IMODE(os.stat(out / "D1").st_mode) == 0o700
    assert sorted(p.name for p in (out / "public").iterdir()) == ["D1.key", "D2.key", "GCS.key"]
    for name in ("GCS", "D1", "D2"):
        secret = out / name / f"{name}.key_secret"
        assert stat.S_IMODE(secret.stat().st_mode) == 0o600
        assert not (out / "public" / f"{name}.key_secret").exists()
        assert sorted(p.name for p in (out / name / "public").iterdir()) == [
            "D1.key",
            "D2.key",
            "GCS.key",
        ]
    mine = FleetKeys.load(out / "D1", "D1")
    assert mine.me == "D1" and set(mine.fleet) == {"GCS", "D1", "D2"}
    assert mine.fleet["D1"] == mine.public and len(mine.secret) == 40
    assert mine.missing(["D2", "D9"]) == ["D9"]
    assert "secret" not in repr(mine) or mine.secret.decode() not in repr(mine)
    # The whole folder works too (the ground station may keep it all).
    assert FleetKeys.load(out, "D2").public == FleetKeys.load(out / "D2", "D2").public
    with pytest.raises(KeysError, match="already exist"):
        create_fleet_keys(out, ["D1"])
    again = create_fleet_keys(out, ["GCS", "D1", "D2"], force=True)
    assert FleetKeys.load(again / "D1", "D1").public != mine.public


def test_bad_key_folders_are_clear_errors(tmp_path: Path) -> None:
    keys = create_fleet_keys(tmp_path / "k", ["D1", "D2"])
    with pytest.raises(KeysError, match=r"no D1\.key_secret"):
        FleetKeys.load(keys / "D2", "D1")  # D2's folder shipped to D1
    with pytest.raises(KeysError, match="no such key folder"):
        FleetKeys.load(tmp_path / "nowhere", "D1")
    (keys / "D2" / "D2.key_secret").rename(keys / "D2" / "D1.key_secret")
    with pytest.raises(KeysError, match="does not match"):
        FleetKeys.load(keys / "D2", "D1")  # a pair that is not the fleet's D1
    (keys / "D1" / "D1.key_secret").write_text("junk")
    with pytest.raises(KeysError, match=r"D1\.key_secret"):
        FleetKeys.load(keys / "D1", "D1")


@pytest.mark.parametrize(
    ("endpoint", "local"),
    [
        ("tcp://127.0.0.1:6000", True),
        ("tcp://127.3.4.5:1", True),
        ("tcp://[::1]:6000", True),
        ("tcp://localhost:6000", True),
        ("inproc://x", True),
        ("ipc:///tmp/x", True),
        ("tcp://0.0.0.0:6000", False),
        ("tcp://*:6000", False),
        ("tcp://192.168.1.10:6000", False),
        ("tcp://drone1.local:6000", False),
        ("tcp://eth0:6000", False),
        ("nonsense", False),
    ],
)
def test_local_endpoints(endpoint: str, local: bool) -> None:
    assert is_local_endpoint(endpoint) is local
    assert (plain_refusal([endpoint]) is None) is local


def test_eamos_keys_command(tmp_path: Path) -> None:
    def eamos(*args: str) -> subprocess.CompletedProcess[str]:
        return subprocess.run(
            [sys.executable, "-m", "eamos.cli", "keys", *args],
            capture_output=True,
            text=True,
            timeout=60,
            cwd=REPO,
        )

    proc = eamos(str(tmp_path / "fleet"), "--fleet", "Drone1", "Drone2")
    assert proc.returncode == 0, proc.stderr
    assert {p.name for p in (tmp_path / "fleet").iterdir()} == {
        "public",
        "GCS",
        "Drone1",
        "Drone2",
        "mavlink_signing.key",  # MAVLink 2 signing: 32 bytes as hex, for the owner only
    }
    signing = tmp_path / "fleet" / "mavlink_signing.key"
    assert signing.stat().st_mode & 0o777 == 0o600
    assert len(bytes.fromhex(signing.read_text().strip())) == 32
    assert eamos(str(tmp_path / "fleet"), "--fleet", "Drone1").returncode == 2
    # From a compiled mission: the participants are its programs.
    compiled = compile_mission("func SEQ_M() {\n D1.Arm()\n D2.Arm()\n}\n", "m.go")
    (tmp_path / "out" / "programs").mkdir(parents=True)
    for name, program in compiled.programs.items():
        program.save(tmp_path / "out" / "programs" / f"{name}.program.json")
    proc = eamos(str(tmp_path / "out"))
    assert proc.returncode == 0, proc.stderr
    assert {p.name for p in (tmp_path / "out" / "keys").iterdir()} == {
        "public",
        "GCS",
        "D1",
        "D2",
        "mavlink_signing.key",
    }
    proc = eamos(str(tmp_path / "empty"))
    assert proc.returncode == 2 and "compile the mission first" in proc.stderr
    assert "Traceback" not in proc.stderr


# -- CURVE links ----------------------------------------------------------------------


def test_fleet_links_are_encrypted_and_reliable(tmp_path: Path) -> None:
    with network(tmp_path) as net:
        net.keys(["A", "B"])
        inbox = Inbox()
        net.link("B", ["A"], inbox, secure=True)
        a = net.link("A", ["B"], secure=True)
        assert a.wait_subscribed([wire.topic_to("B")], WAIT_S)
        for n in range(20):
            a.send(trig("A", "B", n))
        assert inbox.wait(lambda items: len(items) >= 20)
        assert a.flush(WAIT_S)
        assert a.secure and a.stats()["secure"] and a.stats()["auth_denied"] == 0


def test_intruder_with_its_own_keys_gets_nothing_in_or_out(tmp_path: Path) -> None:
    """An intruder knows the endpoints and public keys, but holds no fleet secret key."""
    log = make_logger(tmp_path / "b.log", drone="B")
    fleet = create_fleet_keys(tmp_path / "fleet", ["A", "B"])
    evil = FleetKeys.load(create_fleet_keys(tmp_path / "evil", ["A", "B"]) / "A", "A")
    real_b = FleetKeys.load(fleet / "B", "B")
    # It dresses up as A with the fleet's public keys (so it knows B's server key).
    intruder_keys = FleetKeys("A", evil.public, evil.secret, dict(real_b.fleet))
    try:
        with network(tmp_path) as net:
            net.keys_dir = fleet
            inbox = Inbox()
            b = net.link("B", ["A"], inbox, secure=True, log=log)
            # 1. As a client of B's Out-Bridge: ZAP refuses its key, it never subscribes.
            ctx: zmq.Context[Any] = zmq.Context()
            eaves = Inbox()
            spy = InBridge(
                ctx, {"B": net.endpoints["B"]}, [b""], eaves, MISSION, curve=intruder_keys
            )
            spy.start()
            assert eventually(lambda: b.auth is not None and b.auth.denied >= 1)
            assert not b.wait_subscribed([b""], 0.5)
            b.send(trig("B", "A", 0))
            # 2. At A's address (A is down, or its traffic is redirected): B's client
            # expects A's public key, the handshake fails, forged triggers go nowhere.
            impostor = OutBridge(ctx, net.endpoints["A"], None, curve=intruder_keys)
            impostor.start()
            for n in range(50):
                impostor.send(trig("A", "B", n))
                impostor.send(wire.Abort(MISSION, "A", "forged"))
            assert eventually(lambda: b.inb is not None and b.inb.auth_failures >= 1)
            assert not impostor.wait_subscribed([wire.topic_to("B")], 0.5)
            assert eaves.items == [] and inbox.of(wire.Trigger) == [] and inbox.of(wire.Abort) == []
            spy.close()
            impostor.close()
            ctx.destroy(linger=0)
    finally:
        close_logger(log)
    events = read_log(tmp_path / "b.log")
    denied = [e for e in events if e["event"] == "net.auth.denied"]
    assert denied and denied[0]["key"] == intruder_keys.public.decode()
    assert any(e["event"] == "net.auth.failed" and e["peer"] == "A" for e in events)


def test_plain_peer_cannot_connect_to_a_curve_fleet(tmp_path: Path) -> None:
    with network(tmp_path) as net:
        net.keys(["A", "B"])
        a = net.link("A", ["B"], secure=True)
        ctx: zmq.Context[Any] = zmq.Context()
        inbox = Inbox()
        plain_in = InBridge(ctx, {"A": net.endpoints["A"]}, [b""], inbox, MISSION)
        plain_in.start()
        plain_out = OutBridge(ctx, net.endpoints["B"], None)  # plain, at B's address
        plain_out.start()
        assert not a.wait_subscribed([b""], 1.0)
        a.send(wire.Start(MISSION, "A"))
        for n in range(20):
            plain_out.send(trig("B", "A", n))
        assert eventually(lambda: a.out.auth_failures >= 1)
        assert not plain_out.wait_subscribed([wire.topic_to("A")], 0.5)
        assert inbox.items == []
        plain_in.close()
        plain_out.close()
        ctx.destroy(linger=0)


def test_a_fleet_member_cannot_speak_for_another(tmp_path: Path) -> None:
    """CURVE proves which peer a socket talks to; the In-Bridge checks ``sender`` against it."""
    keys = create_fleet_keys(tmp_path / "k", ["D1", "D2", "D3"])
    ctx3: zmq.Context[Any] = zmq.Context()
    ctx2: zmq.Context[Any] = zmq.Context()
    auth3 = FleetAuthenticator(ctx3, FleetKeys.load(keys / "D3", "D3"))
    d3 = OutBridge(
        ctx3, f"tcp://127.0.0.1:{free_port()}", None, curve=FleetKeys.load(keys / "D3", "D3")
    )
    d3.start()
    inbox = Inbox()
    d2 = InBridge(
        ctx2,
        {"D3": d3.endpoint},
        [wire.topic_to("D2")],
        inbox,
        MISSION,
        curve=FleetKeys.load(keys / "D2", "D2"),
        check_sender=True,
    )
    d2.start()
    try:
        assert d3.wait_subscribed([wire.topic_to("D2")], WAIT_S)
        d3.send(trig("D1", "D2", 0))  # D3 claims to be D1
        d3.send(trig("D3", "D2", 1))
        assert inbox.wait(lambda items: len(items) >= 1)
        assert [m.sender for m in inbox.items] == ["D3"]
        assert d2.dropped_by_reason == {"sender": 1}
    finally:
        d2.close()
        d3.close()
        auth3.stop()
        ctx2.destroy(linger=0)
        ctx3.destroy(linger=0)


def test_one_authenticator_per_context(tmp_path: Path) -> None:
    keys = FleetKeys.load(create_fleet_keys(tmp_path / "k", ["D1"]) / "D1", "D1")
    ctx: zmq.Context[Any] = zmq.Context()
    first = FleetAuthenticator(ctx, keys)
    try:
        with pytest.raises(KeysError, match="one CURVE participant per ZeroMQ context"):
            FleetAuthenticator(ctx, keys)
    finally:
        first.stop()
        first.stop()
        ctx.destroy(linger=0)


def test_a_curve_server_without_zap_handler_admits_nobody(tmp_path: Path) -> None:
    keys = create_fleet_keys(tmp_path / "k", ["D1", "D2"])
    ctx: zmq.Context[Any] = zmq.Context()
    server = OutBridge(ctx, "tcp://127.0.0.1:0", None, curve=FleetKeys.load(keys / "D1", "D1"))
    server.start()
    client = InBridge(
        ctx,
        {"D1": server.endpoint},
        [b"all"],
        Inbox(),
        MISSION,
        curve=FleetKeys.load(keys / "D2", "D2"),
    )
    client.start()
    try:
        assert not server.wait_subscribed([b"all"], 1.0)  # fails closed, not open
    finally:
        client.close()
        server.close()
        ctx.destroy(linger=0)


# -- the plain-on-loopback rule at every entry --------------------------------------------


PROGRAM = compile_mission("func SEQ_M() {\n D1.Arm()\n}\n", "m.go").programs["D1"]


@pytest.mark.parametrize(
    ("net", "why"),
    [
        (NetSettings("tcp://0.0.0.0:0", {}), "only allowed on loopback"),
        (NetSettings("tcp://127.0.0.1:0", {"GCS": "tcp://10.1.2.3:6000"}), "10.1.2.3"),
    ],
)
def test_runtime_refuses_plain_off_loopback(net: NetSettings, why: str) -> None:
    runtime = DroneRuntime(PROGRAM, FakeAdapter("D1", auto=True), net)
    with pytest.raises(DroneRuntimeError, match=why):
        runtime.start()


def test_runtime_refuses_someone_elses_keys(tmp_path: Path) -> None:
    keys = create_fleet_keys(tmp_path / "k", ["GCS", "D1", "D2"])
    net = NetSettings(
        "tcp://127.0.0.1:0", {"GCS": "tcp://127.0.0.1:1"}, keys=FleetKeys.load(keys / "D2", "D2")
    )
    with pytest.raises(DroneRuntimeError, match="D2's, not D1's"):
        DroneRuntime(PROGRAM, FakeAdapter("D1", auto=True), net).start()


def write_config(tmp_path: Path, net: str) -> Path:
    path = tmp_path / "D1.toml"
    path.write_text(
        f'drone = "D1"\nprogram = "p.json"\n[net]\n{net}\n[net.peers]\nGCS = "tcp://127.0.0.1:6000"\n'
    )
    return path


@pytest.mark.parametrize(
    ("net", "why"),
    [
        ('bind = "tcp://127.0.0.1:6001"', "net.keys: required"),
        ('bind = "tcp://0.0.0.0:6001"\nplain = true', "net.plain: plain .* loopback"),
        ('bind = "tcp://127.0.0.1:6001"\nplain = "yes"', "net.plain: must be true or false"),
        ('bind = "tcp://127.0.0.1:6001"\nplain = true\nkeys = "k/D1"', "cannot be combined"),
        ('bind = "tcp://127.0.0.1:6001"\nkeys = "nowhere"', "net.keys: .*no such key folder"),
        ('bind = "tcp://127.0.0.1:6001"\nkeys = "k/D1"\nheartbeat_s = 0', "net.heartbeat_s"),
        (
            'bind = "tcp://127.0.0.1:6001"\nkeys = "k/D1"\nheartbeat_s = 2\npeer_timeout_s = 1',
            "net.peer_timeout_s",
        ),
        ('bind = "tcp://127.0.0.1:6001"\nkeys = "k/D1"\npeer_timout_s = 1', "did you mean"),
        ('bind = "tcp://127.0.0.1:6001"\nkeys = "other/D1"', "no public key for peer.*GCS"),
    ],
)
def test_config_errors_name_the_field(tmp_path: Path, net: str, why: str) -> None:
    create_fleet_keys(tmp_path / "k", ["GCS", "D1"])
    create_fleet_keys(tmp_path / "other", ["D1"])
    with pytest.raises(ConfigError, match=why):
        NodeConfig.load(write_config(tmp_path, net))


def test_config_with_keys_and_link_settings(tmp_path: Path) -> None:
    create_fleet_keys(tmp_path / "k", ["GCS", "D1"])
    config = NodeConfig.load(
        write_config(
            tmp_path,
            'bind = "tcp://0.0.0.0:6001"\nkeys = "k/D1"\npeer_timeout_s = 5\n'
            "telemetry_stale_s = 4\npeer_give_up_s = 20",
        )
    )
    assert config.keys is not None and config.keys.me == "D1"
    assert config.keys_dir == (tmp_path / "k" / "D1").resolve()
    assert config.link.peer_timeout_s == 5 and config.link.telemetry_stale_s == 4
    assert config.peer_give_up_s == 20
    plain = NodeConfig.load(write_config(tmp_path, 'bind = "tcp://127.0.0.1:6001"\nplain = true'))
    assert plain.keys is None


def test_participants_sharing_a_context_share_its_zap_handler(tmp_path: Path) -> None:
    # Two participants' Out-Bridges on one context, one ZapHandler: each admits the
    # fleet in its own ZAP domain, and a refused key is counted by the one it knocked on.
    from eamos.net.zap import ZapHandler

    fleet = create_fleet_keys(tmp_path / "fleet", ["D1", "D2", "GCS"])
    keys = {n: FleetKeys.load(fleet / n, n) for n in ("D1", "D2", "GCS")}
    evil = FleetKeys.load(create_fleet_keys(tmp_path / "evil", ["GCS"]) / "GCS", "GCS")
    intruder = FleetKeys("GCS", evil.public, evil.secret, dict(keys["GCS"].fleet))
    shared: zmq.Context[Any] = zmq.Context()
    client: zmq.Context[Any] = zmq.Context()
    zap = ZapHandler(shared)
    auths = {d: FleetAuthenticator(shared, keys[d], zap=zap) for d in ("D1", "D2")}
    outs = {d: OutBridge(shared, "tcp://127.0.0.1:0", None, curve=keys[d]) for d in auths}
    ins: list[InBridge] = []
    try:
        for out in outs.values():
            out.start()
        for d, out in outs.items():
            ins.append(
                InBridge(client, {d: out.endpoint}, [b""], Inbox(), MISSION, curve=keys["GCS"])
            )
        ins.append(
            InBridge(client, {"D2": outs["D2"].endpoint}, [b"x"], Inbox(), MISSION, curve=intruder)
        )
        for inb in ins:
            inb.start()
        assert outs["D1"].wait_subscribed([b""], WAIT_S)
        assert outs["D2"].wait_subscribed([b""], WAIT_S)
        assert eventually(lambda: auths["D2"].denied >= 1)
        assert auths["D1"].denied == 0  # the refusal is D2's alone
    finally:
        for inb in ins:
            inb.close()
        for out in outs.values():
            out.close()
        for auth in auths.values():
            auth.stop()
        zap.stop()
        shared.destroy(linger=0)
        client.destroy(linger=0)
