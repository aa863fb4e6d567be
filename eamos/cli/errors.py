"""The one place where an exception becomes an exit code and one message, for every entry point.

``eamos`` (:func:`dispatch`), ``eamos-node`` and ``eamos-sim-vehicle`` all run
their work through :func:`run_reported`.  The work returns an exit code of
:mod:`eamos.cli.exits` for outcomes it expects (a mission that failed, a drone
that did not answer); everything else it raises, and :data:`EXIT_CODE_OF`
(walked along the exception's class hierarchy by :func:`exit_code_of`) decides:

* bad input -- a mission with errors (:class:`~eamos.compiler.MissionError`,
  printed with every diagnostic's line and caret), a config or fleet file, a
  program, keys, a run folder, a snapshot, an argument the parser could not check
  (:class:`BadInput`): ``prog: what and where``, :data:`EXIT_BAD_INPUT`;
* could not connect -- a vehicle the adapter cannot use, a runtime whose
  sockets cannot start, a ground station that cannot bind its port, a
  :class:`ConnectionError`, a fleet operation whose every drone failed to
  connect: :data:`EXIT_CONNECT`; other fleet failures (a version mismatch, a
  full disk) and a mission the pre-flight check refused (:class:`Refused`):
  :data:`EXIT_MISSION_FAILED`;
* anything else is a bug of ours: one line, the traceback only with ``-v``:
  :data:`EXIT_INTERNAL`.

The table names each exception class by where it is defined
(``module.QualifiedName``) instead of importing it: an exception is an instance
of a class only if its module ran, so nothing needs loading to classify it, and
neither a node's start-up nor its error path loads the compiler or the fleet
operations to learn that a config was wrong.  ``tests/cli/test_exit_codes.py``
imports every name of the table, so a renamed class fails there, not in the field.
"""

from __future__ import annotations

import argparse
import sys
import traceback
from collections.abc import Callable, Mapping
from pathlib import Path
from types import MappingProxyType
from typing import TextIO

from .exits import (
    EXIT_BAD_INPUT,
    EXIT_CONNECT,
    EXIT_INTERNAL,
    EXIT_INTERRUPTED,
    EXIT_MISSION_FAILED,
)


class BadInput(Exception):
    """Input the command found wrong (an argument combination, an unwritable output)."""


class Refused(Exception):
    """The pre-flight check found errors: the mission is not flown (``--no-check`` overrides)."""


MISSION_ERROR = "eamos.compiler.errors.MissionError"
FLEET_ERROR = "eamos.ops.ssh.FleetError"

#: Exception class (``module.QualifiedName`` where it is defined) -> exit code.  An
#: exception takes the code of the first class of its hierarchy listed here (its own,
#: else its nearest base); none listed: :data:`EXIT_INTERNAL`.
EXIT_CODE_OF: Mapping[str, int] = MappingProxyType(
    {
        # bad input, one exception type per layer (docs/architecture.md)
        __name__ + ".BadInput": EXIT_BAD_INPUT,
        MISSION_ERROR: EXIT_BAD_INPUT,
        "eamos.program.format.ProgramError": EXIT_BAD_INPUT,
        "eamos.config.validation.ConfigError": EXIT_BAD_INPUT,
        "eamos.net.keys.KeysError": EXIT_BAD_INPUT,
        "eamos.net.wire.WireError": EXIT_BAD_INPUT,
        "eamos.report.ReportError": EXIT_BAD_INPUT,
        "eamos.actors.continuation.SnapshotError": EXIT_BAD_INPUT,
        "eamos.ops.ssh.RunFolderError": EXIT_BAD_INPUT,
        # could not connect
        "eamos.hal.api.AdapterError": EXIT_CONNECT,
        "eamos.actors.errors.DroneRuntimeError": EXIT_CONNECT,
        "eamos.ops.ssh.FleetConnectError": EXIT_CONNECT,
        "builtins.ConnectionError": EXIT_CONNECT,
        # the mission failed (or was not flown); FleetError: see exit_code_of
        FLEET_ERROR: EXIT_MISSION_FAILED,
        __name__ + ".Refused": EXIT_MISSION_FAILED,
        "builtins.KeyboardInterrupt": EXIT_INTERRUPTED,
    }
)

#: Kinds of :class:`~eamos.ops.DroneError` that mean "could not connect".
CONNECT_KINDS = frozenset({"unreachable", "wrong key", "host key changed"})


def listed_class(exc: BaseException) -> str | None:
    """The name :data:`EXIT_CODE_OF` lists for ``exc``: its class's or its nearest base's."""
    for cls in type(exc).__mro__:
        name = f"{cls.__module__}.{cls.__qualname__}"
        if name in EXIT_CODE_OF:
            return name
    return None


def exit_code_of(exc: BaseException) -> int:
    """The exit code for an exception raised by an entry point's work (pure: no output)."""
    listed = listed_class(exc)
    if listed is None:
        return EXIT_INTERNAL
    if listed == FLEET_ERROR:
        # A plain FleetError says per drone what went wrong: all of them unreachable
        # (or refusing our key) is "could not connect", anything else the mission's failure.
        drones = getattr(exc, "errors", [])
        if drones and all(getattr(e, "kind", None) in CONNECT_KINDS for e in drones):
            return EXIT_CONNECT
    return EXIT_CODE_OF[listed]


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
    err = err if err is not None else sys.stderr
    code = exit_code_of(exc)
    if listed_class(exc) == MISSION_ERROR:
        path = str(mission) if mission is not None else "<mission>"
        render = exc.render  # type: ignore[attr-defined]
        print(render(path, source_text(path) if mission is not None else None), file=err)
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


def run_reported(
    prog: str,
    work: Callable[[], int],
    *,
    verbose: bool = False,
    mission: str | Path | None = None,
) -> int:
    """``work()``'s exit code, or the exit code of what it raised, said once on stderr.

    Every entry point's ``main()`` runs its work through here (``prog`` starts each
    message: ``eamos compile``, ``eamos-node Drone1``, ``eamos-sim-vehicle``).
    """
    try:
        return int(work())
    except (Exception, KeyboardInterrupt) as exc:
        try:
            return report(prog, exc, verbose=verbose, mission=mission)
        except Exception:  # the report itself failed: still one line, and the code
            if verbose:
                traceback.print_exc()
            print(f"{prog}: internal error: {exc!r}, please report it", file=sys.stderr)
            return EXIT_INTERNAL


def dispatch(args: argparse.Namespace) -> int:
    """Run the ``eamos`` command the parsed ``args`` name (``args.func``); its exit code."""
    prog = getattr(args, "prog", None) or f"eamos {getattr(args, 'command', '')}".strip()
    return run_reported(
        prog,
        lambda: args.func(args),
        verbose=bool(getattr(args, "verbose", False)),
        mission=getattr(args, "mission", None),
    )


def command(parser: argparse.ArgumentParser, func: object) -> None:
    """Make ``func`` the handler of ``parser``'s command (its messages start with its name)."""
    parser.set_defaults(func=func, prog=parser.prog)


__all__ = [
    "CONNECT_KINDS",
    "EXIT_CODE_OF",
    "BadInput",
    "Refused",
    "command",
    "dispatch",
    "exit_code_of",
    "listed_class",
    "report",
    "run_reported",
    "source_text",
]
