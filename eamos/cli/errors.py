"""The one place where an exception becomes an exit code and one message.

Every ``eamos`` command runs through :func:`dispatch`.  A command returns an
exit code of :mod:`eamos.cli.exits` for outcomes it expects (a mission that
failed, a drone that did not answer); everything else it raises, and here:

* a mission with errors (:class:`~eamos.compiler.MissionError`) prints every
  diagnostic with its line and caret: :data:`EXIT_BAD_INPUT`;
* bad input -- a config or fleet file, a program, keys, a run folder, an
  argument the parser could not check (:class:`BadInput`) -- prints
  ``eamos CMD: what and where``: :data:`EXIT_BAD_INPUT`;
* a fleet operation whose drones could not be reached (every drone's failure
  is a connection failure), a ground station that cannot bind its port
  (:class:`~eamos.ops.FleetConnectError`), a :class:`ConnectionError`: :data:`EXIT_CONNECT`;
  other fleet failures (a version mismatch, a full disk): :data:`EXIT_MISSION_FAILED`;
* a mission the pre-flight check refused (:class:`Refused`): :data:`EXIT_MISSION_FAILED`;
* anything else is a bug of ours: one line, the traceback only with ``-v``:
  :data:`EXIT_INTERNAL`.

The exception classes are imported when one is raised, so a command that
succeeds loads nothing it does not use.
"""

from __future__ import annotations

import argparse
import sys
import traceback
from pathlib import Path
from typing import TextIO

from .exits import (
    EXIT_BAD_INPUT,
    EXIT_CONNECT,
    EXIT_INTERNAL,
    EXIT_INTERRUPTED,
    EXIT_MISSION_FAILED,
)

#: Kinds of :class:`~eamos.ops.DroneError` that mean "could not connect".
CONNECT_KINDS = frozenset({"unreachable", "wrong key", "host key changed"})


class BadInput(Exception):
    """Input the command found wrong (an argument combination, an unwritable output)."""


class Refused(Exception):
    """The pre-flight check found errors: the mission is not flown (``--no-check`` overrides)."""


def _bad_input_types() -> tuple[type[BaseException], ...]:
    from eamos.config import ConfigError
    from eamos.net.keys import KeysError
    from eamos.ops import RunFolderError
    from eamos.program.format import ProgramError
    from eamos.report import ReportError

    return (BadInput, ConfigError, KeysError, ProgramError, ReportError, RunFolderError)


def exit_code_of(exc: BaseException) -> int:
    """The exit code for an exception a command raised (pure: no output)."""
    from eamos.compiler import MissionError
    from eamos.ops import FleetConnectError, FleetError

    if isinstance(exc, KeyboardInterrupt):
        return EXIT_INTERRUPTED
    if isinstance(exc, Refused):
        return EXIT_MISSION_FAILED
    if isinstance(exc, (MissionError, *_bad_input_types())):
        return EXIT_BAD_INPUT
    if isinstance(exc, ConnectionError | FleetConnectError):
        return EXIT_CONNECT
    if isinstance(exc, FleetError):
        if exc.errors and all(e.kind in CONNECT_KINDS for e in exc.errors):
            return EXIT_CONNECT
        return EXIT_MISSION_FAILED
    return EXIT_INTERNAL


def source_text(path: str | Path) -> str | None:
    """A mission file's text for error rendering (None if unreadable or binary)."""
    try:
        text = Path(path).read_bytes().decode("utf-8", errors="replace")
    except OSError:
        return None
    # Never echo a binary file's bytes to the terminal.
    return None if "\x00" in text else text


def report(
    prog: str,
    exc: BaseException,
    *,
    verbose: bool = False,
    mission: str | Path | None = None,
    err: TextIO | None = None,
) -> int:
    """Print what went wrong, once, and return the exit code (see :func:`exit_code_of`)."""
    from eamos.compiler import MissionError

    err = err if err is not None else sys.stderr
    code = exit_code_of(exc)
    if isinstance(exc, MissionError):
        path = str(mission) if mission is not None else "<mission>"
        print(exc.render(path, source_text(path) if mission is not None else None), file=err)
    elif code == EXIT_INTERRUPTED:
        print(f"{prog}: interrupted", file=err)
    elif code != EXIT_INTERNAL:
        print(f"{prog}: {exc}", file=err)
    else:
        if verbose:
            traceback.print_exception(exc, file=err)
        detail = str(exc) or type(exc).__name__
        advice = "please report it" if verbose else "(run with -v for details), please report it"
        print(f"{prog}: internal error: {type(exc).__name__}: {detail} {advice}", file=err)
    err.flush()
    return code


def dispatch(args: argparse.Namespace) -> int:
    """Run the command the parsed ``args`` name (``args.func``) and return its exit code."""
    prog = getattr(args, "prog", None) or f"eamos {getattr(args, 'command', '')}".strip()
    verbose = bool(getattr(args, "verbose", False))
    try:
        return int(args.func(args))
    except (Exception, KeyboardInterrupt) as exc:
        try:
            return report(prog, exc, verbose=verbose, mission=getattr(args, "mission", None))
        except Exception:  # the report itself failed: still one line, and the code
            if verbose:
                traceback.print_exc()
            print(f"{prog}: internal error: {exc!r}, please report it", file=sys.stderr)
            return EXIT_INTERNAL


def command(parser: argparse.ArgumentParser, func: object) -> None:
    """Make ``func`` the handler of ``parser``'s command (its messages start with its name)."""
    parser.set_defaults(func=func, prog=parser.prog)


__all__ = [
    "CONNECT_KINDS",
    "BadInput",
    "Refused",
    "command",
    "dispatch",
    "exit_code_of",
    "report",
]
