"""Every mission and every ``eamos`` command of the README and docs/*.md runs as written.

Missions (```go blocks) are written to a temporary folder and must pass ``eamos check``; those
that declare drones fly on simulated drones (``eamos run --speedup 20``, marked e2e).  Command
lines of shell blocks run as written in a temporary folder holding copies of the repository's
``missions/`` and ``configs/``, with ``HOME`` and ``XDG_DATA_HOME`` of their own, and must exit
as the doc says (0 unless a marker says otherwise).  A marker before a block
(``<!-- doc-test: ... -->``, :mod:`tests.docs.doc_examples`) names the few that need hardware, SSH
or a browser, or are fragments: those are checked for syntax only (the mission parsed, the
command's arguments parsed by its own parser).  Commands quoted in prose (synopses,
references) are not run, but every option they name must be one their command has.  Each
test's id is the doc and line.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import os
import shutil
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest

from tests.docs.doc_examples import (
    Command,
    MarkerError,
    Mission,
    command_argv,
    commands,
    declares_drones,
    inline_commands,
    missions,
    options_named,
    parse_marker,
)

REPO = Path(__file__).resolve().parents[2]
DOCS = [REPO / "README.md", *sorted((REPO / "docs").glob("*.md"))]
#: Generous for a loaded 2-core machine; a healthy example takes seconds.
PROCESS_TIMEOUT_S = 240
#: The console entry points, run with this interpreter as ``python -m`` would.
ENTRY_MODULES = {
    "eamos": "eamos.cli.main",
    "eamos-node": "eamos.cli.node",
    "eamos-sim-vehicle": "eamos.cli.sim_vehicle",
}


def _read(path: Path) -> str:
    return path.read_text(encoding="utf-8")


def _rel(path: Path) -> str:
    return str(path.relative_to(REPO))


MISSIONS: list[Mission] = [m for p in DOCS for m in missions(_rel(p), _read(p))]
COMMANDS: list[Command] = [c for p in DOCS for c in commands(_rel(p), _read(p))]


def _flies(mission: Mission) -> bool:
    """A whole mission (drones declared, nothing expected to fail) flies on simulated drones."""
    e = mission.expect
    return not e.syntax_only and e.exit_code == 0 and declares_drones(mission.text)


def _command_flies(command: Command) -> bool:
    """It runs ``eamos run`` (itself or a command of its block before it): a flight."""
    runs = [argv[:2] for argv in (*command.before, command.argv)]
    return not command.expect.syntax_only and ("eamos", "run") in runs


def _params(items: list[Mission] | list[Command], e2e: bool, flies: Callable) -> list:
    marks = [pytest.mark.e2e] if e2e else []
    return [pytest.param(x, id=x.ident, marks=marks) for x in items if flies(x) == e2e]


# ---- running -------------------------------------------------------------------------------


@pytest.fixture
def workdir(tmp_path: Path) -> Path:
    """A folder as a user's checkout looks to a doc: missions/ and configs/ in it."""
    for name in ("missions", "configs"):
        shutil.copytree(REPO / name, tmp_path / name)
    (tmp_path / "home").mkdir()
    return tmp_path


def _env(workdir: Path) -> dict[str, str]:
    env = dict(os.environ)
    # Keys and other per-user files land in the test's folder, not the user's home.
    env["HOME"] = str(workdir / "home")
    env["XDG_DATA_HOME"] = str(workdir / "home" / ".local" / "share")
    env["BROWSER"] = "true"  # a command that opens a browser opens none
    return env


def run(argv: tuple[str, ...], workdir: Path) -> subprocess.CompletedProcess[str]:
    """Run one EAMOS command line (its first word an entry point) in ``workdir``."""
    program = [sys.executable, "-c", f"import sys; from {ENTRY_MODULES[argv[0]]} import main; "
               "sys.exit(main())"]  # fmt: skip
    return subprocess.run(
        [*program, *argv[1:]],
        capture_output=True,
        text=True,
        timeout=PROCESS_TIMEOUT_S,
        cwd=workdir,
        env=_env(workdir),
    )


def _described(proc: subprocess.CompletedProcess[str]) -> str:
    out, err = proc.stdout[-3000:], proc.stderr[-3000:]
    return f"exit {proc.returncode}\n--- stdout\n{out}\n--- stderr\n{err}"


def parser_of(program: str) -> argparse.ArgumentParser:
    """The argument parser of one entry point."""
    if program == "eamos":
        from eamos.cli.main import build_parser
    elif program == "eamos-node":
        from eamos.cli.node import build_parser
    else:
        from eamos.cli.sim_vehicle import build_parser
    return build_parser()


