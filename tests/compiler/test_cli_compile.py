"""``eamos compile`` and ``eamos graph``: handlers, exit codes, outputs."""

from __future__ import annotations

import argparse
import io
import json
import os
import shutil
import subprocess
import sys
from contextlib import redirect_stderr, redirect_stdout
from pathlib import Path

import pytest

from eamos.cli import compile as cli_compile
from eamos.cli.compile import run_compile, run_graph
from eamos.cli.errors import dispatch
from eamos.cli.main import build_parser
from eamos.compiler import CompilerBug
from eamos.program.format import load_program

from .compiler_helpers import MISSIONS, REPO

BAD = "func SEQ_A() {\n\tDrone1.Takof(1)\n\tSEQ_Nope()\n}\n"


def _run(argv: list[str]) -> tuple[int, str, str]:
    """Parse ``argv`` like ``eamos`` does and run the command, capturing its output."""
    args = build_parser().parse_args(argv)
    out, err = io.StringIO(), io.StringIO()
    with redirect_stdout(out), redirect_stderr(err):
        code = dispatch(args)
    return code, out.getvalue(), err.getvalue()


def _subprocess(argv: list[str], cwd: Path) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    return subprocess.run(
        [sys.executable, "-m", "eamos.cli", *argv],
        cwd=cwd,
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )


def test_parsers_register_with_a_host_cli() -> None:
    parser = argparse.ArgumentParser(prog="eamos")
    sub = parser.add_subparsers(dest="command")
    compile_parser = cli_compile.add_compile_parser(sub)
    graph_parser = cli_compile.add_graph_parser(sub)
    args = parser.parse_args(["compile", "m.go", "-o", "x", "--stats", "--no-svg", "-v"])
    assert (args.mission, args.out, args.stats, args.svg, args.verbose) == (
        "m.go",
        "x",
        True,
        False,
        True,
    )
    assert args.func is run_compile
    args = parser.parse_args(
        [
            "graph",
            "m.go",
            "--which",
            "mdg",
            "--drone",
            "D1",
            "--format",
            "dot",
            "-o",
            "f.dot",
            "--open",
        ]
    )
    assert (args.which, args.drone, args.format, args.out, args.open) == (
        "mdg",
        "D1",
        "dot",
        "f.dot",
        True,
    )
    assert args.func is run_graph
    assert "Table 7" in compile_parser.format_help()
    assert "dotted" in graph_parser.format_help()
    assert parser.parse_args(["compile", "m.go"]).svg is True


def test_compile_writes_artifacts_and_prints_a_summary(tmp_path: Path) -> None:
    code, out, err = _run(["compile", str(MISSIONS / "experiment_c.go"), "-o", str(tmp_path)])
    assert code == 0
    if shutil.which("dot") is None:  # the built-in renderer draws; one warning says so
        (line,) = err.splitlines()
        assert line.startswith("warning: Graphviz 'dot' is not installed"), err
    else:
        assert err == ""
    assert "MEG 33 nodes" in out
    for drone in ("GCS", "Drone1", "Drone2", "Drone3"):
        assert f"{tmp_path / 'programs' / drone}.program.json" in out
        load_program(tmp_path / "programs" / f"{drone}.program.json")
    assert "26 nodes" in out and "(9 internal, 8 in, 8 out)" in out
    svg = (tmp_path / "graphs" / "meg.svg").read_text()
    assert svg.lstrip().startswith(("<svg", "<?xml"))


def test_compile_stats_prints_only_json(tmp_path: Path) -> None:
    code, out, _ = _run(
        ["compile", str(MISSIONS / "experiment_d.go"), "-o", str(tmp_path), "--stats", "--no-svg"]
    )
    assert code == 0
    stats = json.loads(out)
    assert set(stats) == {"meg", "drones"}
    assert set(stats["meg"]) == {"nodes", "arcs"}
    assert list(stats["drones"]) == ["GCS", "D1", "D2", "D3"]
    for figures in stats["drones"].values():
        assert set(figures) == {"nodes", "internal_arcs", "external_in", "external_out"}
    assert (stats["drones"]["D2"]["external_in"], stats["drones"]["D2"]["external_out"]) == (5, 5)
    assert not list((tmp_path / "graphs").glob("*.svg"))


