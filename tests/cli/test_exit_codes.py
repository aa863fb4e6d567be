"""Every ``eamos`` command exits with a code of the one table; bad input shows no traceback.

The table (eamos/cli/exits.py, README "Exit codes"): 0 ok, 1 mission failed,
2 bad input, 3 could not connect, 4 internal error.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from eamos.cli.errors import exit_code_of
from eamos.cli.exits import (
    EXIT_BAD_INPUT,
    EXIT_CODES,
    EXIT_CONNECT,
    EXIT_INTERNAL,
    EXIT_INTERRUPTED,
    EXIT_MISSION_FAILED,
)
from eamos.cli.main import main
from eamos.compiler import MissionError
from eamos.config import ConfigError
from eamos.net.keys import KeysError
from eamos.ops import DroneError, FleetConnectError, FleetError, RunFolderError
from eamos.program.format import ProgramError
from eamos.report import ReportError

REPO = Path(__file__).resolve().parents[2]
GOOD = REPO / "missions" / "experiment_b.go"
BAD_MISSION = "func SEQ_A() {\n\tDrone1.Takof(1)\n}\n"


@pytest.fixture
def files(tmp_path: Path) -> dict[str, str]:
    """Bad inputs of every kind, by name."""
    (tmp_path / "bad.go").write_text(BAD_MISSION)
    (tmp_path / "bad.toml").write_text("[drones.Drone1\n")  # not TOML
    (tmp_path / "unknown.toml").write_text("[grund]\nbind = 1\n")  # a misspelt table
    (tmp_path / "empty").mkdir()
    (tmp_path / "keys").mkdir()
    (tmp_path / "keys" / "public").mkdir()  # keys already made: refused without --force
    return {
        "bad.go": str(tmp_path / "bad.go"),
        "missing.go": str(tmp_path / "missing.go"),
        "bad.toml": str(tmp_path / "bad.toml"),
        "unknown.toml": str(tmp_path / "unknown.toml"),
        "missing.toml": str(tmp_path / "missing.toml"),
        "empty": str(tmp_path / "empty"),
        "keys": str(tmp_path / "keys"),
        "out": str(tmp_path / "out"),
    }


# (command line with <placeholders> for the files above, what stderr must say)
BAD_INPUT = [
    (["compile", "<bad.go>", "-o", "<out>"], "unknown action 'Takof'"),
    (["compile", "<missing.go>"], "no such mission file"),
    (["graph", str(GOOD), "--which", "mdg"], "needs --drone"),
    (["graph", str(GOOD), "--which", "mdg", "--drone", "Nobody"], "no drone 'Nobody'"),
    (["run", "<bad.go>", "--plain"], "unknown action 'Takof'"),
    (["run", str(GOOD), "--fleet", "<bad.toml>"], "not valid TOML"),
    (["run", str(GOOD), "--speedup", "-1"], "must be greater than 0"),
    (["rollout", "<bad.go>", "<missing.toml>"], "no such configuration file"),
    (["rollout", str(GOOD), "<unknown.toml>"], "grund: unknown field"),
    (["rollout", str(GOOD), "<bad.toml>", "--run-dir", "<out>"], "not valid TOML"),
    (["start", "<empty>"], "not a roll-out folder"),
    (["status", "<empty>"], "not a roll-out folder"),
    (["abort", "<empty>"], "not a roll-out folder"),
    (["logs", "fetch", "<empty>"], "not a roll-out folder"),
    (["status", "<missing.toml>"], "no such run folder or fleet file"),
    (["abort", "<missing.toml>"], "no such run folder or fleet file"),
    (["logs", "fetch", "<missing.toml>"], "no such run folder or fleet file"),
    (["report", "<empty>"], "summary.json"),
    (["keys", "<empty>"], "compile the mission first"),
    (["keys", "<keys>", "--fleet", "Drone1"], "use --force"),
    (["start", "<empty>", "--timeout", "soon"], "'soon' is not a number"),
    (["fly", str(GOOD)], "invalid choice"),
]


@pytest.mark.parametrize(
    "argv,message", BAD_INPUT, ids=[" ".join(a[:2]) + f"#{i}" for i, (a, _) in enumerate(BAD_INPUT)]
)
def test_bad_input_exits_2_without_a_traceback(
    argv: list[str],
    message: str,
    files: dict[str, str],
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.chdir(Path(files["out"]).parent)  # nothing lands in the repository
    args = [files[a[1:-1]] if a.startswith("<") else a for a in argv]
    code: int | str | None
    try:
        code = main(args)
    except SystemExit as exc:  # argparse refuses before any command runs
        code = exc.code
    err = capsys.readouterr().err
    assert code == EXIT_BAD_INPUT, err
    assert message in err
    assert "Traceback" not in err


def test_an_internal_error_is_one_line_and_the_traceback_needs_v(
    files: dict[str, str], capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    def broken(source: Path, mission: str | None = None) -> None:
        raise RuntimeError("broken invariant")

    monkeypatch.setattr("eamos.ops.deployment.resolve", broken)  # imported by the command
    assert main(["status", files["empty"]]) == EXIT_INTERNAL
    err = capsys.readouterr().err
    assert err == (
        "eamos status: internal error: RuntimeError: broken invariant "
        "(run with -v for details), please report it\n"
    )
    assert main(["status", files["empty"], "-v"]) == EXIT_INTERNAL
    err = capsys.readouterr().err
    assert "Traceback" in err and err.rstrip().endswith("please report it")


def _drone_error(kind: str) -> DroneError:
    return DroneError("Drone1", "root@198.18.0.2:22", kind, "detail")


@pytest.mark.parametrize(
    "exc,code",
    [
        (ConfigError("x"), EXIT_BAD_INPUT),
        (ProgramError("x"), EXIT_BAD_INPUT),
        (KeysError("x"), EXIT_BAD_INPUT),
        (ReportError("x"), EXIT_BAD_INPUT),
        (RunFolderError("not a roll-out folder"), EXIT_BAD_INPUT),
        (
            FleetError("probe", [_drone_error("unreachable"), _drone_error("wrong key")]),
            EXIT_CONNECT,
        ),
        (
            FleetError("probe", [_drone_error("unreachable"), _drone_error("disk full")]),
            EXIT_MISSION_FAILED,
        ),
        (FleetError("no drone has it rolled out"), EXIT_MISSION_FAILED),
        (FleetConnectError("cannot be the ground station at tcp://1.2.3.4:6000"), EXIT_CONNECT),
        (ConnectionRefusedError("refused"), EXIT_CONNECT),
        (KeyboardInterrupt(), EXIT_INTERRUPTED),
        (RuntimeError("bug"), EXIT_INTERNAL),
        (KeyError("bug"), EXIT_INTERNAL),
    ],
)
def test_exceptions_map_to_the_table(exc: BaseException, code: int) -> None:
    assert exit_code_of(exc) == code


def test_a_mission_error_is_bad_input() -> None:
    from eamos.compiler import compile_mission

    with pytest.raises(MissionError) as err:
        compile_mission(BAD_MISSION, "bad.go")
    assert exit_code_of(err.value) == EXIT_BAD_INPUT


def test_the_table_is_the_readme_table() -> None:
    readme = (REPO / "README.md").read_text()
    for code, meaning in EXIT_CODES.items():
        assert f"| {code} | {meaning}" in readme, (code, meaning)


def test_the_installed_command_uses_the_table(tmp_path: Path) -> None:
    (tmp_path / "bad.go").write_text(BAD_MISSION)
    done = subprocess.run(
        [sys.executable, "-m", "eamos.cli", "compile", str(tmp_path / "bad.go")],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=tmp_path,
        check=False,
    )
    assert done.returncode == EXIT_BAD_INPUT
    assert "bad.go:2:9: error: unknown action 'Takof'" in done.stderr
    assert "Traceback" not in done.stderr
