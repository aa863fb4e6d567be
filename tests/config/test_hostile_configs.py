"""Hostile node configs and fleet files end in exit 2 naming the file and the field (issue 28).

Never an internal error (exit 4), never "could not connect" (exit 3) for what is a bad
value, never a hang: the issue's inputs one by one through the real commands
(``eamos-node --config``, ``eamos check --fleet``), then a fuzz of random values, types,
nesting, lengths, NULs and huge and tiny numbers through the loaders in process (many)
and through the real commands (a sample).
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from eamos.check.explore import sim_settings
from eamos.compiler import compile_file
from eamos.config import ConfigError, FleetConfig, NodeConfig, fleet_order
from eamos.config.toml_text import toml_key, toml_value

REPO = Path(__file__).resolve().parents[2]
MISSION = REPO / "missions" / "experiment_b.go"
#: Nothing here may take longer (in process; a command adds its Python start-up).
HANG_S = 10.0
#: A command's bound: its start-up on a loaded 2-core machine, plus HANG_S.
COMMAND_S = 90.0

pytestmark = pytest.mark.timeout(1800)

NODE = {
    "drone": "Drone1",
    "program": "p.json",
    "log_dir": "logs/Drone1",
    "ready_timeout_s": 5,
    "net": {
        "bind": "tcp://127.0.0.1:6001",
        "plain": True,
        "peers": {"GCS": "tcp://127.0.0.1:6000"},
    },
    "hal": {"adapter": "sim", "speedup": 10},
}
FLEET = {
    "defaults": {"hal": {"adapter": "sim", "horizontal_speed_mps": 2.0}},
    "drones": {"Drone1": {"home_m": [0.0, 0.0], "hal": {"climb_speed_mps": 1.0}}},
    "safety": {"min_separation_m": 2.0, "max_altitude_m": 30},
    "net": {"ground_telemetry_hz": 2},
}


def toml(doc: dict[str, Any]) -> str:
    """``doc`` as TOML text, every top-level value inline (any nesting, any value)."""
    return "".join(f"{toml_key(k)} = {toml_value(v)}\n" for k, v in doc.items())


def replaced(doc: dict[str, Any], path: tuple[str, ...], value: Any) -> dict[str, Any]:
    """A copy of ``doc`` with ``value`` at ``path`` (tables on the way made as needed)."""
    out = dict(doc)
    if len(path) == 1:
        out[path[0]] = value
        return out
    inner = out.get(path[0])
    out[path[0]] = replaced(inner if isinstance(inner, dict) else {}, path[1:], value)
    return out


# -- the issue's inputs, through the real commands -------------------------------------------

LONG = "D" * 300
NODE_CASES: list[tuple[str, Callable[[Path], str], str]] = [
    ("drone of 300 characters", lambda d: toml(replaced(NODE, ("drone",), LONG)), "drone"),
    ("log_dir of 300 characters", lambda d: toml(replaced(NODE, ("log_dir",), LONG)), "log_dir"),
    ("NUL in program", lambda d: toml(replaced(NODE, ("program",), "p\x00.json")), "program"),
    ("NUL in log_dir", lambda d: toml(replaced(NODE, ("log_dir",), "logs\x00x")), "log_dir"),
    (
        "3000 nested arrays",
        lambda d: "x = " + "[" * 3000 + "]" * 3000 + "\n" + toml(NODE),
        "line 1",
    ),
    (
        "3000 nested inline tables",
        lambda d: "x = " + "{a = " * 3000 + "1" + "}" * 3000 + "\n" + toml(NODE),
        "line 1",
    ),
    (
        "3000 nested dotted tables",
        lambda d: toml(NODE) + "[zz" + ".a" * 3000 + "]\nb = 1\n",
        "zz.a.a",
    ),
    ("not UTF-8", lambda d: toml(NODE) + "# \udcff\n", "not UTF-8"),
    (
        "telemetry_hz = 1e308",
        lambda d: toml(replaced(NODE, ("hal", "telemetry_hz"), 1e308)),
        "hal.telemetry_hz",
    ),
    (
        "accel_mps2 = 1e308",
        lambda d: toml(replaced(NODE, ("hal", "accel_mps2"), 1e308)),
        "hal.accel_mps2",
    ),
    (
        "accel_mps2 = 1e-9",
        lambda d: toml(replaced(NODE, ("hal", "accel_mps2"), 1e-9)),
        "hal.accel_mps2",
    ),
    (
        "climb_speed_mps = 1e-9",
        lambda d: toml(replaced(NODE, ("hal", "climb_speed_mps"), 1e-9)),
        "hal.climb_speed_mps",
    ),
    (
        "horizontal_speed_mps = -1 (was exit 3)",
        lambda d: toml(replaced(NODE, ("hal", "horizontal_speed_mps"), -1)),
        "hal.horizontal_speed_mps",
    ),
    (
        "bind port 99999",
        lambda d: toml(replaced(NODE, ("net", "bind"), "tcp://127.0.0.1:99999")),
        "net.bind",
    ),
    (
        "bind port -1",
        lambda d: toml(replaced(NODE, ("net", "bind"), "tcp://127.0.0.1:-1")),
        "net.bind",
    ),
    (
        "endpoint with a NUL",
        lambda d: toml(replaced(NODE, ("net", "peers", "GCS"), "tcp://127.0.0.1:6\x000")),
        "net.peers.GCS",
    ),
    ('log_dir = "/"', lambda d: toml(replaced(NODE, ("log_dir",), "/")), "log_dir"),
    ('log_dir = "../../"', lambda d: toml(replaced(NODE, ("log_dir",), "../../")), "log_dir"),
    ("a file of 5 MiB", lambda d: "# " + "x" * (5 << 20) + "\n" + toml(NODE), "too large"),
]


def run_command(args: list[str], cwd: Path) -> tuple[int, str, float]:
    """Run an eamos command; (exit code, stderr, seconds).  A hang fails the test."""
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    t0 = time.monotonic()
    try:
        done = subprocess.run(
            [sys.executable, "-m", "eamos.cli", *args[1:]] if args[0] == "eamos" else args,
            cwd=cwd,
            capture_output=True,
            text=True,
            timeout=COMMAND_S,
            env=env,
        )
    except subprocess.TimeoutExpired as exc:
        raise AssertionError(f"{args}: no end within {COMMAND_S:g} s") from exc
    return done.returncode, done.stderr, time.monotonic() - t0


def node_command(config: Path) -> list[str]:
    return [sys.executable, "-m", "eamos.cli.node", "--config", str(config)]


def assert_refused(code: int, err: str, path: Path, field: str) -> None:
    assert code == 2, (code, err)
    assert f"{path}: " in err and field in err, err
    assert "internal error" not in err and "Traceback" not in err, err


@pytest.mark.parametrize(
    ("make", "field"), [c[1:] for c in NODE_CASES], ids=[c[0] for c in NODE_CASES]
)
def test_the_issues_node_configs_exit_2_naming_file_and_field(
    tmp_path: Path, make: Callable[[Path], str], field: str
) -> None:
    config = tmp_path / "node.toml"
    config.write_text(make(tmp_path), encoding="utf-8", errors="surrogatepass")
    t0 = time.monotonic()
    with pytest.raises(ConfigError) as info:
        NodeConfig.load(config)
    assert time.monotonic() - t0 < HANG_S
    assert str(info.value).startswith(f"{config}: ") and field in str(info.value)
    code, err, _ = run_command(node_command(config), tmp_path)
    assert_refused(code, err, config, field)
    assert not any(Path("/").glob("mission.log*"))  # nothing written at the root


FLEET_CASES: list[tuple[str, str, str]] = [
    ("telemetry_hz", "[defaults.hal]\ntelemetry_hz = 1e308\n", "telemetry_hz"),
    ("accel huge", "[drones.Drone1.hal]\naccel_mps2 = 1e308\n", "accel_mps2"),
    ("accel tiny", "[drones.Drone2.hal]\naccel_mps2 = 1e-9\n", "accel_mps2"),
    ("climb tiny", "[types.Quadcopter.hal]\nclimb_speed_mps = 1e-9\n", "climb_speed_mps"),
    ("nested arrays", "x = " + "[" * 3000 + "]" * 3000 + "\n", "line 1"),
    ("nested tables", "[drones" + ".a" * 3000 + "]\nb = 1\n", "drones.a.a"),
    ("drone name of 300", f"[drones.{LONG}]\nhome_m = [0, 0]\n", "drones.DDD"),
    ("NUL in a name", '[drones."D\\u0000"]\nhome_m = [0, 0]\n', "NUL"),
    ("separation huge", "[safety]\nmin_separation_m = 1e308\n", "safety.min_separation_m"),
    ("home huge", "[drones.Drone1]\nhome_m = [1e308, 0]\n", "drones.Drone1.home_m[0]"),
    ("unknown adapter", '[defaults.hal]\nadapter = "simm"\n', "defaults.hal.adapter"),
]


@pytest.mark.parametrize(
    ("text", "field"), [c[1:] for c in FLEET_CASES], ids=[c[0] for c in FLEET_CASES]
)
def test_hostile_fleet_files_exit_2_naming_file_and_field(
    tmp_path: Path, text: str, field: str
) -> None:
    fleet = tmp_path / "fleet.toml"
    fleet.write_text(text, encoding="utf-8")
    code, err, _ = run_command(["eamos", "check", str(MISSION), "--fleet", str(fleet)], tmp_path)
    assert_refused(code, err, fleet, field)


# -- the fuzz ----------------------------------------------------------------------------------

_TEXT = st.characters(exclude_categories=["Cs"])
LEAF = st.one_of(
    st.booleans(),
    st.integers(min_value=-(2**63), max_value=2**63 - 1),
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([1e308, -1e308, 1e-308, 5e-324, 1e-9, 0, -1, 65536, 99999, 2**63 - 1]),
    st.text(_TEXT, max_size=30),
    st.builds(lambda a, b: f"{a}\x00{b}", st.text(_TEXT, max_size=5), st.text(_TEXT, max_size=5)),
    st.builds(
        lambda ch, n: ch * n,
        st.sampled_from(["x", "é", "/", "../", "\n"]),
        st.sampled_from([255, 256, 300, 5000]),
    ),
    st.sampled_from(
        [
            "tcp://127.0.0.1:0",
            "tcp://*:6001",
            "tcp://[::1]:65535",
            "ipc://",
            "inproc://",
            "udp://x:1",
        ]
    ),
)
VALUE = st.recursive(
    LEAF,
    lambda inner: (
        st.lists(inner, max_size=4) | st.dictionaries(st.text(_TEXT, max_size=8), inner, max_size=4)
    ),
    max_leaves=12,
)
NODE_PATHS = [
    ("drone",),
    ("program",),
    ("log_dir",),
    ("ready_timeout_s",),
    ("land_timeout_s",),
    ("mission_timeout_s",),
    ("peer_wait_limit_s",),
    ("on_stranded",),
    ("battery_reserve_pct",),
    ("net",),
    ("net", "bind"),
    ("net", "plain"),
    ("net", "keys"),
    ("net", "peers"),
    ("net", "peers", "GCS"),
    ("net", "heartbeat_s"),
    ("net", "peer_timeout_s"),
    ("net", "telemetry_max_hz"),
    ("net", "peer_give_up_s"),
    ("hal",),
    ("hal", "adapter"),
    ("hal", "speedup"),
    ("hal", "telemetry_hz"),
    ("hal", "accel_mps2"),
    ("hal", "climb_speed_mps"),
    ("hal", "pilot"),
    ("hal", "home_m"),
    ("hal", "reject_actions"),
    ("hal", "connection"),
    ("hal", "auto"),
]
FLEET_PATHS = [
    ("defaults",),
    ("defaults", "hal"),
    ("defaults", "hal", "adapter"),
    ("defaults", "hal", "telemetry_hz"),
    ("defaults", "hal", "horizontal_speed_mps"),
    ("types",),
    ("types", "Quadcopter", "hal", "accel_mps2"),
    ("types", "Quadcopter", "hal", "battery_pct"),
    ("drones",),
    ("drones", "Drone1"),
    ("drones", "Drone1", "home_m"),
    ("drones", "Drone1", "home_lla"),
    ("drones", "Drone2", "hal", "pilot"),
    ("drones", "Drone2", "hal", "arm_delay_s"),
    ("safety",),
    ("safety", "min_separation_m"),
    ("safety", "geofence_m"),
    ("safety", "battery_reserve_pct"),
    ("net", "ground_telemetry_hz"),
]


@st.composite
def mutated(draw: st.DrawFn, base: dict[str, Any], paths: list[tuple[str, ...]]) -> str:
    """``base`` with one to three fields replaced by random values, or raw hostile text."""
    doc = base
    for _ in range(draw(st.integers(1, 3))):
        path = draw(st.sampled_from(paths) | st.tuples(st.text(_TEXT, min_size=1, max_size=6)))
        doc = replaced(doc, path, draw(VALUE))
    text = toml(doc)
    extra = draw(st.sampled_from(["", "", "", "deep", "dotted", "junk"]))
    if extra == "deep":
        n = draw(st.sampled_from([33, 500, 5000]))
        text = f"z = {'[' * n}{']' * n}\n" + text
    elif extra == "dotted":
        text += "[zz" + ".b" * draw(st.sampled_from([33, 2000])) + "]\nc = 1\n"
    elif extra == "junk":
        text += draw(st.sampled_from(["\x00\x01", "[[", "a = ", "\udcff"]))  # \udcff: not UTF-8
    return text


#: What follows ``<file>: `` in a refusal: a line, or a field (its keys TOML-quoted when not
#: bare, so a quoted key may hold a colon), then ``: ``; or a whole-file problem.
_QUOTED = r'"(?:[^"\\]|\\.)*"'
FIELD = re.compile(
    rf"(line \d+: |not valid TOML: |too large|cannot read it: "
    rf"|(?:[^\s:\"]|{_QUOTED})(?:[^:\"]|{_QUOTED})*: )"
)


def names_a_field(message: str, path: Path) -> bool:
    """The message is ``<file>: <field or line>: <problem>``."""
    if not message.startswith(f"{path}: "):
        return False
    rest = message[len(str(path)) + 2 :]
    return FIELD.match(rest) is not None


def check_node(path: Path) -> str | None:
    """What ``eamos-node`` checks before it opens a socket: None if accepted, else the error."""
    t0 = time.monotonic()
    try:
        NodeConfig.load(path)
        return None
    except ConfigError as exc:
        message = str(exc)
        assert names_a_field(message, path), message
        return message
    finally:
        assert time.monotonic() - t0 < HANG_S


def check_fleet(path: Path, compiled: Any) -> str | None:
    """What ``eamos check --fleet`` checks of the file before it simulates: None if accepted."""
    t0 = time.monotonic()
    try:
        fleet = FleetConfig.load(path).for_mission(compiled.programs, compiled.mission.types)
        drones = fleet_order(compiled.programs)
        fleet.check_drones(drones)
        for drone in drones:
            sim_settings(fleet, drone)
        fleet.homes(drones)
        return None
    except ConfigError as exc:
        message = str(exc)
        assert names_a_field(message, path), message
        return message
    finally:
        assert time.monotonic() - t0 < HANG_S


FUZZ = settings(
    max_examples=400,
    deadline=None,
    database=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)


def test_fuzzed_node_configs_are_loaded_or_refused_naming_file_and_field(tmp_path: Path) -> None:
    path = tmp_path / "node.toml"
    refused: list[str] = []

    @FUZZ
    @given(mutated(NODE, NODE_PATHS))
    def one(text: str) -> None:
        path.write_text(text, encoding="utf-8", errors="surrogatepass")
        message = check_node(path)
        if message is not None:
            refused.append(text)

    one()
    assert len(refused) > 100  # the fuzz mostly made bad configs, and each was refused well
    # A sample through the real command: exit 2 naming file and field, never 3 or 4.
    for i, text in enumerate(refused[:: max(1, len(refused) // 12)][:12]):
        sample = tmp_path / f"sample{i}.toml"
        sample.write_text(text, encoding="utf-8", errors="surrogatepass")
        message = check_node(sample)
        assert message is not None
        code, err, _ = run_command(node_command(sample), tmp_path)
        assert code == 2 and names_a_field(err.split("eamos-node: ", 1)[-1].strip(), sample), (
            code,
            err,
        )


def test_fuzzed_fleet_files_are_loaded_or_refused_naming_file_and_field(tmp_path: Path) -> None:
    compiled = compile_file(MISSION)
    path = tmp_path / "fleet.toml"
    refused: list[str] = []

    @FUZZ
    @given(mutated(FLEET, FLEET_PATHS))
    def one(text: str) -> None:
        path.write_text(text, encoding="utf-8", errors="surrogatepass")
        if check_fleet(path, compiled) is not None:
            refused.append(text)

    one()
    assert len(refused) > 100
    for i, text in enumerate(refused[:: max(1, len(refused) // 8)][:8]):
        sample = tmp_path / f"sample{i}.toml"
        sample.write_text(text, encoding="utf-8", errors="surrogatepass")
        code, err, _ = run_command(
            ["eamos", "check", str(MISSION), "--fleet", str(sample)], tmp_path
        )
        assert code == 2 and names_a_field(err.split("eamos check: ", 1)[-1].strip(), sample), (
            code,
            err,
        )
