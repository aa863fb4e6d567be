"""The ``eamos`` command: compile, draw and run missions; roll them out to real drones.

    eamos compile MISSION.go [-o OUT] [--stats]    compile to drone programs and graphs
    eamos graph MISSION.go [--which meg] ...         draw one graph
    eamos run MISSION.go [--fleet F] [--speedup K]   fly it on simulated drones, one process each
    eamos rollout / start / status / abort / logs fetch   real drones over SSH
    eamos pause / resume RUN_DIR, eamos drone RUN_DIR NAME hold|resume|land|...   the operator
    eamos report RUN_DIR                             an HTML page about a run folder
    eamos monitor RUN_DIR                            replay a run in the browser monitor
    eamos keys OUT [--fleet NAMES...]                the fleet's network keys (CURVE)

Every command exits with a code of :mod:`eamos.cli.exits` (0 ok, 1 mission
failed, 2 bad input, 3 could not connect, 4 internal error), decided in one
place for every entry point, :func:`eamos.cli.errors.run_reported` (through
:func:`~eamos.cli.errors.dispatch`); a traceback appears only with ``-v``.
"""

from __future__ import annotations

import argparse
import gc
import sys

from eamos import __version__

from .amend import add_amend_parser
from .check import add_check_parser
from .compile import add_compile_parser, add_graph_parser
from .errors import dispatch
from .fleet import add_fleet_commands
from .keys import add_keys_parser
from .lsp import add_lsp_parser
from .monitor import add_monitor_parser
from .operator import add_operator_parsers
from .report import add_report_parser
from .run import add_run_parser


def build_parser() -> argparse.ArgumentParser:
    """The ``eamos`` argument parser with every subcommand."""
    parser = argparse.ArgumentParser(
        prog="eamos",
        description="EAMOS: write a multi-drone mission as a short Go-syntax text file, "
        "compile it into one program per drone, and run it decentralized.",
        epilog="exit codes: 0 ok, 1 mission failed, 2 bad input, 3 could not connect, "
        "4 internal error",
    )
    parser.add_argument("--version", action="version", version=f"eamos {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    add_compile_parser(sub)
    add_graph_parser(sub)
    add_run_parser(sub)
    add_fleet_commands(sub)
    add_operator_parsers(sub)
    add_report_parser(sub)
    add_keys_parser(sub)
    add_check_parser(sub)
    add_amend_parser(sub)
    add_lsp_parser(sub)
    add_monitor_parser(sub)
    return parser


#: Commands that build a mission's graphs (and, for ``check``, its virtual runs), print
#: and exit.
BATCH_COMMANDS = ("compile", "graph", "check", "amend")


def main(argv: list[str] | None = None) -> int:
    """Console entry point of ``eamos``."""
    args = build_parser().parse_args(argv)
    if args.command not in BATCH_COMMANDS or not gc.isenabled():
        return dispatch(args)
    # These make many small objects, all freed by reference counting; the cyclic
    # collector's scans over them find nothing and take a good part of the time
    # (scripts/bench_compile.py, scripts/bench_check.py).  Paused for the command only,
    # here in the entry point: not in compile_mission, which the language server runs on
    # a worker thread while its other threads go on.
    gc.disable()
    try:
        return dispatch(args)
    finally:
        gc.enable()


if __name__ == "__main__":
    sys.exit(main())