def arguments_accepted(argv: tuple[str, ...]) -> str | None:
    """``None`` if the command's own parser accepts its arguments, else argparse's message."""
    parser = parser_of(argv[0])
    printed = io.StringIO()
    try:
        with contextlib.redirect_stderr(printed), contextlib.redirect_stdout(io.StringIO()):
            parser.parse_args(list(argv[1:]))
    except SystemExit as exc:  # argparse exits 0 after --help, 2 on a usage error
        if exc.code not in (0, None):
            return printed.getvalue().strip().splitlines()[-1]
    return None


def mission_name(mission: Mission) -> str:
    stem = Path(mission.doc).stem.lower().replace("-", "_")
    return mission.expect.file_name or f"{stem}_{mission.line}.go"


# ---- the examples --------------------------------------------------------------------------


@pytest.mark.parametrize("mission", [pytest.param(m, id=m.ident) for m in MISSIONS])
def test_mission_compiles_and_passes_the_check(mission: Mission, workdir: Path) -> None:
    if mission.expect.syntax_only:
        from eamos.compiler.parse import parse_partial

        _, diagnostics, unusable = parse_partial(mission.text)
        errors = [d for d in diagnostics if d.severity == "error"]
        assert not unusable and not errors, f"{mission.ident}: {errors}"
        return
    name = mission_name(mission)
    (workdir / name).write_text(mission.text, encoding="utf-8")
    want = mission.expect.exit_code
    # A mission shown with its errors is what ``eamos compile`` refuses; any other passes the
    # pre-flight check (which compiles it first).
    proc = run(("eamos", "compile" if want else "check", name), workdir)
    assert proc.returncode == want, f"{mission.ident}: {_described(proc)}"
    if mission.expect.output is not None:
        assert mission.expect.output.strip() in (proc.stdout + proc.stderr), (
            f"{mission.ident}: the doc's output differs:\n{_described(proc)}"
        )


@pytest.mark.parametrize("mission", _params(MISSIONS, True, _flies))
def test_mission_flies_on_simulated_drones(mission: Mission, workdir: Path) -> None:
    name = mission_name(mission)
    (workdir / name).write_text(mission.text, encoding="utf-8")
    argv = ("eamos", "run", name, "--speedup", "20", "--plain", "--no-svg", "--timeout", "180")
    proc = run((*argv, "--summary", "summary.json"), workdir)
    assert proc.returncode == 0, f"{mission.ident}: {_described(proc)}"
    summary = json.loads((workdir / "summary.json").read_text())
    assert summary["result"] == "finished", f"{mission.ident}: {summary['result']}"


def _check_command(command: Command, workdir: Path) -> None:
    if command.expect.syntax_only:
        problem = arguments_accepted(command.argv)
        assert problem is None, f"{command.ident}: {command.text}: {problem}"
        return
    for argv in command.before:  # the block's earlier commands, as a reader types them
        proc = run(argv, workdir)
        assert proc.returncode == 0, f"{command.ident}: before it, {argv}: {_described(proc)}"
    proc = run(command.argv, workdir)
    assert proc.returncode == command.expect.exit_code, (
        f"{command.ident}: {command.text}: {_described(proc)}"
    )


@pytest.mark.parametrize("command", _params(COMMANDS, False, _command_flies))
def test_command_runs_as_written(command: Command, workdir: Path) -> None:
    _check_command(command, workdir)


@pytest.mark.parametrize("command", _params(COMMANDS, True, _command_flies))
def test_command_flies_as_written(command: Command, workdir: Path) -> None:
    _check_command(command, workdir)


def help_text(program: str, subcommand: list[str]) -> str:
    """What ``PROGRAM SUBCOMMAND... --help`` prints."""
    printed = io.StringIO()
    with contextlib.redirect_stdout(printed), contextlib.redirect_stderr(io.StringIO()):
        try:
            parser_of(program).parse_args([*subcommand, "--help"])
        except SystemExit:
            pass
    return printed.getvalue()


@pytest.mark.parametrize("doc", DOCS, ids=_rel)
def test_every_command_quoted_in_prose_has_the_options_it_names(doc: Path) -> None:
    # `eamos compile --fleet F` in a sentence is a promise too: the option must exist.
    wrong = []
    for line, span in inline_commands(_rel(doc), _read(doc)):
        program = span.split()[0]
        words, options = options_named(span)
        # The deepest subcommand the parser knows (``logs fetch``; ``run`` of ``run X``).
        while words and f"usage: {program} {' '.join(words)}" not in help_text(program, words):
            words = words[:-1]
        shown = help_text(program, words)
        wrong += [f"{_rel(doc)}:{line}: {span}: no {o}" for o in options if o not in shown]
    assert not wrong, "\n".join(wrong)


