"""The fleet file's ``[net] ground_telemetry_hz``: read, defaulted and refused with its place."""

from __future__ import annotations

from pathlib import Path

import pytest

from eamos.cli.exits import EXIT_BAD_INPUT
from eamos.cli.main import main
from eamos.config import FleetConfig
from eamos.config.fleet import DEFAULT_GROUND_TELEMETRY_HZ, PEER_TELEMETRY_HZ

from .refusals import assert_fleet_refused

REPO = Path(__file__).resolve().parents[2]


def load(tmp_path: Path, text: str) -> FleetConfig:
    path = tmp_path / "fleet.toml"
    path.write_text(text)
    return FleetConfig.load(path)


def test_the_rate_is_read_and_a_drone_read_by_peers_keeps_the_peers_rate(tmp_path: Path) -> None:
    fleet = load(tmp_path, "[net]\nground_telemetry_hz = 5\n")
    assert fleet.ground_telemetry_hz == 5.0
    assert fleet.telemetry_hz(read_by_peers=False) == 5.0
    assert fleet.telemetry_hz(read_by_peers=True) == PEER_TELEMETRY_HZ
    faster = load(tmp_path, "[net]\nground_telemetry_hz = 50\n")
    assert faster.telemetry_hz(read_by_peers=True) == 50.0  # never slower than asked
    for default in (load(tmp_path, ""), FleetConfig.empty()):
        assert default.telemetry_hz(read_by_peers=False) == DEFAULT_GROUND_TELEMETRY_HZ


@pytest.mark.parametrize(
    ("text", "field", "words"),
    [
        ("[net]\nground_telemetry_hz = 0\n", "net.ground_telemetry_hz", "between 0.5 and 1000"),
        ("[net]\nground_telemetry_hz = 0.1\n", "net.ground_telemetry_hz", "got 0.1"),
        ("[net]\nground_telemetry_hz = 1e6\n", "net.ground_telemetry_hz", "between"),
        ("[net]\nground_telemetry_hz = nan\n", "net.ground_telemetry_hz", "must be a number"),
        ('[net]\nground_telemetry_hz = "2"\n', "net.ground_telemetry_hz", "must be a number"),
        ("[net]\nground_telemetry = 2\n", "net", "ground_telemetry"),
        ("net = 2\n", "net", "must be a table"),
    ],
)
def test_a_bad_rate_is_refused_with_its_place(
    tmp_path: Path, text: str, field: str, words: str
) -> None:
    assert_fleet_refused(tmp_path, text, field, words)


def test_eamos_run_refuses_a_bad_rate_before_any_drone_starts(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.chdir(tmp_path)
    fleet = tmp_path / "fleet.toml"
    fleet.write_text("[net]\nground_telemetry_hz = -2\n")
    code = main(
        [
            *("run", str(REPO / "missions" / "experiment_b.go"), "--plain", "--no-svg"),
            *("--no-check", "--run-dir", str(tmp_path / "run"), "--fleet", str(fleet)),
        ]
    )
    err = capsys.readouterr().err
    assert code == EXIT_BAD_INPUT, err
    assert f"{fleet}: net.ground_telemetry_hz: must be between" in err, err
    assert "Traceback" not in err
    assert not (tmp_path / "run" / "logs").exists()
