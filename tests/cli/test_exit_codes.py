"""Every entry point exits with a code of the one table; bad input shows no traceback.

The codes (eamos/cli/exits.py, README "Exit codes"): 0 ok, 1 mission failed,
2 bad input, 3 could not connect, 4 internal error.  Exceptions become codes in one
place (eamos/cli/errors.py, ``EXIT_CODE_OF`` and ``run_reported``) for ``eamos``,
``eamos-node`` and ``eamos-sim-vehicle`` alike.
"""

from __future__ import annotations

import argparse
import importlib
import signal
import socket
import subprocess
import sys
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from eamos.actors.errors import DroneRuntimeError
from eamos.cli import node as cli_node
from eamos.cli import sim_vehicle as cli_sim_vehicle
from eamos.cli.errors import EXIT_CODE_OF, BadInput, Refused, dispatch, exit_code_of
from eamos.cli.exits import (
    EXIT_BAD_INPUT,
    EXIT_CODES,
    EXIT_CONNECT,
    EXIT_INTERNAL,
    EXIT_INTERRUPTED,
    EXIT_MISSION_FAILED,
    EXIT_OK,
)
from eamos.cli.main import main
from eamos.compiler import MissionError, compile_file
from eamos.config import ConfigError
from eamos.hal import AdapterError
from eamos.net.keys import KeysError
from eamos.net.wire import WireError
from eamos.ops import DroneError, FleetConnectError, FleetError, RunFolderError
from eamos.program.format import ProgramError
from eamos.report import ReportError
from tests.net.link_helpers import free_port
from tests.support.netlab import node_argv, write_fleet

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
        (WireError("x"), EXIT_BAD_INPUT),
        (BadInput("x"), EXIT_BAD_INPUT),
        (RunFolderError("not a roll-out folder"), EXIT_BAD_INPUT),
        (AdapterError("hal.connection: nobody answers"), EXIT_CONNECT),
        (DroneRuntimeError("cannot bind"), EXIT_CONNECT),
        (Refused("the check found errors"), EXIT_MISSION_FAILED),
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


def test_every_class_the_table_names_is_an_exception_defined_there() -> None:
    # The table names classes instead of importing them: a renamed or moved class fails here.
    for name, code in EXIT_CODE_OF.items():
        module, _, qualname = name.rpartition(".")
        cls = getattr(importlib.import_module(module), qualname, None)
        assert isinstance(cls, type) and issubclass(cls, BaseException), name
        assert (cls.__module__, cls.__qualname__) == (module, qualname), name
        assert code in EXIT_CODES or code == EXIT_INTERRUPTED, name


def test_a_subclass_takes_its_nearest_listed_base() -> None:
    class LabConfigError(ConfigError):
        pass

    class Unlisted(Exception):
        pass

    assert exit_code_of(LabConfigError("x")) == EXIT_BAD_INPUT
    assert exit_code_of(RunFolderError("x")) == EXIT_BAD_INPUT  # not its base FleetError's 1
    assert exit_code_of(Unlisted("x")) == EXIT_INTERNAL


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


# -- every entry point: the same table, the same one line --------------------------------


def _raiser(exc: BaseException) -> Callable[..., int]:
    def work(*args: object, **kwargs: object) -> int:
        raise exc

    return work


def _via_eamos(exc: BaseException) -> int:
    args = argparse.Namespace(func=_raiser(exc), prog="eamos status", verbose=False)
    return dispatch(args)


def _via_node(exc: BaseException) -> int:
    return cli_node.guarded(_raiser(exc), verbose=False, who="Drone1")


def _via_sim_vehicle(exc: BaseException, monkeypatch: pytest.MonkeyPatch) -> int:
    monkeypatch.setattr(cli_sim_vehicle, "fly", _raiser(exc))
    return cli_sim_vehicle.main(["--autopilot", "px4", "--connection", "udpout:127.0.0.1:9"])


ENTRY_POINTS = ["eamos status", "eamos-node Drone1", "eamos-sim-vehicle"]