# ---- the extraction itself -----------------------------------------------------------------


def test_the_docs_have_examples_and_every_marker_is_understood() -> None:
    assert len(MISSIONS) >= 8 and len(COMMANDS) >= 8
    assert any(m.doc == "README.md" for m in MISSIONS)
    assert any(c.doc == "README.md" and c.argv[:2] == ("eamos", "run") for c in COMMANDS)


def test_a_command_line_is_found_where_a_reader_would_type_it() -> None:
    assert command_argv("eamos keys --fleet A B   # a comment") == (
        "eamos",
        "keys",
        "--fleet",
        "A",
        "B",
    )
    assert command_argv("$ eamos run m.go --open") == ("eamos", "run", "m.go", "--open")
    readme = "python3 -m venv .venv && .venv/bin/pip install -q -e . && .venv/bin/eamos run m.go"
    assert command_argv(readme) == ("eamos", "run", "m.go")
    assert command_argv("scripts/rollout.sh m.go f.toml") is None
    assert command_argv("cd editors/vscode") is None


def test_a_marker_applies_to_the_block_after_it_only() -> None:
    text = (
        "<!-- doc-test: exit 2; as bad.go; output -->\n\n```go\nfunc SEQ_A() {}\n```\n\n"
        "```text\nbad.go:1:1: error: x\n```\n\nText.\n\n```go\nvar D1 Quadcopter\n```\n"
        "<!-- doc-test: syntax-only (needs SSH) -->\n```bash\neamos start runs/b\n```\n"
    )
    first, second = missions("x.md", text)
    assert (first.line, first.expect.exit_code, first.expect.file_name) == (4, 2, "bad.go")
    assert first.expect.output == "bad.go:1:1: error: x\n"
    assert second.expect.exit_code == 0 and second.expect.output is None
    (start,) = commands("x.md", text)
    assert start.expect.syntax_only and start.expect.reason == "needs SSH" and start.line == 18
    assert parse_marker("syntax-only (opens a browser; slow); exit 1").reason == (
        "opens a browser; slow"
    )
    # A marker is a line of its own: prose that shows one in passing is no marker.
    assert missions("y.md", "A `<!-- doc-test: ... -->` comment.\n```go\nvar D1 Quadcopter\n```\n")
    with pytest.raises(MarkerError):
        parse_marker("syntax-only")
    with pytest.raises(MarkerError):
        parse_marker("fragmnet")


def test_the_syntax_check_of_a_command_can_fail() -> None:
    assert arguments_accepted(("eamos", "run", "m.go", "--speedup", "5")) is None
    assert arguments_accepted(("eamos", "run", "m.go", "--sppedup", "5")) is not None
    assert arguments_accepted(("eamos", "launch", "m.go")) is not None
    assert arguments_accepted(("eamos-sim-vehicle", "--autopilot", "px5")) is not None
    # A quoted command's options: found in the deepest subcommand's help, or not.
    words, options = options_named("eamos logs fetch RUN_DIR\\|FLEET.toml [-o RUN_DIR] --sppedup")
    assert (words, options) == (["logs", "fetch"], ["-o", "--sppedup"])
    assert "-o RUN_DIR" in help_text("eamos", words) and "--sppedup" not in help_text(
        "eamos", words
    )


def test_the_readme_mission_is_missions_first_go() -> None:
    # The README's commands check, fly and report missions/first.go: the mission it shows.
    (first, *_) = missions("README.md", _read(REPO / "README.md"))
    assert first.text == _read(REPO / "missions" / "first.go")


def test_the_readme_reads_in_a_newcomers_order() -> None:
    # The two commands, then what EAMOS is, a mission, check/run/watch/report, real drones,
    # the exit codes, the architecture map and the docs index, in this order.
    text = _read(REPO / "README.md")
    headings = [line for line in text.splitlines() if line.startswith("## ")]
    wanted = [
        "## What EAMOS is",
        "## A mission",
        "## Check, run, watch, report",
        "## Flying a real drone",
        "## Exit codes",
        "## Architecture",
        "## Documentation",
    ]
    assert [h for h in headings if h in wanted] == wanted
    assert text.index("```bash") < text.index("## What EAMOS is")
    # Every package of eamos/ is on the map, and every doc in the index.
    for package in sorted((REPO / "eamos").iterdir()):
        if package.name != "__init__.py" and not package.name.startswith((".", "__")):
            assert f"  {package.name}{'/' if package.is_dir() else ''} " in text, package.name
    for doc in sorted((REPO / "docs").glob("*.md")):
        assert f"[docs/{doc.name}](docs/{doc.name})" in text, doc.name
