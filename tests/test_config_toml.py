"""``NodeConfig.to_toml()`` writes what ``NodeConfig.load()`` reads back, for any config."""

from __future__ import annotations

import math
import tomllib
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from eamos.config import ConfigError, NodeConfig
from eamos.net.keys import FleetKeys, create_fleet_keys
from eamos.net.link import LinkSettings

# Participant names: identifiers, as in a mission (a config refuses other names).
NAME = st.text(st.characters(exclude_categories=["Cs"]), min_size=1, max_size=10).filter(
    str.isidentifier
)


def seconds(top: int) -> st.SearchStrategy[float | int]:
    """Durations a config accepts for a field whose range ends at ``top`` (config.RANGES)."""
    return st.floats(min_value=0.001, max_value=top) | st.integers(1, top)


SECONDS = seconds(3600)
WAYPOINT = st.fixed_dictionaries(
    {
        "x_m": st.floats(-100, 100) | st.integers(-100, 100),
        "y_m": st.floats(-100, 100),
        "z_m": st.floats(0.5, 100),
    },
    optional={"hold_s": st.floats(0, 60) | st.integers(0, 60)},
)
# A simulated drone's [hal] table (load checks it with the simulator's settings): numbers,
# lists of strings and lists of tables, so to_toml writes every kind of value.
HAL = st.fixed_dictionaries(
    {"adapter": st.just("sim")},
    optional={
        "horizontal_speed_mps": st.floats(0.05, 50) | st.integers(1, 50),
        "telemetry_hz": st.floats(0.1, 50),
        "home_alt_m": st.floats(-1000, 10_000),
        "reject_actions": st.lists(st.sampled_from(["Land", "FlyByX", "Arm"]), max_size=3),
        "pilot": st.lists(WAYPOINT, max_size=3),
        "home_m": st.tuples(st.floats(-1e5, 1e5), st.floats(-1e5, 1e5)).map(list),
    },
)
LOCAL = st.builds(
    lambda host, port: f"tcp://{host}:{port}",
    st.sampled_from(["127.0.0.1", "localhost", "[::1]", "127.3.2.1"]),
    st.integers(1, 65535),
) | st.builds(
    lambda name: f"ipc:///tmp/eamos-{name}", st.from_regex(r"[a-z0-9]{1,8}", fullmatch=True)
)


@st.composite
def link_settings(draw: st.DrawFn) -> LinkSettings:
    heartbeat = draw(st.floats(min_value=0.01, max_value=10))
    peer = heartbeat * draw(st.floats(min_value=1.01, max_value=50))
    stale = heartbeat * draw(st.floats(min_value=1.01, max_value=50))
    hz = draw(st.floats(min_value=0.1, max_value=1000))
    return LinkSettings(
        heartbeat_s=heartbeat, peer_timeout_s=peer, telemetry_stale_s=stale, telemetry_max_hz=hz
    )


@st.composite
def plain_configs(draw: st.DrawFn, folder: Path) -> NodeConfig:
    """A config with plain sockets on loopback (keys are tested apart: they need files)."""
    drone = draw(NAME)
    where = draw(st.sampled_from(["configs", "deep/er/configs", "."]))
    path = folder / where / "node.toml"
    program = draw(st.sampled_from(["programs/X.program.json", "../p.json", "/abs/p q.json"]))
    # An absolute folder of our own: /var/log is writable only by root.
    log_dir = draw(st.sampled_from(["logs/X", "../../logs", str(folder / "var" / "log")]))
    peers = draw(st.dictionaries(NAME, LOCAL, max_size=4))
    give_up = draw(st.none() | seconds(86_400).map(float))
    return NodeConfig(
        path=path,
        drone=drone,
        program=(path.parent / program).resolve(),
        log_dir=(path.parent / log_dir).resolve(),
        bind=draw(LOCAL),
        peers=peers,
        hal=draw(HAL),
        ready_timeout_s=float(draw(seconds(86_400))),
        land_timeout_s=float(draw(SECONDS)),
        mission_timeout_s=float(draw(seconds(604_800))),
        link=draw(st.none() | link_settings()) or LinkSettings(),
        peer_give_up_s=give_up,
    )


