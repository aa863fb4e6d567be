"""The ``eamos`` command: compile, draw and run missions.

    eamos compile MISSION.go [-o OUT] [--stats]    compile to drone programs and graphs
    eamos graph MISSION.go [--which meg] ...         draw one graph
    eamos run MISSION.go [--fleet F] [--speedup K]   fly it on simulated drones, one process each
    eamos rollout / start / status / abort / logs fetch / report   real drones over SSH
    eamos keys OUT [--fleet NAMES...]                the fleet's network keys (CURVE)

Every command prints clear errors and exits non-zero on bad input; a
traceback appears only with ``-v``.
"""

from __future__ import annotations

import argparse
import sys
import traceback

from eamos import __version__
from eamos.cli.run import add_run_parser
from eamos.compiler.cli_compile import add_compile_parser, add_graph_parser


def build_parser() -> argparse.ArgumentParser:
    """The ``eamos`` argument parser with every subcommand."""
    parser = argparse.ArgumentParser(
        prog="eamos",
        description="EAMOS: write a multi-drone mission as a short Go-syntax text file, "
        "compile it into one program per drone, and run it decentralized.",
    )
    parser.add_argument("--version", action="version", version=f"eamos {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    add_compile_parser(sub)
    add_graph_parser(sub)
    add_run_parser(sub)
    # --- fleet operations (eamos/ops/cli.py): rollout, start, status, abort, logs, report ---
    from eamos.ops.cli import add_fleet_commands

    add_fleet_commands(sub)
    # --- end of fleet operations ---
    # --- network keys (eamos/net/keys.py): eamos keys ---
    from eamos.net.keys import add_keys_parser

    add_keys_parser(sub)
    # --- end of network keys ---
    return parser


def main(argv: list[str] | None = None) -> int:
    """Console entry point of ``eamos``."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args))
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    except Exception as exc:  # an internal error: one line, the trace only with -v
        if getattr(args, "verbose", False):
            traceback.print_exc()
        print(
            f"eamos: internal error: {exc!r} (run with -v for details); please report it",
            file=sys.stderr,
        )
        return 4


if __name__ == "__main__":
    sys.exit(main())