def test_compile_default_output_folder(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    code, _, _ = _run(["compile", str(MISSIONS / "experiment_a.go"), "--no-svg"])
    assert code == 0
    assert (tmp_path / "out" / "experiment_a" / "programs" / "Drone1.program.json").exists()


def test_compile_prints_warnings(tmp_path: Path) -> None:
    mission = tmp_path / "warn.go"
    mission.write_text("func SEQ_A() {\n\tDrone1.Arm()\n}\n\nfunc SEQ_B() {\n\tDrone1.Land()\n}\n")
    code, out, err = _run(["compile", str(mission), "-o", str(tmp_path / "o"), "--no-svg"])
    assert code == 0
    assert f"{mission}:5:6: warning: block 'SEQ_B' is never reached" in err
    assert "compiled" in out


def test_compile_bad_mission_exits_2_with_locations(tmp_path: Path) -> None:
    # A mission with errors is bad input (2) in the one exit-code table (it was 1).
    mission = tmp_path / "bad.go"
    mission.write_text(BAD)
    code, out, err = _run(["compile", str(mission), "-o", str(tmp_path / "o")])
    assert code == 2 and out == ""
    assert f"{mission}:2:9: error: unknown action 'Takof'" in err
    assert f"{mission}:3:2: error: undefined block 'SEQ_Nope'" in err
    assert "2 errors in" in err and "Traceback" not in err
    assert not (tmp_path / "o").exists()


def test_compile_missing_and_binary_files(tmp_path: Path) -> None:
    code, _, err = _run(["compile", str(tmp_path / "nope.go")])
    assert code == 2 and "no such mission file" in err
    binary = tmp_path / "bin.go"
    binary.write_bytes(b"func\x00\x01\x02")
    code, _, err = _run(["compile", str(binary)])
    assert code == 2 and "NUL bytes" in err and "\x00" not in err


def test_compile_unwritable_output_is_a_clean_error(tmp_path: Path) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    code, _, err = _run(["compile", str(MISSIONS / "experiment_a.go"), "-o", str(blocker / "x")])
    assert code == 2 and "cannot write the output" in err and "Traceback" not in err


@pytest.mark.parametrize("exc", [CompilerBug("broken invariant"), RuntimeError("boom")])
def test_internal_errors_exit_4_in_one_line(
    exc: Exception,
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    def explode(path: Path) -> None:
        raise exc

    monkeypatch.setattr("eamos.compiler.compile_file", explode)  # imported by the command
    # Internal errors exit 4 like every other command's (compile's was 2).
    code, out, err = _run(["compile", str(MISSIONS / "experiment_a.go")])
    assert code == 4 and out == ""
    assert err.count("\n") == 1
    assert err.startswith("eamos compile: internal error: ") and str(exc) in err
    assert "(run with -v for details), please report it" in err
    code, _, err = _run(["compile", str(MISSIONS / "experiment_a.go"), "-v"])
    assert code == 4 and "Traceback" in err and "please report it" in err


def test_graph_prints_dot_and_writes_files(tmp_path: Path) -> None:
    mission = str(MISSIONS / "listing01_demo.go")
    code, out, _ = _run(["graph", mission, "--which", "amt", "--format", "dot"])
    assert code == 0 and out.startswith('digraph "amt" {')
    target = tmp_path / "d2.svg"
    code, out, _ = _run(
        ["graph", mission, "--which", "mdg", "--drone", "Drone2", "-o", str(target)]
    )
    assert code == 0 and str(target) in out
    assert target.read_text().lstrip().startswith(("<svg", "<?xml"))
    code, _, _ = _run(
        ["graph", mission, "--format", "graphml", "-o", str(tmp_path / "meg.graphml")]
    )
    assert code == 0 and (tmp_path / "meg.graphml").read_text().startswith("<?xml")
    code, out, _ = _run(["graph", mission, "--format", "graphml"])
    assert code == 0 and "<graphml" in out


def test_graph_mdg_needs_a_known_drone() -> None:
    mission = str(MISSIONS / "listing01_demo.go")
    code, _, err = _run(["graph", mission, "--which", "mdg"])
    assert code == 2 and "needs --drone" in err and "Drone3" in err
    code, _, err = _run(["graph", mission, "--which", "mdg", "--drone", "Drone9"])
    assert code == 2 and "no drone 'Drone9'" in err


def test_graph_open_without_a_display_prints_the_path(
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    monkeypatch.setattr(cli_compile.sys, "platform", "linux")
    code, out, _ = _run(["graph", str(MISSIONS / "experiment_a.go"), "--open"])
    assert code == 0
    path = tmp_path / "out" / "experiment_a" / "graphs" / "meg.svg"
    assert path.exists() and "no viewer found" in out


def test_graph_bad_mission_exits_2(tmp_path: Path) -> None:
    mission = tmp_path / "bad.go"
    mission.write_text(BAD)
    code, out, err = _run(["graph", str(mission)])
    assert code == 2 and out == "" and f"{mission}:2:9:" in err


def test_cli_in_a_subprocess(tmp_path: Path) -> None:
    done = _subprocess(
        ["compile", str(MISSIONS / "listing01_demo.go"), "-o", str(tmp_path / "o"), "--stats"],
        cwd=tmp_path,
    )
    assert done.returncode == 0, done.stderr
    assert json.loads(done.stdout)["meg"] == {"nodes": 12, "arcs": 14}
    mission = tmp_path / "bad.go"
    mission.write_text(BAD)
    done = _subprocess(["compile", str(mission)], cwd=tmp_path)
    assert done.returncode == 2
    assert f"{mission}:2:9: error:" in done.stderr and "Traceback" not in done.stderr
    done = _subprocess(["compile", "--help"], cwd=tmp_path)
    assert done.returncode == 0 and "--no-svg" in done.stdout
