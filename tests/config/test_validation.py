"""Every config value is validated: finite, in range, known keys, known drones (issue 17).

Table-driven: each row is a config with one bad field and the field the error must name.
Bad input ends in ConfigError naming the file and the field (``eamos`` exit 2), never in an
internal error.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import pytest

from eamos.cli.exits import EXIT_BAD_INPUT
from eamos.cli.main import main
from eamos.cli.options import MAX_SECONDS, positive_number, seconds_number, speedup_number
from eamos.config import MAX_SPEEDUP, RANGES, ConfigError, FleetConfig, NodeConfig

from .refusals import assert_fleet_refused

REPO = Path(__file__).resolve().parents[2]
GOOD = REPO / "missions" / "experiment_b.go"

NODE = """\
drone = "Drone1"
program = "p.json"
{top}
[net]
bind = "tcp://127.0.0.1:6001"
plain = true
{net}
[net.peers]
GCS = "tcp://127.0.0.1:6000"

[hal]
adapter = "sim"
{hal}
"""

# (top-level lines, [net] lines, [hal] lines, the field the error names, words it says)
BAD_NODE = [
    ("ready_timeout_s = nan", "", "", "ready_timeout_s", "finite"),
    ("ready_timeout_s = inf", "", "", "ready_timeout_s", "finite"),
    ("ready_timeout_s = -1", "", "", "ready_timeout_s", "0 < value"),
    ("ready_timeout_s = 0", "", "", "ready_timeout_s", "0 < value"),
    ("ready_timeout_s = 1e9", "", "", "ready_timeout_s", "86400"),
    ('ready_timeout_s = "60"', "", "", "ready_timeout_s", "must be a number"),
    ("ready_timeout_s = true", "", "", "ready_timeout_s", "must be a number"),
    ("land_timeout_s = 1e5", "", "", "land_timeout_s", "3600"),
    ("mission_timeout_s = inf", "", "", "mission_timeout_s", "finite"),
    ("mission_timeout_s = 1e7", "", "", "mission_timeout_s", "604800"),
    ("", "heartbeat_s = 1e-9", "", "net.heartbeat_s", "0.01 <= value"),
    ("", "heartbeat_s = nan", "", "net.heartbeat_s", "finite"),
    ("", "heartbeat_s = 1e3", "", "net.heartbeat_s", "60"),
    ("", "peer_timeout_s = inf", "", "net.peer_timeout_s", "finite"),
    ("", "heartbeat_s = 5\npeer_timeout_s = 4", "", "net.peer_timeout_s", "heartbeat_s"),
    ("", "telemetry_stale_s = -inf", "", "net.telemetry_stale_s", "finite"),
    ("", "telemetry_max_hz = 1e9", "", "net.telemetry_max_hz", "1000"),
    ("", "telemetry_max_hz = nan", "", "net.telemetry_max_hz", "finite"),
    ("", "peer_give_up_s = inf", "", "net.peer_give_up_s", "finite"),
    ("", "peer_give_up_s = 0", "", "net.peer_give_up_s", "0 < value"),
    ("", "", "speedup = 1e9", "hal.speedup", "1000"),
    ("", "", "speedup = nan", "hal.speedup", "finite"),
    ("", "", "speedup = 0", "hal.speedup", "0 < value"),
    ("", "", 'speedup = "fast"', "hal.speedup", "must be a number"),
    ('log_dir = "a-file"', "", "", "log_dir", "is a file"),
    ('log_dir = "a-file/logs"', "", "", "log_dir", "is a file"),
    ('log_dir = ""', "", "", "log_dir", "must be a path"),
    ("ready_timeout = 5", "", "", "ready_timeout", "did you mean 'ready_timeout_s'"),
    ("", "heartbeat = 1", "", "net.heartbeat", "did you mean 'heartbeat_s'"),
]


@pytest.mark.parametrize(
    "top,net,hal,field,words", BAD_NODE, ids=[f"{r[3]}#{i}" for i, r in enumerate(BAD_NODE)]
)
def test_a_bad_drone_config_names_file_and_field(
    tmp_path: Path, top: str, net: str, hal: str, field: str, words: str
) -> None:
    (tmp_path / "a-file").write_text("not a folder\n")
    path = tmp_path / "node.toml"
    path.write_text(NODE.format(top=top, net=net, hal=hal))
    with pytest.raises(ConfigError) as info:
        NodeConfig.load(path)
    message = str(info.value)
    assert message.startswith(f"{path}: {field}"), message
    assert words in message, message


def test_the_drone_config_template_itself_loads(tmp_path: Path) -> None:
    path = tmp_path / "node.toml"
    path.write_text(NODE.format(top="ready_timeout_s = 86400", net="heartbeat_s = 0.01", hal=""))
    config = NodeConfig.load(path)
    assert config.ready_timeout_s == 86400 and config.link.heartbeat_s == 0.01


def test_a_drone_may_not_use_the_ground_adapter_but_the_ground_station_does(
    tmp_path: Path,
) -> None:
    path = tmp_path / "node.toml"
    path.write_text(NODE.format(top="", net="", hal="").replace('"sim"', '"ground"'))
    with pytest.raises(ConfigError, match=r"hal\.adapter: \"ground\" is the ground station's"):
        NodeConfig.load(path)
    text = path.read_text().replace('drone = "Drone1"', 'drone = "GCS"')
    path.write_text(text.replace('GCS = "tcp://127.0.0.1:6000"', 'D1 = "tcp://127.0.0.1:6002"'))
    assert NodeConfig.load(path).hal["adapter"] == "ground"


# (fleet file text, the field the error names, words it says)
BAD_FLEET = [
    ("drones = 5\n", "drones", "must be a table"),
    ("drones = [1, 2]\n", "drones", "must be a table"),
    ("defaults = 5\n", "defaults", "must be a table"),
    ("[defaults]\nhal = 3\n", "defaults.hal", "must be a table"),
    ("[drones]\nDrone1 = 7\n", "drones.Drone1", "must be a table"),
    ("[drones.Drone1]\nhal = 7\n", "drones.Drone1.hal", "must be a table"),
    ("[drones.Drone1]\nhome = [0, 0]\n", "drones.Drone1.home", "did you mean 'home_m'"),
    ("[defaults.hal]\nspeedup = 1e9\n", "defaults.hal.speedup", "1000"),
    ("[defaults.hal]\nspeedup = nan\n", "defaults.hal.speedup", "finite"),
    ("[drones.Drone1.hal]\nspeedup = -2\n", "drones.Drone1.hal.speedup", "0 < value"),
    ('[defaults.hal]\nadapter = "ground"\n', "defaults.hal.adapter", "ground station"),
    ('[drones.Drone2.hal]\nadapter = "ground"\n', "drones.Drone2.hal.adapter", "ground station"),
    ("[drones.Drone1]\nhome_m = [inf, 0]\n", "drones.Drone1.home_m[0]", "finite"),
    ("[drones.Drone1]\nhome_m = [0, nan]\n", "drones.Drone1.home_m[1]", "must be a number"),
    ("[safety]\nmin_separation_m = inf\n", "safety.min_separation_m", "finite"),
    ("[safety]\nmax_altitude_m = nan\n", "safety.max_altitude_m", "must be a number"),
    ("[safety]\nbattery_reserve_pct = 120\n", "safety.battery_reserve_pct", "between 0 and 100"),
    ("[safet]\nmin_separation_m = 2\n", "safet", "did you mean 'safety'"),
]


@pytest.mark.parametrize("text,field,words", BAD_FLEET, ids=[r[1] for r in BAD_FLEET])
def test_a_bad_fleet_file_names_file_and_field(
    tmp_path: Path, text: str, field: str, words: str
) -> None:
    assert_fleet_refused(tmp_path, text, field, words)


@pytest.mark.parametrize(
    "text,words",
    [
        ("[drones.Dron1.hal]\nadapter = 'sim'\n", "did you mean 'Drone1'"),
        ("[drones.Drone9]\nhome_m = [0, 0]\n", "the mission's drones: Drone1, Drone2"),
        ("[drones.Drone3.ssh]\nhost = 'x'\n", "the mission's drones: Drone1, Drone2"),
    ],
)
def test_a_table_for_a_drone_not_in_the_mission_is_refused(
    tmp_path: Path, text: str, words: str
) -> None:
    path = tmp_path / "fleet.toml"
    path.write_text(text)
    fleet = FleetConfig.load(path)
    with pytest.raises(ConfigError) as info:
        fleet.check_drones(["Drone1", "Drone2"])
    name = text.split("]")[0].split(".")[1]
    assert str(info.value).startswith(f"{path}: drones.{name}: not a drone of the mission")
    assert words in str(info.value)
    FleetConfig.load(path).check_drones(["Drone1", "Drone2", name])  # the right mission: fine


@pytest.mark.parametrize("text", ["nan", "inf", "-inf", "0", "-3", "soon"])
def test_option_numbers_are_finite_and_positive(text: str) -> None:
    with pytest.raises(argparse.ArgumentTypeError):
        positive_number(text)


def test_duration_options_are_at_most_a_week() -> None:
    assert seconds_number("604800") == MAX_SECONDS == RANGES["mission_timeout_s"].high
    with pytest.raises(argparse.ArgumentTypeError, match="at most 604800 s"):
        seconds_number("604801")


def test_speedup_option_has_the_config_range() -> None:
    assert speedup_number(str(MAX_SPEEDUP)) == MAX_SPEEDUP == RANGES["speedup"].high
    with pytest.raises(argparse.ArgumentTypeError, match="at most 1000"):
        speedup_number("1e9")


# `eamos run` with a bad fleet file or option: exit 2, one line naming file and field.
RUN_BAD = [
    (["--timeout", "nan"], "", "--timeout: must be a finite number"),
    (["--timeout", "inf"], "", "--timeout: must be a finite number"),
    (["--ready-timeout", "nan"], "", "--ready-timeout: must be a finite number"),
    (["--timeout", "1e300"], "", "--timeout: must be at most 604800 s (a week)"),
    (["--speedup", "1e9"], "", "--speedup: must be at most 1000"),
    (["--ready-timeout", "200000"], "", "--ready-timeout: must be finite, 0 < value <= 86400 s"),
    (["--speedup", "5"], "[defaults.hal]\nspeedup = nan\n", "defaults.hal.speedup: must be"),
    (["--speedup", "5"], "[drones.Drone1.hal]\nspeedup = 1e9\n", "drones.Drone1.hal.speedup"),
    ([], "drones = 5\n", "drones: must be a table"),
    ([], "drones = [1, 2]\n", "drones: must be a table"),
    ([], '[drones.Drone2.hal]\nadapter = "ground"\n', "drones.Drone2.hal.adapter"),
    ([], "[drones.Dron1.hal]\nadapter = 'sim'\n", "drones.Dron1: not a drone of the mission"),
    (["--check"], "[drones.Dron1]\nhome_m = [0, 5]\n", "drones.Dron1: not a drone of the"),
]


@pytest.mark.parametrize("extra,fleet,words", RUN_BAD, ids=[r[2] for r in RUN_BAD])
def test_eamos_run_refuses_bad_input_with_exit_2(
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
    extra: list[str],
    fleet: str,
    words: str,
) -> None:
    monkeypatch.chdir(tmp_path)  # nothing lands in the repository
    argv = ["run", str(GOOD), "--plain", "--no-svg", "--run-dir", str(tmp_path / "run")]
    if "--check" not in extra:
        argv.append("--no-check")
    argv += [a for a in extra if a != "--check"]
    if fleet:
        (tmp_path / "fleet.toml").write_text(fleet)
        argv += ["--fleet", str(tmp_path / "fleet.toml")]
    code: int | str | None
    try:
        code = main(argv)
    except SystemExit as exc:  # argparse refuses before the command runs
        code = exc.code
    err = capsys.readouterr().err
    assert code == EXIT_BAD_INPUT, err
    assert words in err, err
    if fleet:
        assert str(tmp_path / "fleet.toml") in err, err
    assert "Traceback" not in err and "internal error" not in err
    assert not (tmp_path / "run" / "logs").exists()  # refused before any drone started
