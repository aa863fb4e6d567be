"""The operator's commands to a flying mission: ``eamos pause``, ``eamos resume``, ``eamos drone``.

They reach the ground station running the mission of a run folder (``eamos run``'s or
a roll-out's, run by ``eamos start``) through its operator's socket
(:mod:`eamos.ground.operator`); the ground station broadcasts the command and every
drone logs it with its origin (this user, on this host).
"""

from __future__ import annotations

import argparse
import getpass
import socket
from pathlib import Path
from typing import Any

from .errors import BadInput, command
from .exits import EXIT_OK

_PAUSE_HELP = """\
Pause the mission: every drone holds where it is.  A running move is suspended, not
cancelled; a running PauseFor stops its clock; conditions keep being evaluated.
`eamos resume RUN_DIR` continues every suspended action from where it stopped."""

_RESUME_HELP = """\
Resume a paused mission: every suspended action continues from where it stopped (a
move to its original target, a PauseFor for the time it had left)."""

_DRONE_HELP = """\
A command for one drone of a flying mission:

  hold         it holds where it is (its running action is suspended)
  resume       it continues (after hold), or EAMOS takes it back (after release)
  land         it lands now; its remaining actions fail (a Try catches them, drones
               waiting for it apply their policy)
  return-home  it flies home and lands; its remaining actions fail, as for land
  release      EAMOS stops commanding it (a pilot takes it); its remaining actions
               fail; only `resume` hands it back"""


def add_operator_parsers(sub: Any) -> None:
    """Add ``pause``, ``resume`` and ``drone``."""
    fmt = argparse.RawDescriptionHelpFormatter
    for name, text, desc in (
        ("pause", "pause a flying mission: every drone holds", _PAUSE_HELP),
        ("resume", "resume a paused mission", _RESUME_HELP),
    ):
        p = sub.add_parser(name, help=text, description=desc, formatter_class=fmt)
        _run_dir(p)
        command(p, cmd_operator)
    p = sub.add_parser(
        "drone",
        help="hold, resume, land, send home or release one drone of a flying mission",
        description=_DRONE_HELP,
        formatter_class=fmt,
    )
    _run_dir(p)
    p.add_argument("drone", metavar="NAME", help="the drone")
    p.add_argument(
        "action",
        metavar="COMMAND",
        choices=("hold", "resume", "land", "return-home", "release"),
        help="hold | resume | land | return-home | release",
    )
    command(p, cmd_operator)


def _run_dir(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "run_dir",
        metavar="RUN_DIR",
        type=Path,
        help="the run folder of the flying mission (`eamos run`'s or a roll-out's)",
    )


def origin() -> str:
    """Who sends a command from this terminal: ``cli user NAME@HOST``."""
    try:
        user = getpass.getuser()
    except (KeyError, OSError):
        user = "unknown"
    return f"cli user {user}@{socket.gethostname()}"


def cmd_operator(args: argparse.Namespace) -> int:
    """``eamos pause|resume|drone``: 0 once the ground station sent the command; 2 for a
    folder that is not a run folder; 3 when no ground station runs it or it refused."""
    from eamos.ground.operator import send_command

    if not args.run_dir.is_dir():
        raise BadInput(f"{args.run_dir}: not a run folder")
    drone = getattr(args, "drone", "") or ""
    what = getattr(args, "action", None) or args.command
    send_command(args.run_dir, what, drone, origin())
    print(f"{what} sent to {drone or 'every drone'} ({args.run_dir})")
    return EXIT_OK


__all__ = ["add_operator_parsers"]