@pytest.mark.parametrize("prog", ENTRY_POINTS)
@pytest.mark.parametrize(
    "exc",
    [
        ConfigError("drone1.toml: net.bind: missing"),
        AdapterError("hal.connection: udpin:0.0.0.0:14540: in use"),
        FleetError("probe", [DroneError("Drone1", "root@198.18.0.2:22", "unreachable", "x")]),
        Refused("the check found errors"),
        RuntimeError("broken invariant"),
    ],
    ids=lambda e: type(e).__name__,
)
def test_every_entry_point_maps_exceptions_by_the_one_table(
    prog: str,
    exc: BaseException,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    via = {
        "eamos status": _via_eamos,
        "eamos-node Drone1": _via_node,
        "eamos-sim-vehicle": lambda e: _via_sim_vehicle(e, monkeypatch),
    }[prog]
    assert via(exc) == exit_code_of(exc)
    err = capsys.readouterr().err
    if exit_code_of(exc) == EXIT_INTERNAL:
        assert err == (
            f"{prog}: internal error: RuntimeError: broken invariant "
            "(run with -v for details), please report it\n"
        )
    else:
        assert err.startswith(f"{prog}: ") and str(exc).splitlines()[0] in err, err
    assert "Traceback" not in err


def _run(argv: list[str], cwd: Path, timeout: float = 120) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        argv, capture_output=True, text=True, timeout=timeout, cwd=cwd, check=False
    )


def test_eamos_node_bad_input_exits_2(tmp_path: Path) -> None:
    done = _run(node_argv(tmp_path / "missing.toml"), tmp_path)
    assert done.returncode == EXIT_BAD_INPUT, done.stderr
    assert done.stderr.startswith("eamos-node: ") and "missing.toml" in done.stderr
    assert "Traceback" not in done.stderr
    twice = [*node_argv(tmp_path / "a.toml"), "--config", str(tmp_path / "a.toml")]
    done = _run(twice, tmp_path)
    assert done.returncode == EXIT_BAD_INPUT and "Traceback" not in done.stderr, done.stderr


@pytest.fixture
def taken_port() -> Iterator[int]:
    """A TCP port on loopback that something listens on."""
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        sock.listen()
        yield sock.getsockname()[1]


def test_eamos_node_that_cannot_bind_exits_3(tmp_path: Path, taken_port: int) -> None:
    compiled = compile_file(REPO / "missions" / "experiment_b.go")
    bind = {name: f"tcp://127.0.0.1:{free_port()}" for name in compiled.programs}
    bind["Drone1"] = f"tcp://127.0.0.1:{taken_port}"
    files = write_fleet(compiled.programs, tmp_path, bind, ready_timeout_s=30.0)
    done = _run(node_argv(files.configs["Drone1"]), tmp_path)
    assert done.returncode == EXIT_CONNECT, done.stderr
    assert f"cannot bind the out-bridge at {bind['Drone1']}" in done.stderr
    assert "Traceback" not in done.stderr


def _sim_vehicle(*args: str) -> list[str]:
    return [sys.executable, "-m", "eamos.cli.sim_vehicle", "--autopilot", "px4", *args]


def test_eamos_sim_vehicle_exits_0_2_and_3(tmp_path: Path, taken_port: int) -> None:
    done = _run(_sim_vehicle("--connection", "udpout:127.0.0.1:9", "--speedup", "0"), tmp_path)
    assert done.returncode == EXIT_BAD_INPUT and "must be > 0" in done.stderr, done.stderr
    done = _run(_sim_vehicle("--connection", f"tcpin:127.0.0.1:{taken_port}"), tmp_path)
    assert done.returncode == EXIT_CONNECT, done.stderr
    assert done.stderr.startswith(f"eamos-sim-vehicle: cannot open tcpin:127.0.0.1:{taken_port}")
    assert "Traceback" not in done.stderr
    with subprocess.Popen(
        _sim_vehicle("--connection", f"udpout:127.0.0.1:{free_port()}"),
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        cwd=tmp_path,
    ) as vehicle:
        assert vehicle.stdout is not None
        assert "eamos-sim-vehicle: px4 sysid 1" in vehicle.stdout.readline()
        vehicle.send_signal(signal.SIGTERM)
        assert vehicle.wait(timeout=60) == EXIT_OK, vehicle.stderr.read() if vehicle.stderr else ""