def _same(a: Any, b: Any) -> bool:
    """Equality where -0.0 == 0.0 and inf == inf (TOML keeps both), recursively."""
    if isinstance(a, float) and isinstance(b, float):
        return a == b and math.copysign(1, a) == math.copysign(1, b)
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    if isinstance(a, list | tuple) and isinstance(b, list | tuple):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b, strict=True))
    return type(a) is type(b) and a == b


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(data=st.data())
def test_load_of_to_toml_is_the_config(tmp_path_factory: pytest.TempPathFactory, data: Any) -> None:
    folder = tmp_path_factory.mktemp("cfg")
    config = data.draw(plain_configs(folder))
    config.write()
    loaded = NodeConfig.load(config.path)
    assert loaded == config
    assert _same(loaded.hal, config.hal)  # == alone takes 0.0 for -0.0 and 1 for True


def test_keys_round_trip_relative_to_the_config(tmp_path: Path) -> None:
    keys = create_fleet_keys(tmp_path / "keys", ["GCS", "Drone1", "Drone2"])
    path = tmp_path / "run" / "configs" / "Drone1.toml"
    config = NodeConfig(
        path=path,
        drone="Drone1",
        program=(tmp_path / "run" / "programs" / "Drone1.program.json"),
        log_dir=(tmp_path / "run" / "logs" / "Drone1"),
        bind="tcp://198.18.0.2:6001",
        peers={"GCS": "tcp://198.18.0.1:6000", "Drone2": "tcp://198.18.0.3:6002"},
        hal={"adapter": "sim", "pilot": [{"x_m": 0, "y_m": 0, "z_m": 5, "hold_s": 2}]},
        keys_dir=keys / "Drone1",
        keys=FleetKeys.load(keys / "Drone1", "Drone1"),
        peer_give_up_s=30.0,
    )
    text = config.to_toml()
    doc = tomllib.loads(text)
    # Paths are relative to the config's folder, so the folder can move (the roll-out's case).
    assert doc["program"] == "../programs/Drone1.program.json"
    assert doc["log_dir"] == "../logs/Drone1"
    assert doc["net"]["keys"] == "../../keys/Drone1" and "plain" not in doc["net"]
    assert doc["net"]["peers"] == config.peers
    config.write()
    assert NodeConfig.load(path) == config


def test_plain_sockets_off_loopback_do_not_load(tmp_path: Path) -> None:
    # to_toml writes what it is given; load still refuses plain sockets on a network.
    config = NodeConfig(
        path=tmp_path / "n.toml",
        drone="D",
        program=tmp_path / "p.json",
        log_dir=tmp_path / "logs",
        bind="tcp://198.18.0.2:6001",
        peers={},
    )
    config.write()
    assert tomllib.loads(config.to_toml())["net"]["plain"] is True
    with pytest.raises(ConfigError, match="only allowed on loopback"):
        NodeConfig.load(config.path)


def test_what_a_config_file_cannot_say_is_refused(tmp_path: Path) -> None:
    base = NodeConfig(
        path=tmp_path / "n.toml",
        drone="D",
        program=tmp_path / "p.json",
        log_dir=tmp_path / "logs",
        bind="tcp://127.0.0.1:6001",
        peers={},
    )
    with pytest.raises(ValueError, match="link settings"):
        NodeConfig(**{**base.__dict__, "link": LinkSettings(window=7)}).to_toml()
    with pytest.raises(ValueError, match="cannot write"):
        NodeConfig(**{**base.__dict__, "hal": {"x": object()}}).to_toml()
    with pytest.raises(ValueError, match="surrogate"):
        NodeConfig(**{**base.__dict__, "drone": "\ud800"}).to_toml()
